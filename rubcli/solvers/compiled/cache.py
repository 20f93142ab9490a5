"""Freshness of numba's cache of the compiled sub-package.

Every kernel is compiled with ``cache=True``; the first call on a machine compiles
(seconds), later processes load the machine code from ``__pycache__``. numba does not
notice that a *called* function in another file changed (model.py's, events.py's and
control.py's cores, among them the whole event search, or a neighbour module of this
sub-package), so ``ensure_fresh`` (run once
per process before the first kernel call) compares a fingerprint of those files with the
one the cache was built from, and evaluates the registered cores through a cached probe;
if either disagrees, every kernel is recompiled.
"""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path

import numpy as np
from numba.core.dispatcher import Dispatcher

from rubcli import drive, model, stator
from rubcli.model import (
    cartesian_entries,
    entry_regime_value,
    linearised_contact_arrays,
    polar_entries,
    polar_jacobian_arrays,
    polar_rhs_entries,
    rhs_entries,
    rhs_jacobian_array,
    rhs_jacobian_record,
    rhs_record,
    slip_velocity_rate,
    slip_velocity_value,
    zero_slip_regime_value,
)
from rubcli.solvers import control, events
from rubcli.solvers.compiled.jit import jit
from rubcli.solvers.events import start_flags, switch_regime

# The files whose functions the kernels compile in: the cores of ``jit.COMPILABLE_CORES``
# and every module of this sub-package (a kernel calls into its neighbours: roots.py,
# precheck.py, ...; and jit.py holds the decorators' flags, which numba's cache key
# omits), and the energy balance's kernel, which reads model.py's cores and parameter
# record (a cached copy would keep the record's old layout). A change to any of them
# recompiles every kernel once. The fingerprint of the sources the cache was built
# from is kept in FINGERPRINT.
ENERGY_KERNEL = Path(__file__).parents[2] / "analysis" / "energy" / "kernel.py"
CORE_FILES = (
    Path(model.__file__),
    Path(events.__file__),
    Path(control.__file__),
    Path(drive.__file__),
    Path(stator.__file__),
    ENERGY_KERNEL,
    *sorted(Path(__file__).parent.glob("*.py")),
)
FINGERPRINT = Path(__file__).parent / "__pycache__" / "cores.fingerprint"


def _probe_values(x):
    """The registered model and event cores evaluated at one point (``ensure_fresh``).

    A plain function, run as it is by the interpreter and compiled as ``_probe``.
    """
    nu, eta, E, phi0, K, mu, Rp = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
    tau, px, py, vx, vy = x[7], x[8], x[9], x[10], x[11]
    out = np.empty(192)
    n = 0
    for regime in (0, 1, -1, 2):
        for v in rhs_entries(tau, px, py, vx, vy, nu, eta, E, phi0, K, mu, Rp, regime):
            out[n] = v
            n += 1
    for v in rhs_jacobian_array(tau, px, py, vx, vy, nu, eta, E, phi0, K, mu, Rp, 1).ravel():
        out[n] = v
        n += 1
    A, b = linearised_contact_arrays(px, py, K, nu, mu)
    for v in A.ravel():
        out[n] = v
        n += 1
    for v in b:
        out[n] = v
        n += 1
    out[n] = slip_velocity_rate(px, py, vx, vy, 0.3, -0.2)
    n += 1
    r, theta, u, omega = polar_entries(px, py, vx, vy)
    for v in cartesian_entries(r, theta, u, omega):
        out[n] = v
        n += 1
    for v in polar_rhs_entries(tau, r, theta, u, omega, nu, eta, E, phi0, K, mu):
        out[n] = v
        n += 1
    J, f_tau = polar_jacobian_arrays(tau, r, theta, u, omega, nu, eta, E, phi0, K, mu)
    for v in J.ravel():
        out[n] = v
        n += 1
    for v in f_tau:
        out[n] = v
        n += 1
    # the event rules: v_r, the entry direction, Filippov's rule, the switch at each kind
    out[n] = slip_velocity_value(px, py, vx, vy, Rp * eta)
    out[n + 1] = entry_regime_value(px, py, vx, vy, mu, Rp * eta)
    out[n + 2] = zero_slip_regime_value(tau, px, py, vx, vy, nu, eta, E, phi0, K, mu)
    n += 3
    # a general machine's record: every departure from the paper's machine nonzero
    pars = np.zeros(model.N_PARAMS)
    pars[model.P_NU], pars[model.P_ETA], pars[model.P_E], pars[model.P_PHI0] = nu, eta, E, phi0
    pars[model.P_K], pars[model.P_MU], pars[model.P_RP] = K, mu, Rp
    for k in range(model.P_SXX, model.N_PARAMS):
        pars[k] = 0.01 * (k - model.P_SXX + 1) * (-1.0) ** k
    for regime in (1, 2):
        for v in rhs_record(tau, px, py, vx, vy, pars, regime):
            out[n] = v
            n += 1
    for v in rhs_jacobian_record(tau, px, py, vx, vy, pars, 1).ravel():
        out[n] = v
        n += 1
    for kind in range(5):
        new, recorded, project = switch_regime(kind, tau, px, py, vx, vy, 1, pars)
        flags = start_flags(kind)
        out[n] = new
        out[n + 1] = recorded
        out[n + 2] = 1.0 if project else 0.0
        out[n + 3] = 4.0 * flags[0] + 2.0 * flags[1] + 1.0 * flags[2]
        n += 4
    return out[:n]


