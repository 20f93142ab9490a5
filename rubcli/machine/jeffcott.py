"""The Jeffcott rotor's machines as composed machines, in the nondimensional scales.

The paper's machine and the general machine (``docs/general-machine.md``) are a structure
of two coordinates, the rotor's ``(x, y)``: ``M = I``, ``K = S`` (the support stiffness
over ``k_r``), ``C = 2 D`` (``D = nu I`` unless a damping matrix is given), ``G = 0``, the
static load; an unbalance ``e`` at ``(x, y)`` at phase ``phi0`` (its force ``e eta^2 (cos
p, sin p)`` at a constant speed); one station with clearance 1, the spring ``K``,
friction ``mu`` and radius ``Rp``, its stator rigid and centred at the offset. A stator
with its own mass (``ModelParams.stator``) adds its coordinates ``(u, v)``: mass
``m_s``, stiffness ``diag(k_s)``, damping ``2 diag(n_s)``, and the station joins the two.
"""

from __future__ import annotations

import numpy as np

from rubcli.machine.contact import ContactLaw
from rubcli.machine.machine import Machine, Speed, Station, Structure, Unbalance
from rubcli.model import ModelParams
from rubcli.speed import SpeedProfile


def jeffcott_machine(
    params: ModelParams,
    profile: SpeedProfile | None = None,
    contact_damping: float = 0.0,
    contact_exponent: float = 1.0,
) -> Machine:
    """``params`` (and a prescribed speed ``profile``, None: ``params.eta``) as a machine;
    ``contact_damping`` is the nondimensional one of a case's ``[model]`` (the force
    ``2 contact_damping z'``), ``contact_exponent`` the Hertzian exponent."""
    if not isinstance(params, ModelParams):
        raise TypeError(f"jeffcott_machine: params must be a ModelParams, got {params!r}")
    S = np.array(params.stiffness, dtype=float)
    D = np.array(params.damping, dtype=float) if params.damping is not None else None
    D = params.nu * np.eye(2) if D is None else D
    M, K, C = np.eye(2), S, 2.0 * D
    static = np.array(params.load, dtype=float)
    stator_coordinates = None
    if params.stator is not None:
        stator = params.stator
        M = np.diag([1.0, 1.0, stator.mass, stator.mass])
        K = _blocks(S, np.diag(stator.stiffness))
        C = _blocks(2.0 * D, 2.0 * np.diag(stator.damping))
        static = np.concatenate([static, [0.0, 0.0]])
        stator_coordinates = (2, 3)
    law = ContactLaw(params.K, 2.0 * contact_damping, contact_exponent)
    station = Station(
        rotor=(0, 1),
        clearance=1.0,
        law=law,
        mu=params.mu,
        radius=params.Rp,
        stator=stator_coordinates,
        offset=params.offset,
        name="stator",
    )
    speed = Speed.constant(params.eta) if profile is None else Speed(profile.tau, profile.eta)
    return Machine(
        structure=Structure(M=M, K=K, C=C, static=static),
        stations=(station,),
        speed=speed,
        unbalances=(Unbalance((0, 1), params.e, params.phi0),),
        name="jeffcott",
    )


def _blocks(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros((4, 4))
    out[:2, :2] = a
    out[2:, 2:] = b
    return out
