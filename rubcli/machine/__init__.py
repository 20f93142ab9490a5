"""The composed machine: a linear structure of any size, unbalances, contact stations with
their contact law, and a speed (``docs/composed-machine.md``). Data only, checked once on
construction; ``rubcli.system`` builds the one system every method runs from it."""

from rubcli.machine.contact import ContactLaw
from rubcli.machine.jeffcott import jeffcott_machine
from rubcli.machine.machine import Machine, Speed, SpeedTable, Station, Structure, Unbalance

__all__ = [
    "ContactLaw",
    "Machine",
    "Speed",
    "SpeedTable",
    "Station",
    "Structure",
    "Unbalance",
    "jeffcott_machine",
]
