"""Atomic writers and staged output dirs: complete files or none."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rubcli import io


def test_atomic_path_replaces_only_on_success(tmp_path):
    target = tmp_path / "a.txt"
    io.write_text(target, "old")
    with pytest.raises(RuntimeError), io.atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]  # no temp file left
    io.write_text(target, "new")
    assert target.read_text() == "new"


def test_written_files_get_the_usual_mode(tmp_path):
    """A staged file gets the mode a plain open() would give it: 0o666 less the umask
    (a temp file's own 0o600 must not leak into the output)."""
    import os
    import stat

    for umask in (0o022, 0o077, 0o002):
        old = os.umask(umask)
        try:
            path = io.write_text(tmp_path / f"a{umask:o}.txt", "x")
        finally:
            os.umask(old)
        assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


def test_json_writer_handles_numpy_and_non_finite(tmp_path):
    data = {"a": np.float64(1.5), "b": np.arange(3), "c": math.nan, "d": (1, math.inf)}
    path = io.write_json(tmp_path / "r.json", data)
    assert json.loads(path.read_text()) == {"a": 1.5, "b": [0, 1, 2], "c": None, "d": [1, None]}


def test_staged_output_dir_commits_on_success(tmp_path):
    target = tmp_path / "out"
    with io.staged_output_dir(target) as staged:
        io.write_text(staged.path("a.csv"), "1")
        io.write_text(staged.path("report.json"), "{}")
        assert not target.exists()
    assert sorted(p.name for p in target.iterdir()) == ["a.csv", "report.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_staged_output_dir_writes_nothing_on_failure(tmp_path):
    target = tmp_path / "out"
    with pytest.raises(ValueError), io.staged_output_dir(target) as staged:
        io.write_text(staged.path("a.csv"), "1")
        raise ValueError
    assert list(tmp_path.iterdir()) == []


def test_staged_output_keeps_other_files_in_the_target(tmp_path):
    target = tmp_path / "out"
    target.mkdir()
    (target / "notes.txt").write_text("mine")
    (target / "a.csv").write_text("old")
    with io.staged_output_dir(target) as staged:
        io.write_text(staged.path("a.csv"), "new")
    assert (target / "a.csv").read_text() == "new"
    assert (target / "notes.txt").read_text() == "mine"


def test_staged_names_are_plain_file_names(tmp_path):
    with io.staged_output_dir(tmp_path / "out") as staged, pytest.raises(ValueError):
        staged.path("../escape.csv")
