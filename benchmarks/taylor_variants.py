"""Routes to a cheaper ``taylor`` without friction, measured (issue 13, target 1, mu = 0).

Run from the repository root: ``python benchmarks/taylor_variants.py`` (about a minute;
``--quick``: decade ladder, fewer repeats). Prints two tables and writes them to
``benchmarks/taylor_variants.md``.

The paper's case without friction (K = 17.6, 100 forcing periods, Figure 3 start) stays
in contact from its last contact entry (tau = 17.9) to the end: most of ``taylor``'s
steps are slip steps there. Table 1 integrates that stretch alone, from the state
``taylor`` at rtol 1e-12 has at the entry, in a bare loop (no pre-check, no samples; no
event occurs) with the kernel's own slip series (``_slip_coefficients``), step rule
(``step_size``) and dense output, and two variants of it:

- ``rotating``: the series of the frame turning with the unbalance, w(t0 + s) e^{-i eta
  s} (aligned with the fixed frame at each step's start, so the forcing is the constant
  E e^{i (eta t0 + phi0)} on the step), the step's end rotated back exactly. The issue
  suggests it; the transient rings at the contact frequency in either frame;
- ``scaled norm``: the step rule with the velocity coefficients divided by sqrt(1 + K),
  the contact frequency (a velocity error dv shows as a position error of about dv /
  omega), the state tolerance likewise.

Each runs on a tolerance ladder; the error is the final position error against
``dop853-jit`` at rtol 1e-13; time is CPU time, the minimum of the repeats. Below the
table, each variant's cheapest setting that reaches 1e-6 and 1e-10.

Table 2 times the slip series alone (order 13 and 18): the loop as shipped, the same
recurrences as generated straight-line code (every loop unrolled, every coefficient a
local variable), the loop compiled without FMA contraction (plain IEEE arithmetic: the
shipped series are compiled with numba ``fastmath = {"contract"}``, ``jit_fused``), and
the loop with the friction terms of the contact force removed (mu = 0 only). Every
variant is compiled with the shipped series' flags unless it says otherwise.
"""

from __future__ import annotations

import argparse
import inspect
import math
import re
import sys
import time
from pathlib import Path

import numba
import numpy as np
from machine import describe
from work_precision import FIG3, START

from rubcli import model
from rubcli.model import ModelParams
from rubcli.problem import Problem
from rubcli.solvers import solve
from rubcli.solvers.compiled import taylor as tk

HERE = Path(__file__).resolve().parent
TARGETS = (1e-6, 1e-10)
SHIPPED_FLAGS = {"fastmath": {"contract"}}  # the series' flags (compiled/jit.py jit_fused)
M = tk.MAX_ORDER


def slip_series_variant(replacements=(), **jit_options):
    """The shipped slip series (``taylor._slip_coefficients``) compiled again from its
    own source with the textual ``replacements`` (old, new) applied, with the shipped
    flags unless ``jit_options`` says otherwise: a variant of the same recurrences rather
    than a copy of them. Fails if a replacement no longer matches the source."""
    source = inspect.getsource(tk._slip_coefficients.py_func)
    source = re.sub(r"^@\w+\n", "", source)  # the decorator
    jit_options = {**SHIPPED_FLAGS, **jit_options}
    for old, new in replacements:
        if old not in source:
            raise RuntimeError(f"not in the shipped slip series any more: {old.strip()!r}")
        source = source.replace(old, new)
    namespace = dict(tk.__dict__)
    exec(source, namespace)
    return numba.njit(**jit_options)(namespace["_slip_coefficients"])


# The series of u(s) = w(t0 + s) e^{-i eta s}: u'' = E F0 - (2 nu + 2 i eta) u' - (1 -
# eta^2 + 2 i nu eta) u - K (u - u / |u|) (1 + i mu_c), F0 the forcing at the step's
# start (constant in this frame); |u| = |w|, so q, z and P = u / z keep their recurrences.
_rotating_series = slip_series_variant(
    (
        ("    mu_c = pars[5] * sign\n",
         "    mu_c = pars[5] * sign\n    c1, c2, e2 = 1.0 - eta * eta, nu2 * eta, 2.0 * eta\n"),
        ("ax = E * fr - nu2 * C[2, k] - C[0, k] - K",
         "ax = E * fr - nu2 * C[2, k] + e2 * C[3, k] - c1 * C[0, k] + c2 * C[1, k] - K"),
        ("ay = E * fi - nu2 * C[3, k] - C[1, k] - K",
         "ay = E * fi - nu2 * C[3, k] - e2 * C[2, k] - c1 * C[1, k] - c2 * C[0, k] - K"),
        ("        fr, fi = -fi * rotate, fr * rotate\n", "        fr, fi = 0.0, 0.0\n"),
    )
)  # fmt: skip


