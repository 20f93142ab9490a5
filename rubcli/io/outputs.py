"""Output dirs: checked before anything is computed, written staged, committed at the end.

``staged_output_dir`` writes every file of a run into a hidden staging directory and
moves them in only when the run got that far, so a run that fails part way (an
exception, Ctrl-C, SIGTERM) leaves no outputs.

The rules of an output dir (``check_output_dir``, called by every command before it
computes anything):

- it must be a directory or not exist yet, and be creatable and writable (tried, not
  guessed: a probe directory is made and removed);
- a dir that holds files is used only if rubcli wrote it: its ``report.json`` is a rubcli
  report whose ``files`` list is the *manifest* of the run that wrote it. Files of that
  manifest which the new run does not write are removed after the new run committed
  (they would be stale results beside a new report) and named in a warning;
- a non-empty dir without a manifest (``--out .``, a home dir, someone's data) is refused
  unless ``force``; with ``force`` rubcli writes its files and leaves the others alone.
  Sub-directories that hold a rubcli manifest (the ``compare/`` and ``forces-map/`` dirs
  inside a case's output dir) do not count.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from rubcli.io.files import atomic_path

REPORT_NAME = "report.json"


STAGING_PREFIX = ".rubcli-staging-"


class OutputError(Exception):
    """An output location that cannot be used; the message says which and why."""


@dataclass
class OutputPlan:
    """What ``check_output_dir`` found: where to write and what a previous run left."""

    target: Path
    previous: list[str] = field(default_factory=list)  # files of the previous manifest
    foreign: list[str] = field(default_factory=list)  # files no rubcli manifest lists
    removed: list[str] = field(default_factory=list)  # stale files removed at commit


def read_manifest(directory: Path) -> list[str] | None:
    """The ``files`` of a rubcli report.json in ``directory``, or None if it has none."""
    try:
        report = json.loads((directory / REPORT_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(report, dict) or "rubcli_version" not in report:
        return None
    files = report.get("files")
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        return None
    return [f for f in files if Path(f).name == f and f not in ("", ".", "..")]


def _nearest_existing(path: Path) -> Path:
    for candidate in (path, *path.parents):
        if os.path.lexists(candidate):
            return candidate
    return Path(".")


def check_output_dir(target: str | Path, *, force: bool = False) -> OutputPlan:
    """Check an output dir before anything is computed; raise OutputError saying why not.

    See the module docstring for the rules. Nothing is created or changed here (the probe
    directory is removed again).
    """
    target = Path(target)
    if target.exists() and not target.is_dir():
        raise OutputError(f"{target}: output dir exists and is not a directory")
    if os.path.lexists(target) and not target.exists():
        raise OutputError(f"{target}: output dir is a broken symbolic link")
    base = _nearest_existing(target.absolute())
    if not base.is_dir():
        raise OutputError(f"{target}: cannot create the output dir: {base} is not a directory")
    try:
        probe = tempfile.mkdtemp(dir=base, prefix=".rubcli-probe-")
        os.rmdir(probe)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise OutputError(f"{target}: output dir is not writable ({base}: {reason})") from None
    plan = OutputPlan(target=target)
    if not target.is_dir():
        return plan
    entries = sorted(
        p.name
        for p in target.iterdir()
        if not p.name.startswith(STAGING_PREFIX)
        # a sub-dir written by rubcli (`compare/`, `forces-map/` of a case) is no obstacle
        and not (p.is_dir() and read_manifest(p) is not None)
    )
    if not entries:
        return plan
    manifest = read_manifest(target)
    if manifest is None:
        if not force:
            shown = ", ".join(entries[:5]) + (f" and {len(entries) - 5} more" if len(entries) > 5
                                              else "")  # fmt: skip
            raise OutputError(
                f"{target}: output dir is not empty and was not written by rubcli (no rubcli "
                f"report.json; it holds {shown}); choose a new or empty dir, or pass --force "
                "to write beside these files"
            )
        plan.foreign = entries
        return plan
    plan.previous = manifest
    plan.foreign = [e for e in entries if e not in manifest and e != REPORT_NAME]
    return plan


def _move(source: Path, destination: Path) -> None:
    """Move a staged file over ``destination`` atomically, also across filesystems (a
    copy to a temporary file beside the destination, then a rename there)."""
    try:
        os.replace(source, destination)
    except OSError as exc:
        if exc.errno != errno.EXDEV:
            raise
        with atomic_path(destination) as tmp:
            shutil.copyfile(source, tmp)
        source.unlink(missing_ok=True)


def _same_device(a: Path, b: Path) -> bool:
    try:
        return os.stat(a).st_dev == os.stat(b).st_dev
    except OSError:
        return True


class StagedOutput:
    """A staging directory whose files are moved into ``target`` by ``commit()``.

    The staging directory is made in the target's real parent (symbolic links resolved),
    or inside the target itself when the target is a mount point, so that the final moves
    are renames on one filesystem; a move that still crosses filesystems is copied.
    """

    def __init__(self, target: str | Path, plan: OutputPlan | None = None):
        self.target = Path(target)
        self.plan = plan
        self.created: list[Path] = []  # directories made for the target (removed on failure)
        real = self.target.resolve()
        parent = real.parent
        for directory in reversed((real, *real.parents)):
            if directory != real and not directory.exists():
                directory.mkdir()
                self.created.append(directory)
        if real.is_dir() and not _same_device(real, parent):
            parent = real
        self.staging = Path(tempfile.mkdtemp(dir=parent, prefix=f"{STAGING_PREFIX}{real.name}-"))
        self.committed: list[Path] = []

    def path(self, name: str) -> Path:
        """Where to write the output ``name`` (a plain file name) while staging."""
        if Path(name).name != name or name in ("", ".", ".."):
            raise ValueError(f"output names are plain file names, not {name!r}")
        return self.staging / name

    def commit(self, last: tuple[str, ...] = (REPORT_NAME,)) -> list[Path]:
        """Move every staged file into the target; the names in ``last`` go last.

        Each move is atomic per file. A report written last marks that the files before it
        are complete. Then the files of the previous run's manifest that this run did not
        write are removed (``plan.removed`` names them).
        """
        try:
            self.target.mkdir(parents=True, exist_ok=True)
            staged = sorted(p for p in self.staging.iterdir() if p.is_file())
            staged.sort(key=lambda p: p.name in last)
            for item in staged:
                destination = self.target / item.name
                _move(item, destination)
                self.committed.append(destination)
            self.created.clear()
            written = {p.name for p in self.committed}
            if self.plan is not None:
                for name in self.plan.previous:
                    stale = self.target / name
                    if name not in written and stale.is_file():
                        stale.unlink()
                        self.plan.removed.append(name)
        finally:
            self.discard()
        return self.committed

    def discard(self) -> None:
        """Remove the staging directory and whatever is still in it, and the directories
        made for a target that was never committed."""
        shutil.rmtree(self.staging, ignore_errors=True)
        for directory in reversed(self.created):
            with contextlib.suppress(OSError):
                directory.rmdir()
        self.created.clear()


@contextlib.contextmanager
def staged_output_dir(target: str | Path, plan: OutputPlan | None = None) -> Iterator[StagedOutput]:
    """Stage a run's outputs; move them into ``target`` only if the block completes.

    ::

        with staged_output_dir("out/fig3a") as out:
            write_json(out.path("report.json"), report)
        # now out/fig3a/report.json exists; after an exception nothing would.

    ``plan`` (from ``check_output_dir``) lets the commit remove the stale files of the
    previous run.
    """
    staged = StagedOutput(target, plan)
    try:
        yield staged
    except BaseException:
        staged.discard()
        raise
    staged.commit()
