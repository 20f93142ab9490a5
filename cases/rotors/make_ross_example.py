"""Write ross_example.toml: ROSS's own example rotor with damping
(``ross.rotor_example_with_damping()``: 34 nodes, disks at nodes 12 and 24, bearings at
4 and 31), saved by ``Rotor.save``. Written with ROSS 2.3 so that both ROSS 2.3
(Python 3.11-3.12) and ROSS 3 (Python 3.13+) read it.

    python cases/rotors/make_ross_example.py
"""

from pathlib import Path

from rubcli.machine.ross import import_ross

if __name__ == "__main__":
    ross = import_ross()
    ross.rotor_example_with_damping().save(Path(__file__).with_name("ross_example.toml"))