@numba.njit
def _scaled_step(C, y, order, rtol, atol, wv):
    """``step_size`` with the velocity rows (coefficients and state) weighted by wv."""
    scale = max(max(abs(y[0]), abs(y[1])), wv * max(abs(y[2]), abs(y[3])))
    log_eps = math.log(max(atol, rtol * scale))
    exponent = math.inf
    for k in (order - 1, order):
        norm = max(max(abs(C[0, k]), abs(C[1, k])), wv * max(abs(C[2, k]), abs(C[3, k])))
        if norm > 0.0:
            exponent = min(exponent, (log_eps - math.log(norm)) / k)
    return math.exp(exponent - tk.STEP_SAFETY_EXPONENT / (order - 1))


@numba.njit
def slip_stretch(t, y, t_end, pars, order, rtol, atol, variant):
    """Taylor steps in slip (mu = 0) from (t, y) to t_end; variant 0 the kernel's, 1
    rotating, 2 scaled norm. Returns the steps; y holds the final state."""
    C = np.zeros((4, M + 1))
    W = np.zeros((tk.WORK_ROWS, tk.WORK_COLS))
    out = np.empty(4)
    eta = pars[1]
    wv = 1.0 / math.sqrt(1.0 + pars[4])
    steps = 0
    while t < t_end:
        fr, fi = math.cos(eta * t + pars[3]), math.sin(eta * t + pars[3])
        C[0, 0], C[1, 0] = y[0], y[1]
        if variant == 1:
            C[2, 0], C[3, 0] = y[2] + eta * y[1], y[3] - eta * y[0]
            _rotating_series(fr, fi, pars, 1.0, order, C, W)
            h, _ = tk.step_size(C, order, rtol, atol)
        else:
            C[2, 0], C[3, 0] = y[2], y[3]
            tk._slip_coefficients(fr, fi, pars, 1.0, order, C, W)
            if variant == 2:
                h = _scaled_step(C, y, order, rtol, atol, wv)
            else:
                h, _ = tk.step_size(C, order, rtol, atol)
        h = min(h, t_end - t)
        tk.dense_at(t + h, t, C, order, out)
        if variant == 1:
            c, s = math.cos(eta * h), math.sin(eta * h)
            ux, uy = out[2] - eta * out[1], out[3] + eta * out[0]
            y[0], y[1] = c * out[0] - s * out[1], s * out[0] + c * out[1]
            y[2], y[3] = c * ux - s * uy, s * ux + c * uy
        else:
            for i in range(4):
                y[i] = out[i]
        t += h
        steps += 1
    return steps


VARIANTS = {"kernel's series and step": 0, "rotating": 1, "scaled norm": 2}


def cpu_min(fn, repeats: int) -> float:
    best = math.inf
    for _ in range(repeats):
        c0 = time.process_time()
        fn()
        best = min(best, time.process_time() - c0)
    return best


