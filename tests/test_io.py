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


def visible(directory):
    return sorted(p.name for p in directory.iterdir() if not p.name.startswith("."))


def test_staged_output_dir_commits_on_success(tmp_path):
    target = tmp_path / "out"
    with io.staged_output_dir(target) as staged:
        io.write_text(staged.path("a.csv"), "1")
        io.write_text(staged.path("report.json"), "{}")
        assert visible(target) == []  # staged out of sight, inside the target (locked)
    assert sorted(p.name for p in target.iterdir()) == ["a.csv", "report.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert io.read_manifest(target) == ["a.csv", "report.json"]


def test_staged_output_dir_writes_nothing_on_failure(tmp_path):
    target = tmp_path / "out"
    with pytest.raises(ValueError), io.staged_output_dir(target) as staged:
        io.write_text(staged.path("a.csv"), "1")
        raise ValueError
    assert list(tmp_path.iterdir()) == []


def test_staged_output_keeps_other_files_in_the_target(tmp_path):
    """Files rubcli did not write: refused without force; with it, the one named like an
    output is replaced and the other kept."""
    target = tmp_path / "out"
    target.mkdir()
    (target / "notes.txt").write_text("mine")
    (target / "a.csv").write_text("old")
    with pytest.raises(io.OutputError, match="not written by rubcli"):
        io.staged_output_dir(target).__enter__()
    with io.staged_output_dir(target, force=True) as staged:
        io.write_text(staged.path("a.csv"), "new")
    assert (target / "a.csv").read_text() == "new"
    assert (target / "notes.txt").read_text() == "mine"


def test_staged_names_are_plain_file_names(tmp_path):
    with io.staged_output_dir(tmp_path / "out") as staged, pytest.raises(ValueError):
        staged.path("../escape.csv")


# ------------------------------------------------- compiled CSV text


def _awkward_floats(n: int, seed: int = 3) -> np.ndarray:
    """Doubles of every kind: random bit patterns (subnormals included), values spread over
    the exponents, powers of two and their neighbours (where the rounding interval is
    lopsided), every power of ten, the smallest subnormals, short decimals, integers, and
    the edge cases of repr's layout (1e16, 1e-05, 0.0001, -0.0, the largest and smallest
    doubles)."""
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 2**64, n, dtype=np.uint64).view(np.float64)
    spread = rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n)
    powers = 2.0 ** rng.integers(-1074, 1024, n).astype(float)
    decimals = np.round(rng.standard_normal(n) * 1e4) / 10.0 ** rng.integers(0, 8, n)
    integers = rng.integers(-(10**6), 10**6, n) * 10.0 ** rng.integers(0, 20, n)
    edges = np.array([0.0, -0.0, 1.0, -1.0, 0.1, 0.30000000000000004, 1e-5, 1e-4, 9.999e-5,
                      1e15, 1e16, 1e17, 1.5e16, 9999999999999998.0, 123456789012345678.0,
                      5e-324, -5e-324, 2.2250738585072014e-308, 2.225073858507201e-308,
                      1.7976931348623157e308, 2.0**-1022, 2.0**63, 1e22, 1e23, 12.5,
                      1000000.0, np.nan, np.inf, -np.inf])  # fmt: skip
    two = np.ldexp(1.0, np.arange(-1074, 1024))
    boundaries = np.concatenate(
        [
            two,
            np.nextafter(two, np.inf),
            np.nextafter(two, 0.0),
            [float(f"1e{k}") for k in range(-323, 309)],
            np.arange(1, 2000, dtype=np.uint64).view(np.float64),
        ]
    )
    return np.concatenate([edges, bits, spread, powers, decimals, integers, boundaries])


