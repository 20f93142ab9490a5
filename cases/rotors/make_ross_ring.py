"""Write ross_ring.toml: ROSS's example rotor with damping (``ross.rotor_example_with_damping()``)
with a snubber ring around its mid-span (node 18): a ring of 0.8 kg on a support node
(node 34, which ROSS numbers after the shaft's 34 nodes, 3 coordinates) held to the
ground by a spring of 2e6 N/m and 60 N s/m in x and y. The shaft reaches the ring only
through the case's contact station; ROSS's model joins node 18 to the ring's node by a
bearing of zero coefficients (its ``n_link``). Written with ROSS 2.3 so that both ROSS
2.3 and ROSS 3 read it.

    python cases/rotors/make_ross_ring.py
"""

from pathlib import Path

from rubcli.machine.ross import import_ross

SHAFT_NODE = 18
RING_MASS = 0.8  # kg
RING_STIFFNESS = 2e6  # N/m
RING_DAMPING = 60.0  # N s/m


def ring_rotor(ross):
    example = ross.rotor_example_with_damping()
    ring = len(example.nodes)  # the first support node: after the shaft's
    link = ross.BearingElement(n=SHAFT_NODE, n_link=ring, kxx=0.0, kyy=0.0, cxx=0.0, cyy=0.0,
                               tag="ring link")  # fmt: skip
    k, c = RING_STIFFNESS, RING_DAMPING
    support = ross.BearingElement(n=ring, kxx=k, kyy=k, cxx=c, cyy=c, tag="ring support")
    mass = ross.PointMass(n=ring, m=RING_MASS, tag="ring")
    return ross.Rotor(example.shaft_elements, example.disk_elements,
                      [*example.bearing_elements, link, support],
                      point_mass_elements=[mass])  # fmt: skip


if __name__ == "__main__":
    ring_rotor(import_ross()).save(Path(__file__).with_name("ross_ring.toml"))
