"""Shared fixtures of the hostile suite: the real command line, end to end, under faults.

Every test here runs ``rubcli`` as a user would, in a subprocess (``python -m rubcli``),
and checks what the user sees (exit code, one clear message, never a traceback) and what
is left on disk. Test files of any area may use these fixtures (this conftest is the
only one of the directory; keep it general):

- ``run_cli(*args, ...)``: run the command line in a subprocess with a timeout; returns a
  ``Run`` (``code``, ``stdout``, ``stderr``) and asserts that stderr holds no traceback
  (``traceback_ok=True`` to allow one). ``cwd``, ``env`` (added to the environment),
  ``stdout`` (a file name to redirect to, e.g. ``/dev/full``), ``preexec`` (a function
  run in the child before exec, e.g. ``fsize_limit(n)``), ``fault`` (a fault injected by
  ``launcher.py``: a signal, SIGKILL or a pause at a chosen import, call or commit move;
  see its docstring) and ``background=True`` (returns the ``Popen``; the test waits).
- ``out_dir``: a fresh, not yet existing output dir in the test's temporary dir.
- ``previous(target, *methods)``: fills ``target`` with the outputs of a finished
  ``rubcli run`` of ``SMALL_CASE`` with these methods (default rk45): a rubcli dir with
  its signed manifest, made once per session and copied (the previous good outputs that
  a failed or stopped run must leave as they are).
- ``case_file(text=SMALL_CASE, name="case.toml")``: writes a case file (the texts below:
  ``SMALL_CASE`` 2 periods of rk45, ``LONG_CASE`` 300 periods of dop853-jit,
  ``SWEEP_CASE`` a 5-point sweep, ``ORBITS_CASE`` an orbits table that fails at once).
- ``fsize_limit(n_bytes)``: a ``preexec`` that caps the size of any file the child
  writes (``RLIMIT_FSIZE``, SIGXFSZ ignored: a write beyond fails with EFBIG), the way a
  full disk fails a write.
- ``in_namespace(shell_script)``: runs a shell script in a private mount namespace
  (``unshare -rm``), where it may mount a small tmpfs or a bind mount; skips the test when
  namespaces are not permitted. Mounts vanish with the process.
- ``visible(directory)``: the names in a directory that do not start with a dot;
  ``snapshot(directory)``: name -> bytes of its visible files.

Subprocesses get the session's ``RUBCLI_STATE_DIR`` (the manifest key, in a temporary
dir: tests/conftest.py), so that the suite never touches the user's home.

``RUBCLI_UNDER_TEST=/path/to/a/checkout`` runs the command line of that checkout in the
subprocesses (its dir is put first on their ``PYTHONPATH``): how a test is checked to
fail on an older rubcli.
"""

from __future__ import annotations

import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
LAUNCHER = HERE / "launcher.py"
ROOT = HERE.parents[1]
TIMEOUT_S = 180
TRACEBACK = re.compile(r'Traceback|^\s*File "|SystemError|KeyboardInterrupt', re.M)

SMALL_CASE = """\
[case]
name = "small"

[model]
nu = 0.009478
eta = 0.7818
e = 7.52
K = 17.6
mu = 0.01
Rp = 46.16

[initial]
x = 0.88544
y = -0.8039

[time]
periods = 2
samples_per_period = 20

[solver]
methods = ["rk45"]

[output]
plots = []
"""

# Long enough that each phase (solve, energy balance, CSV, figures) lasts a while: 30001
# samples of dop853-jit (about 0.1 s to solve, 10 ms in the compiled energy balance, a
# 3 MB CSV).
LONG_CASE = (
    SMALL_CASE.replace("periods = 2", "periods = 300")
    .replace("samples_per_period = 20", "samples_per_period = 100")
    .replace('methods = ["rk45"]', 'methods = ["dop853-jit"]')
    .replace("plots = []", 'plots = ["orbit"]')
)


# A sweep of a free rotor (never touching): 5 points, about a second each.
SWEEP_CASE = """\
[case]
name = "free"
[model]
nu = 0.1
eta = 1.0
e = 0.05
K = 10.0
mu = 0.1
Rp = 2.0
[initial]
x = 0.0
y = 0.0
[time]
periods = 10
samples_per_period = 32
[sweep]
parameter = "eta"
values = [0.5, 0.8, 1.0, 1.3, 2.0]
transient_periods = 20
record_periods = 8
"""

# An [orbits] table whose first shooting fails at once (one Newton step): orbits exits 1
# with report.json only, in a second.
ORBITS_CASE = (
    SMALL_CASE
    + """
[orbits]
parameter = "eta"
min = 0.7
max = 0.8
step = 0.005
max_newton = 1
"""
)


@dataclass
class Run:
    code: int
    stdout: str
    stderr: str


def _child_environment() -> dict[str, str]:
    environment = dict(os.environ)
    under_test = os.environ.get("RUBCLI_UNDER_TEST")
    if under_test:
        environment["PYTHONPATH"] = os.pathsep.join(
            [under_test, *filter(None, [os.environ.get("PYTHONPATH")])]
        )
    return environment