def variant_table(quick: bool, repeats: int) -> list[str]:
    params = ModelParams(K=17.6, mu=0.0, **FIG3)
    problem = Problem.from_periods(params, START, 100, 1)
    t_end = float(problem.t_eval[-1])
    reference = solve(problem, "dop853-jit", rtol=1e-13, atol=1e-15).states[-1]
    entry = solve(problem, "taylor", rtol=1e-12, atol=1e-14).events
    t0, y0 = float(entry.tau[-1]), np.array(entry.state[-1])
    pars = np.array(model.params_vector(params))
    exponents = np.arange(6.0, 11.01, 1.0 if quick else 0.5)
    lines = [
        f"Slip from the last contact entry (tau = {t0:.4f}) to tau = {t_end:.2f}, "
        f"mu = 0, K = 17.6; CPU time, minimum of {repeats}.",
        "",
        "| rtol | N | variant | steps | error | ms |",
        "|---|---|---|---|---|---|",
    ]
    rows: dict[str, list[tuple[float, float, float]]] = {v: [] for v in VARIANTS}
    for e in exponents:
        rtol = 10.0**-e
        order = tk.taylor_order(rtol)
        for name, code in VARIANTS.items():
            y = y0.copy()
            steps = slip_stretch(t0, y, t_end, pars, order, rtol, rtol * 1e-2, code)
            error = math.hypot(y[0] - reference[0], y[1] - reference[1])
            ms = 1e3 * cpu_min(
                lambda c=code, r=rtol, n=order: slip_stretch(
                    t0, y0.copy(), t_end, pars, n, r, r * 1e-2, c
                ),
                repeats,
            )
            rows[name].append((rtol, error, ms))
            lines.append(f"| {rtol:.1e} | {order} | {name} | {steps} | {error:.2e} | {ms:.3f} |")
    header = "| variant | " + " | ".join(f"to {t:.0e}" for t in TARGETS) + " |"
    lines += ["", header, "|---|---|---|"]
    for name, results in rows.items():
        cells = []
        for target in TARGETS:
            hits = [(ms, rtol) for rtol, error, ms in results if error <= target]
            cells.append(f"{min(hits)[0]:.3f} ms (rtol {min(hits)[1]:.0e})" if hits else "-")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def _unrolled_source(order: int) -> str:
    """``_slip_coefficients`` as straight-line code for one order: every Cauchy sum
    written out over local variables, the same results stored (at the end)."""
    src = [
        "def unrolled(fr, fi, pars, C, W):",
        "    nu2 = 2.0 * pars[0]; eta = pars[1]; E = pars[2]; K = pars[4]; mu_c = pars[5]",
        "    x0 = C[0, 0]; y0 = C[1, 0]; vx0 = C[2, 0]; vy0 = C[3, 0]",
        "    q0 = x0 * x0 + y0 * y0; W[0, 0] = q0; z0 = math.sqrt(q0); W[3, 0] = z0",
        "    iz = 1.0 / z0; hz = 0.5 * iz",
        "    px0 = x0 * iz; py0 = y0 * iz; gx = x0 - px0; gy = y0 - py0",
    ]
    for k in range(order):
        m = k + 1
        inv = repr(1.0 / m)
        src += [
            f"    ax = E * fr - nu2 * vx{k} - x{k} - K * (gx - mu_c * gy)",
            f"    ay = E * fi - nu2 * vy{k} - y{k} - K * (gy + mu_c * gx)",
            f"    rot = eta * {inv}; fr, fi = -fi * rot, fr * rot",
            f"    x{m} = vx{k} * {inv}; y{m} = vy{k} * {inv}",
            f"    vx{m} = ax * {inv}; vy{m} = ay * {inv}",
        ]
        # the shipped sums' order: newest terms (order m - 1) last
        half = range((m + 1) // 2 - 1, 0, -1)
        pairs = [f"(x{j} * x{m - j} + y{j} * y{m - j})" for j in half]
        sq = f"2.0 * (0.0 + {' + '.join(pairs)})" if pairs else "0.0"
        zz = [f"z{j} * z{m - j}" for j in half]
        sz = f"2.0 * (0.0 + {' + '.join(zz)})" if zz else "0.0"
        if m % 2 == 0:
            c = m // 2
            sq += f" + (x{c} * x{c} + y{c} * y{c})"
            sz += f" + z{c} * z{c}"
        js = [*range(2, m - 1), *([m - 1] if m >= 3 else []), *([1] if m >= 2 else [])]
        sx = " + ".join(["0.0", *(f"z{j} * px{m - j}" for j in js)])
        sy = " + ".join(["0.0", *(f"z{j} * py{m - j}" for j in js)])
        src.append(f"    q{m} = {sq} + 2.0 * (x0 * x{m} + y0 * y{m})")
        if m == order:  # without friction the shipped series stops here (no z_N, P_N)
            continue
        src += [
            f"    z{m} = (q{m} - ({sz})) * hz",
            f"    px{m} = (x{m} - ({sx}) - z{m} * px0) * iz",
            f"    py{m} = (y{m} - ({sy}) - z{m} * py0) * iz",
            f"    gx = x{m} - px{m}; gy = y{m} - py{m}",
        ]
    for m in range(1, order + 1):
        src.append(f"    C[0, {m}] = x{m}; C[1, {m}] = y{m}; C[2, {m}] = vx{m}; C[3, {m}] = vy{m}")
        src.append(f"    W[0, {m}] = q{m}")
        if m < order:
            src.append(f"    W[3, {m}] = z{m}; W[4, {m}] = px{m}; W[5, {m}] = py{m}")
    return "\n".join(src)


def _repeat_loop(series, with_order: bool):
    """A compiled loop of n series calls (the order a run-time argument, as in the
    kernel; the unrolled variant has its own fixed)."""
    if with_order:

        @numba.njit
        def loop(n, pars, order, C, W):
            acc = 0.0
            for i in range(n):
                C[0, 0] = 1.1 + 1e-9 * i
                series(0.9, 0.1, pars, 1.0, order, C, W)
                acc += C[0, 1]
            return acc

        return loop

    @numba.njit
    def loop_fixed(n, pars, order, C, W):
        acc = 0.0
        for i in range(n):
            C[0, 0] = 1.1 + 1e-9 * i
            series(0.9, 0.1, pars, C, W)
            acc += C[0, 1]
        return acc

    return loop_fixed


def series_table(repeats: int) -> list[str]:
    pars = np.array([0.009478, 0.7818, 7.52 * 0.7818**2, 0.0, 17.6, 0.0, 46.16])
    plain = slip_series_variant(fastmath=False)
    frictionless = slip_series_variant(
        (("K * (gx - mu_c * gy)", "K * gx"), ("K * (gy + mu_c * gx)", "K * gy"))
    )
    lines = [
        "Slip series alone (mu = 0), ns a series, minimum of the repeats of 100,000 calls.",
        "",
        "| order | loop (shipped) | unrolled | loop without FMA contraction | loop without the "
        "friction terms |",
        "|---|---|---|---|---|",
    ]
    n = 100_000
    for order in (13, 18):
        generated: dict = {"math": math}
        exec(_unrolled_source(order), generated)
        unrolled = numba.njit(**SHIPPED_FLAGS)(generated["unrolled"])
        loops = (
            _repeat_loop(tk._slip_coefficients, True),
            _repeat_loop(unrolled, False),
            _repeat_loop(plain, True),
            _repeat_loop(frictionless, True),
        )
        cells = []
        results = []
        for loop in loops:
            C = np.zeros((4, M + 1))
            W = np.zeros((tk.WORK_ROWS, tk.WORK_COLS))
            C[:, 0] = [1.1, 0.3, -0.2, 0.9]
            loop(1, pars, order, C, W)
            results.append(C[:, : order + 1].copy())
            best = math.inf
            for _ in range(repeats):
                start = time.perf_counter()
                loop(n, pars, order, C, W)
                best = min(best, time.perf_counter() - start)
            cells.append(f"{best / n * 1e9:.0f}")
        spread = max(float(np.max(np.abs(r - results[0]))) for r in results)
        if spread > 1e-12 * float(np.max(np.abs(results[0]))):
            raise RuntimeError(f"the series variants disagree at order {order}: {spread:.1e}")
        lines.append(f"| {order} | " + " | ".join(cells) + " |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="decade ladder, fewer repeats")
    opts = ap.parse_args(argv)
    repeats = 5 if opts.quick else 20
    text = [
        "# `taylor` without friction: variants of the step (benchmarks/taylor_variants.py)",
        "",
        f"Command: `python benchmarks/taylor_variants.py{' --quick' if opts.quick else ''}`. "
        + describe(),
        "",
        *variant_table(opts.quick, repeats),
        "",
        *series_table(repeats),
        "",
    ]
    print("\n".join(text))
    name = "taylor_variants-quick.md" if opts.quick else "taylor_variants.md"
    (HERE / name).write_text("\n".join(text))
    return 0


if __name__ == "__main__":
    sys.exit(main())
