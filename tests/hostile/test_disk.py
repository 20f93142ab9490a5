"""Full disks, file size limits, names too long and a stdout that cannot be written.

A write that fails for want of space (ENOSPC, EFBIG, EDQUOT) ends the command with exit
74 and a message naming the dir and the reason; nothing of the run is written, the
previous outputs are kept, no staging is left (README, "Exit codes"). The full disk is
made with ``RLIMIT_FSIZE`` (every file past the limit fails with EFBIG) and, where mount
namespaces are permitted, with a small tmpfs (ENOSPC).
"""

from __future__ import annotations

import json
import os
import sys

import pytest

from .conftest import LONG_CASE, SMALL_CASE, SWEEP_CASE, fsize_limit, snapshot, visible


def _hidden(directory) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.name.startswith("."))


@pytest.mark.slow
def test_a_csv_past_the_file_size_limit(run_cli, case_file, out_dir, previous):
    before = previous(out_dir)
    run = run_cli("run", case_file(LONG_CASE), "--out", out_dir,
                  preexec=fsize_limit(1 << 20))  # fmt: skip
    assert run.code == 74, run.stderr
    assert f"{out_dir}: could not write the outputs: File too large" in run.stderr
    assert "nothing of this run was written, the previous outputs are unchanged" in run.stderr
    assert snapshot(out_dir) == before and _hidden(out_dir) == []


@pytest.mark.slow
def test_a_report_past_the_file_size_limit(run_cli, case_file, out_dir, previous):
    """The report alone (no CSV, no figure) does not fit: the same."""
    before = previous(out_dir)
    case = case_file(SMALL_CASE + "csv = false\n")
    run = run_cli("run", case, "--out", out_dir, preexec=fsize_limit(2000))
    assert run.code == 74, run.stderr
    assert "File too large (report.json)" in run.stderr
    assert snapshot(out_dir) == before and _hidden(out_dir) == []


@pytest.mark.slow
def test_a_sweep_whose_netcdf_does_not_fit_keeps_its_points(run_cli, case_file, out_dir):
    """sweep.nc past the limit: exit 74, the computed points kept in the store (named in
    the message), nothing half-written; run again with room: the points are resumed."""
    case = case_file(SWEEP_CASE)
    run = run_cli("sweep", case, "--out", out_dir, "--workers", "1",
                  preexec=fsize_limit(16000))  # fmt: skip
    assert run.code == 74, run.stderr
    assert "could not write the outputs" in run.stderr
    assert "5 of 5 points are kept in" in run.stderr and "run the same command" in (run.stderr)
    assert visible(out_dir) == []  # nothing half-written: only the store, hidden, inside
    assert [p.name for p in out_dir.iterdir() if p.name.startswith(".rubcli-sweep-")]
    run = run_cli("sweep", case, "--out", out_dir, "--workers", "1")
    assert run.code == 0, run.stderr
    assert json.loads((out_dir / "report.json").read_text())["points_resumed"] == 5


@pytest.mark.slow
def test_a_full_tmpfs(in_namespace, case_file):
    """A real full file system (a 400 kB tmpfs): the first run fits, the second does not
    (ENOSPC): exit 74, the first run's files as they were."""
    small, long_case = case_file(), case_file(LONG_CASE, "long.toml")
    script = f"""
mkdir -p disk && mount -t tmpfs -o size=400k tmpfs disk || exit 99
$RUBCLI run {small} --out disk/out || exit 98
{sys.executable} -c "import hashlib, os; print(sorted((n, hashlib.sha256(open('disk/out/' + n, 'rb').read()).hexdigest()) for n in os.listdir('disk/out')))" > before.txt
$RUBCLI run {long_case} --out disk/out
echo "code=$?"
{sys.executable} -c "import hashlib, os; print(sorted((n, hashlib.sha256(open('disk/out/' + n, 'rb').read()).hexdigest()) for n in os.listdir('disk/out')))" > after.txt
ls -A disk > listing.txt
"""  # noqa: E501
    run = in_namespace(script)
    assert "code=74" in run.stdout, (run.stdout, run.stderr)
    assert "No space left on device" in run.stderr and "Traceback" not in run.stderr
    here = small.parent
    assert (here / "before.txt").read_text() == (here / "after.txt").read_text()
    assert (here / "listing.txt").read_text().split() == ["out"]