_probe = jit(_probe_values)
# nu, eta, E, phi0, K, mu, Rp, tau, x, y, vx, vy: a contact state with friction
PROBE_POINT = np.array([0.013, 0.71, 2.9, 0.37, 123.0, 0.07, 3.1, 1.3, 1.05, -0.42, 0.61, 1.7])
PROBE_RTOL = 1e-12  # the two evaluations differ by round-off (libm vs CPython's hypot)
_usable: bool | None = None


def _probe_agrees() -> bool:
    compiled = _probe(PROBE_POINT)
    expected = _probe_values(PROBE_POINT)
    return bool(np.allclose(compiled, expected, rtol=PROBE_RTOL, atol=PROBE_RTOL))


def ensure_fresh() -> bool:
    """Make sure the cached kernels run model.py's current cores; True if they do.

    numba invalidates a cached function when its own file changes, not when a function
    it calls in another file (model.py's cores) does. Once per process, the probe
    (cached like the kernels) is compared with the interpreter's evaluation of the same
    cores; if they disagree, every kernel's cache is flushed and the probe compared
    again. Should they still disagree (a core that numba compiles differently), the
    kernels are not used: False, with a warning, and the callers run pure Python.
    """
    global _usable
    if _usable is None:
        fingerprint = _fingerprint()
        usable = _stored_fingerprint() == fingerprint and _probe_agrees()
        if not usable:
            for dispatcher in _dispatchers():
                dispatcher.recompile()  # flushes its cache; compiled afresh on next call
            usable = _probe_agrees()
            if usable:
                _store_fingerprint(fingerprint)
        if not usable:
            warnings.warn(
                "rubcli: the compiled kernels disagree with model.py; using the pure-Python "
                "path (please report this)",
                RuntimeWarning,
                stacklevel=2,
            )
        _usable = usable
    return _usable


def _fingerprint() -> str:
    """SHA-256 of the source files compiled into the kernels (``CORE_FILES``)."""
    digest = hashlib.sha256()
    for path in CORE_FILES:
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _stored_fingerprint() -> str | None:
    try:
        return FINGERPRINT.read_text().strip()
    except OSError:
        return None


def _store_fingerprint(fingerprint: str) -> None:
    """Written atomically; a read-only install keeps only the probe's protection."""
    try:
        FINGERPRINT.parent.mkdir(exist_ok=True)
        tmp = FINGERPRINT.with_suffix(f".{id(fingerprint)}.tmp")
        tmp.write_text(fingerprint + "\n")
        tmp.replace(FINGERPRINT)
    except OSError:
        pass


def _dispatchers() -> list:
    """Every compiled function of the sub-package (the kernels and the probe) and of the
    energy balance's kernel."""
    from rubcli.analysis.energy import kernel as energy_kernel
    from rubcli.solvers.compiled import (
        contact,
        dop853,
        dop853_loop,
        drive,
        driven_taylor,
        extended_loop,
        linalg,
        piecewise,
        piecewise_loop,
        precheck,
        propagators,
        rhs,
        roots,
        taylor,
        two_body,
        two_body_taylor,
        variational,
    )  # fmt: skip

    modules = (
        linalg, propagators, precheck, contact, rhs, dop853, roots, dop853_loop, taylor,
        piecewise, piecewise_loop, drive, driven_taylor, extended_loop, two_body, two_body_taylor,
        variational, energy_kernel,
    )  # fmt: skip
    found = [_probe]
    for module in modules:
        found += [v for v in vars(module).values() if isinstance(v, Dispatcher)]
    return found
