"""Write ross_runup.toml: ROSS's example rotor with damping (its shaft and its disks at
nodes 12 and 24, ``ross.rotor_example_with_damping()``) on bearings whose coefficients
change with the speed, as an oil-film bearing's do: the direct stiffness rising and the
damping falling with speed, and a cross-coupled stiffness (``kxy = -kyx``) growing with
it, tabulated at 0 to 400 rad/s (ROSS interpolates between, a spline through the table).
Written with ROSS 2.3 so that both ROSS 2.3 and ROSS 3 read it.

    python cases/rotors/make_ross_runup.py
"""

from pathlib import Path

import numpy as np

from rubcli.machine.ross import import_ross

FREQUENCY = np.array([0.0, 100.0, 200.0, 300.0, 400.0])  # rad/s
STIFFENING = np.array([1.0, 1.08, 1.2, 1.35, 1.55])  # the direct stiffness, x the example's
CROSS = np.array([0.0, 0.01, 0.02, 0.03, 0.04])  # kxy = -kyx, a share of kxx
DAMPING = np.array([1.6, 1.45, 1.3, 1.15, 1.0])  # the direct damping, x the example's


def bearing(ross, n: int, kxx: float, kyy: float, cxx: float, cyy: float):
    k = kxx * STIFFENING
    return ross.BearingElement(
        n=n,
        kxx=list(k),
        kyy=list(kyy * STIFFENING),
        kxy=list(CROSS * k),
        kyx=list(-CROSS * k),
        cxx=list(cxx * DAMPING),
        cyy=list(cyy * DAMPING),
        frequency=list(FREQUENCY),
    )


if __name__ == "__main__":
    ross = import_ross()
    example = ross.rotor_example_with_damping()
    bearings = [bearing(ross, 4, 4.40e5, 4.6114e5, 27.4, 2.505),
                bearing(ross, 31, 9.50e5, 1.09e8, 50.4, 100.4553)]  # fmt: skip
    rotor = ross.Rotor(example.shaft_elements, example.disk_elements, bearings)
    rotor.save(Path(__file__).with_name("ross_runup.toml"))