@pytest.mark.slow
def test_an_output_name_longer_than_the_file_system_allows(run_cli, case_file, tmp_path):
    name = "x" * 300
    run = run_cli("run", case_file(), "--out", tmp_path / name / "out")
    assert run.code == 2
    assert "is 300 bytes long; this file system allows at most 255" in run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.toml"]


@pytest.mark.slow
def test_a_full_stdout(run_cli, case_file, tmp_path):
    """`init > /dev/full`, `--json > /dev/full`: a message on stderr, exit 74."""
    case = case_file()
    for args in (["init"], ["validate", case, "--json"], ["run", case, "--json", "--out",
                                                          tmp_path / "out"]):  # fmt: skip
        run = run_cli(*args, stdout="/dev/full")
        assert run.code == 74, (args, run.stderr)
        assert "cannot write to standard output: No space left on device" in run.stderr


@pytest.mark.parametrize("args", [["--help"], []])
def test_the_help_to_a_full_stdout(run_cli, args):
    """The help (also the group's, printed while its arguments are parsed): exit 74."""
    run = run_cli(*args, stdout="/dev/full")
    assert run.code == 74, run.stderr
    assert "No space left on device" in run.stderr


def _stdout_a_pipe_nobody_reads() -> None:
    """In the child: stdout is a pipe whose reading end is closed (`| head -1` once head
    has left), so that every write to it fails with EPIPE."""
    read, write = os.pipe()
    os.dup2(write, 1)
    os.close(read)
    os.close(write)


@pytest.mark.parametrize("args", [["--help"], [], ["run", "--help"]])
def test_the_help_to_a_closed_pipe(run_cli, args):
    """The help (also the group's): the closed pipe's exit 141, silently, as a command's
    output to it, where rich's own handling exited 1."""
    run = run_cli(*args, preexec=_stdout_a_pipe_nobody_reads)
    assert run.code == 141, run.stderr
    assert run.stderr == ""


@pytest.mark.slow
def test_a_disk_full_at_the_check_is_exit_74_and_leaves_no_lock(run_cli, case_file, out_dir,
                                                                previous, tmp_path):  # fmt: skip
    """Not even the lock fits (every write fails): exit 74 before anything is computed,
    and neither the lock nor the dir made for the command is left."""
    previous(tmp_path / "earlier")  # the session's key is made (no write of it could be)
    run = run_cli("run", case_file(), "--out", out_dir, preexec=fsize_limit(0))
    assert run.code == 74, run.stderr
    assert f"{out_dir}: the output dir cannot be written (File too large)" in run.stderr
    assert not out_dir.exists()
    out_dir.mkdir()
    run = run_cli("run", case_file(), "--out", out_dir, preexec=fsize_limit(0))
    assert run.code == 74, run.stderr
    assert _hidden(out_dir) == []


@pytest.mark.slow
def test_a_disk_full_everywhere_with_the_key_at_home_is_exit_74(run_cli, case_file, out_dir,
                                                               tmp_path):  # fmt: skip
    """No RUBCLI_STATE_DIR, the key in its home place, and no temporary dir usable (every
    write fails): the key is read from home and the check says the dir cannot be written,
    where looking for a temporary dir as the key's last place ended in a traceback."""
    env = {"RUBCLI_STATE_DIR": "", "XDG_STATE_HOME": str(tmp_path / "state")}
    assert run_cli("run", case_file(), "--out", tmp_path / "first", env=env).code == 0
    run = run_cli("run", case_file(), "--out", out_dir, env=env, preexec=fsize_limit(0))
    assert run.code == 74, run.stderr
    assert f"{out_dir}: the output dir cannot be written (File too large)" in run.stderr
    assert not out_dir.exists()


@pytest.mark.slow
def test_a_full_tmpfs_at_the_check(in_namespace, case_file):
    """A file system with no room left at all (ENOSPC on the lock's first write): exit
    74, no lock left."""
    case = case_file()
    script = f"""
mkdir -p disk && mount -t tmpfs -o size=64k tmpfs disk || exit 99
mkdir disk/out
dd if=/dev/zero of=disk/fill bs=4k 2>/dev/null
$RUBCLI run {case} --out disk/out
echo "code=$?"
ls -A disk/out > listing.txt
"""
    run = in_namespace(script)
    assert "code=74" in run.stdout, (run.stdout, run.stderr)
    assert "No space left on device" in run.stderr and "Traceback" not in run.stderr
    assert (case.parent / "listing.txt").read_text() == ""