@pytest.mark.slow
def test_compiled_csv_fields_are_exactly_pythons_repr():
    """Every float field of the compiled formatter (Schubfach digits in repr's layout) is
    ``repr(value)``; integers are ``str``; texts the caller's."""
    from rubcli import csvtext

    values = _awkward_floats(40_000)
    n = values.size
    ints = np.random.default_rng(5).integers(-(2**63), 2**63 - 1, n, dtype=np.int64)
    ints[:3] = [0, -(2**63), 2**63 - 1]
    names = np.array(["free", 'say "x", y', "slip+"] * (n // 3) + ["stick"] * (n % 3),
                     dtype=object)  # fmt: skip
    data = bytes(csvtext.format_block([values, ints, names, -values], io.csv_field))
    rows = data.decode("utf-8").split("\n")
    assert rows[-1] == "" and len(rows) == n + 1
    expected = [
        f"{a!r},{i},{io.csv_field(s)},{-a!r}"
        for a, i, s in zip(values.tolist(), ints.tolist(), names.tolist(), strict=True)
    ]
    mismatches = [(g, w) for g, w in zip(rows[:-1], expected, strict=True) if g != w]
    assert mismatches == []
    read_back = [float(f.split(",")[0]) for f in rows[:-1]]
    np.testing.assert_array_equal(read_back, values)  # round trip, bit for bit
    # non-finite values take the caller's replacement
    data = csvtext.format_block([np.array([np.nan, 1.5, -np.inf])], io.csv_field, "")
    assert bytes(data) == b"\n1.5\n\n"


def test_compiled_and_python_csv_writers_give_the_same_bytes(tmp_path, monkeypatch):
    """``write_csv`` formats large numpy blocks compiled and small ones in Python: the
    files are byte for byte the same."""
    values = _awkward_floats(2_000, seed=7)
    n = values.size
    block = [values, np.arange(n), np.where(np.arange(n) % 2, "free", "slip+").astype(object),
             values[::-1].copy()]  # fmt: skip
    header = ["a", "i", "name", "c"]
    io.write_csv(tmp_path / "compiled.csv", header, [block, block], nonfinite="")
    monkeypatch.setattr(io.tables, "CSV_COMPILED_MIN_ROWS", 10**9)
    io.write_csv(tmp_path / "python.csv", header, [block, block], nonfinite="")
    compiled = (tmp_path / "compiled.csv").read_bytes()
    assert compiled == (tmp_path / "python.csv").read_bytes()
    assert compiled.count(b"\n") == 2 * n + 1


def test_compiled_csv_leaves_mixed_object_columns_to_the_general_path():
    """An object column of floats (NaN replaced by ``nonfinite``), None or unhashable
    values is not text: ``format_block`` declines it and ``write_csv`` formats it as
    before, with the same result as for a short table."""
    from rubcli import csvtext

    mixed = np.array([1.5, float("nan"), None, "a,b"] * 300, dtype=object)
    assert csvtext.format_block([mixed], io.csv_field, "") is None
    assert csvtext.format_block([np.array([[1], [2]] * 600 + [None], dtype=object)],
                                io.csv_field) is None  # fmt: skip
    assert csvtext.format_block([np.array(["x", "y"] * 600)], io.csv_field) is not None


def test_write_csv_of_mixed_object_columns_matches_rows(tmp_path):
    mixed = np.array([1.5, float("nan"), None, "a,b"] * 300, dtype=object)
    io.write_csv(tmp_path / "m.csv", ["v", "i"], [[mixed, np.arange(mixed.size)]], nonfinite="")
    lines = (tmp_path / "m.csv").read_text().splitlines()
    assert lines[:5] == ["v,i", "1.5,0", ",1", ",2", '"a,b",3'] and len(lines) == 1201


def test_background_jobs_run_in_order_and_a_failure_reaches_the_caller():
    done = []
    with pytest.raises(ValueError, match="second"), io.Background() as background:
        background.submit(done.append, 1)
        background.submit(lambda: (_ for _ in ()).throw(ValueError("second")))
        background.submit(done.append, 3)
    assert done == [1, 3]  # every job ran; the first failure is raised on leaving


def test_background_stops_its_job_when_the_block_fails():
    """On an exception in the block (a signal's Terminated, a failed figure), the
    running job stops at its next progress report and the queued ones never start:
    nothing writes into a staged dir after it is discarded."""
    import threading
    import time

    started, reports, ran = threading.Event(), [], []

    def long_job(on_rows):
        started.set()
        for i in range(10_000):  # 100 s unless stopped
            on_rows(i)
            reports.append(i)
            time.sleep(0.01)

    background = io.Background()
    with pytest.raises(KeyboardInterrupt), background:
        future = background.submit(long_job, progress=("job", 10_000.0))
        background.submit(ran.append, "queued")
        started.wait(5.0)
        raise KeyboardInterrupt
    assert isinstance(future.exception(timeout=0), io.Cancelled)
    assert len(reports) < 500 and ran == []


def test_background_wait_shows_the_progress_of_a_running_job():
    import contextlib
    import threading

    release, seen = threading.Event(), []

    def job(on_rows):
        on_rows(10.0)
        release.wait(5.0)

    @contextlib.contextmanager
    def bar(label, total):
        seen.append((label, total))
        release.set()  # let the job finish once the bar is up
        yield seen.append

    with io.Background() as background:
        background.submit(job, progress=("a.csv", 20.0))
        background.wait(bar)
    assert seen[0] == ("a.csv", 20.0) and seen[-1] == 20.0


def _labelled_blocks(n_blocks: int, rows: int, seed: int = 11):
    """Blocks of a float, an integer and a coded text column (``io.Labels``)."""
    rng = np.random.default_rng(seed)
    names = {-1: "slip-", 0: "free", 1: "slip+", 2: 'say "x", y'}
    return [[rng.standard_normal(rows), np.arange(rows) + b * rows,
             io.Labels(rng.integers(-1, 3, rows), names)] for b in range(n_blocks)]  # fmt: skip


def test_coded_text_columns_give_the_texts_of_their_codes(tmp_path, monkeypatch):
    """A ``Labels`` column (the regime names of a solution CSV) is written as the text of
    each code, quoted as any text, the same by the compiled and the Python formatter; a
    code without a name is refused."""
    from rubcli import csvtext

    blocks = _labelled_blocks(2, 1500)
    io.write_csv(tmp_path / "compiled.csv", ["v", "i", "name"], blocks)
    monkeypatch.setattr(io.tables, "CSV_COMPILED_MIN_ROWS", 10**9)
    io.write_csv(tmp_path / "python.csv", ["v", "i", "name"], blocks)
    compiled = (tmp_path / "compiled.csv").read_bytes()
    assert compiled == (tmp_path / "python.csv").read_bytes()
    lines = compiled.decode().splitlines()[1:]
    expected = [io.csv_field(blocks[b][2].names[int(c)]) for b in range(2)
                for c in blocks[b][2].codes]  # fmt: skip
    assert [line.split(",", 2)[2] for line in lines] == expected
    with pytest.raises(ValueError, match="without a name"):
        csvtext.format_block([io.Labels(np.array([0, 5] * 600), {0: "a"})], io.csv_field)


def test_shared_blocks_formatted_by_two_threads_are_written_in_order(tmp_path):
    """``SharedBlocks``: a helper thread formats blocks ahead while ``write_csv`` writes
    them; the file is the one a single thread writes, whoever formatted which block."""
    import threading

    blocks = _labelled_blocks(24, 2000, seed=3)
    header = ["v", "i", "name"]
    io.write_csv(tmp_path / "alone.csv", header, blocks)
    shared = io.SharedBlocks(blocks, width=3)
    helped = []
    start = threading.Event()

    def helper():
        start.wait(5.0)
        while shared.work():
            helped.append(1)

    thread = threading.Thread(target=helper)
    thread.start()
    start.set()
    io.write_csv(tmp_path / "shared.csv", header, shared)
    thread.join(5.0)
    assert (tmp_path / "shared.csv").read_bytes() == (tmp_path / "alone.csv").read_bytes()
    # the helper may lose every race on a busy machine; formatting ahead first it cannot
    ahead = io.SharedBlocks(blocks, width=3)
    assert all(ahead.work() for _ in range(ahead.AHEAD)) and not ahead.work()  # AHEAD wait
    io.write_csv(tmp_path / "ahead.csv", header, ahead)
    assert (tmp_path / "ahead.csv").read_bytes() == (tmp_path / "alone.csv").read_bytes()


def test_shared_blocks_a_failed_block_fails_the_writer(tmp_path):
    """A block that fails to format in the helper fails ``write_csv`` with its error (no
    writer waits for it forever), and the staged file is not left behind."""
    blocks = _labelled_blocks(3, 1200)
    blocks[1] = blocks[1][:2]  # a block with a column missing
    shared = io.SharedBlocks(blocks, width=3)
    assert shared.work()  # block 0
    assert not shared.work()  # block 1 fails: kept for the writer
    assert not shared.work()  # and nothing more is taken
    with pytest.raises(ValueError, match="2 columns"):
        io.write_csv(tmp_path / "t.csv", ["v", "i", "name"], shared)
    assert list(tmp_path.iterdir()) == []

    def failing():  # the blocks' source itself fails (e.g. a column cannot be computed)
        yield _labelled_blocks(1, 1200)[0]
        raise RuntimeError("no second block")

    shared = io.SharedBlocks(failing(), width=3)
    assert shared.work() and not shared.work()
    with pytest.raises(RuntimeError, match="no second block"):
        io.write_csv(tmp_path / "t.csv", ["v", "i", "name"], shared)
    assert list(tmp_path.iterdir()) == []


def test_background_wait_helps_a_job_that_offers_work(tmp_path):
    """``Background.wait`` does the pieces a job offers (``helper``) instead of idling:
    the CSV's blocks are formatted by the waiting thread too, and the file is complete."""
    import threading

    blocks = _labelled_blocks(12, 2000, seed=5)
    header = ["v", "i", "name"]
    io.write_csv(tmp_path / "alone.csv", header, blocks)
    shared = io.SharedBlocks(blocks, width=3)
    waiting = threading.get_ident()
    helpers = []

    def work():
        helpers.append(threading.get_ident())
        return shared.work()

    gate = threading.Event()

    def write(path, on_rows):
        gate.wait(5.0)  # the waiting thread starts first: it must get blocks to format
        return io.write_csv(path, header, shared, on_rows=on_rows)

    with io.Background() as background:
        background.submit(write, tmp_path / "shared.csv", progress=("x", 24000.0), helper=work)
        threading.Timer(0.3, gate.set).start()
        background.wait()
    assert waiting in helpers
    assert (tmp_path / "shared.csv").read_bytes() == (tmp_path / "alone.csv").read_bytes()


def test_a_csv_writer_records_the_digest_of_what_it_wrote(tmp_path):
    """The manifest takes a CSV's SHA-256 from its writer (no second read): it must be the
    file's, and be forgotten once the file changes."""
    import hashlib
    import time

    from rubcli.io import files, manifest

    path = tmp_path / "t.csv"
    io.write_csv(path, ["a", "b"], [[np.arange(1000.0), np.arange(1000.0) / 3]])
    data = path.read_bytes()
    assert files.known_digest(path) == (len(data), hashlib.sha256(data).hexdigest())
    assert manifest.file_digest(path) == manifest.file_digest(path, fresh=True)
    time.sleep(0.01)
    with open(path, "ab") as handle:
        handle.write(b"1,2\n")
    assert files.known_digest(path) is None
    assert manifest.file_digest(path)[0] == len(data) + 4