def has_traceback(text: str) -> bool:
    return bool(TRACEBACK.search(text))


@pytest.fixture(scope="session")
def state_dir(private_state_dir) -> Path:
    """The manifest key's dir of the session (tests/conftest.py)."""
    return Path(private_state_dir)


@pytest.fixture
def run_cli(state_dir, tmp_path):
    def run(*args, cwd=None, env=None, stdout=None, preexec=None, fault=None,
            background=False, timeout=TIMEOUT_S, traceback_ok=False):  # fmt: skip
        environment = {**_child_environment(), "RUBCLI_STATE_DIR": str(state_dir),
                       "COLUMNS": "100"}  # fmt: skip
        environment.update(env or {})
        if fault is not None:
            environment["RUBCLI_HOSTILE_FAULT"] = json.dumps(fault)
            command = [sys.executable, str(LAUNCHER)]
        else:
            command = [sys.executable, "-m", "rubcli"]
        command += [str(a) for a in args]
        out = open(stdout, "w") if stdout else subprocess.PIPE  # noqa: SIM115
        try:
            proc = subprocess.Popen(
                command, cwd=cwd or tmp_path, env=environment, stdout=out,
                stderr=subprocess.PIPE, text=True, preexec_fn=preexec,
            )  # fmt: skip
        finally:
            if stdout:
                out.close()
        if background:
            return proc
        try:
            captured, err = proc.communicate(timeout=timeout)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        if not traceback_ok:
            assert not has_traceback(err), err
        return Run(proc.returncode, captured or "", err)

    return run


def finish(proc: subprocess.Popen, timeout: float = TIMEOUT_S, traceback_ok=False) -> Run:
    """Wait for a ``run_cli(..., background=True)`` process; no traceback in stderr."""
    try:
        out, err = proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    if not traceback_ok:
        assert not has_traceback(err), err
    return Run(proc.returncode, out or "", err)


def wait_for(path: Path, proc: subprocess.Popen | None = None, timeout: float = 120) -> None:
    """Wait until ``path`` exists (a launcher's marker), failing if ``proc`` ends first."""
    deadline = time.monotonic() + timeout
    while not path.exists():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"ended before {path.name}: {proc.communicate()}")
        assert time.monotonic() < deadline, f"no {path.name} after {timeout} s"
        time.sleep(0.005)


@pytest.fixture(scope="session")
def _templates(tmp_path_factory, state_dir):
    made: dict[tuple[str, ...], Path] = {}
    base = tmp_path_factory.mktemp("previous-runs")

    def get(methods: tuple[str, ...]) -> Path:
        if methods not in made:
            case = base / "case.toml"
            case.write_text(SMALL_CASE, encoding="utf-8")
            target = base / "-".join(methods)
            args = [sys.executable, "-m", "rubcli", "run", str(case), "--out", str(target)]
            for method in methods:
                args += ["-m", method]
            env = {**_child_environment(), "RUBCLI_STATE_DIR": str(state_dir)}
            done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
            assert done.returncode == 0, done.stderr
            made[methods] = target
        return made[methods]

    return get


@pytest.fixture
def previous(_templates):
    def fill(target: Path, *methods: str) -> dict[str, bytes]:
        shutil.copytree(_templates(tuple(methods) or ("rk45",)), target)
        return snapshot(target)

    return fill


@pytest.fixture
def out_dir(tmp_path) -> Path:
    return tmp_path / "out"


@pytest.fixture
def case_file(tmp_path):
    def write(text: str = SMALL_CASE, name: str = "case.toml") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write


def fsize_limit(n_bytes: int):
    """A ``preexec`` that makes every write past ``n_bytes`` of a file fail with EFBIG."""

    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (n_bytes, n_bytes))

    return limit


def _namespaces_permitted() -> bool:
    if shutil.which("unshare") is None or sys.platform != "linux":
        return False
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"],
                           capture_output=True, timeout=30)  # fmt: skip
    return probe.returncode == 0


@pytest.fixture(scope="session")
def namespaces() -> bool:
    return _namespaces_permitted()


@pytest.fixture
def in_namespace(namespaces, state_dir, tmp_path):
    """Run a shell script in a private mount namespace (skip the test if not permitted).
    ``$RUBCLI`` in the script runs the command line (``python -m rubcli``)."""
    if not namespaces:
        pytest.skip("mount namespaces (unshare -rm) are not permitted here")

    def run(script: str, timeout: float = TIMEOUT_S) -> Run:
        env = {**_child_environment(), "RUBCLI_STATE_DIR": str(state_dir),
               "RUBCLI": f"{sys.executable} -m rubcli"}  # fmt: skip
        proc = subprocess.run(["unshare", "-rm", "sh", "-c", script], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=timeout)  # fmt: skip
        return Run(proc.returncode, proc.stdout, proc.stderr)

    return run


def visible(directory: Path) -> list[str]:
    if not directory.exists():
        return []
    return sorted(p.name for p in directory.iterdir() if not p.name.startswith("."))


def snapshot(directory: Path) -> dict[str, bytes]:
    return {name: (directory / name).read_bytes() for name in visible(directory)}
