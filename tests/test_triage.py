"""rockscan triage: walk, classify, rank, report; nothing lost, same answer on any number of workers."""

from __future__ import annotations

import base64
import concurrent.futures as cf
import fcntl
import io
import json
import math
import os
import pty
import shutil
import signal
import struct
import subprocess
import sys
import termios
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image

from rockscan.cli import main
from rockscan.core.errors import ParameterError, WriteError
from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import default_spec_path, load_library, read_spec
from rockscan.io.folders import find_photos
from rockscan.io.library import read_pending
from rockscan.io.report import (
    CSV_COLUMNS,
    ROW_KEYS,
    ReportJournal,
    latest_rows,
    photo_key,
    rank_key,
    read_provenance,
    read_rows,
)
from rockscan.run.backends import _ProcessBackend, _run_backend, held_interrupts
from rockscan.run.photo import PhotoOutcome
from rockscan.run.report import finalize_report
from rockscan.run.triage import TriageConfig, interest_score, triage_folder, triage_row

N_PHOTOS = 50
CLASSIFY_KEYS = (
    "match",
    "nearest",
    "mscore",
    "distance",
    "angle_deg",
    "interesting",
    "residual",
    "symmetry",
    "centroid",
    "index",
    "area_px",
)


def _render_folder(root: Path, n: int, *, seed: int = 0, shapes=None) -> list[Path]:
    """n rendered photos (160 x 200) spread over root, root/nested and root/nested/deeper."""
    specs = shapes or [(s.name, s.params) for s in read_spec(default_spec_path())]
    rng = np.random.default_rng(seed)
    config = RenderConfig(rows=160, cols=200)
    paths = []
    for i in range(n):
        name, params = specs[i % len(specs)]
        suffix = (".png", ".jpg")[i % 2]
        path = root / ("", "nested", "nested/deeper")[i % 3] / f"{i:03d}-{name}{suffix}"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(render_photo(params, config, rng=rng, name=name).encode(suffix))
        paths.append(path)
    return paths


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """50 rendered photos, 5 corrupt photos, a text file, a nested folder and a link loop."""
    root = tmp_path_factory.mktemp("mission") / "photos"
    photos = _render_folder(root, N_PHOTOS)
    good = photos[0].read_bytes()
    corrupt = {
        root / "bad" / "truncated.png": good[:200],
        root / "bad" / "empty.jpg": b"",
        root / "bad" / "noise.bmp": np.random.default_rng(1).bytes(3000),
        root / "bad" / "words.tif": b"this is not a TIFF\n",
        root / "nested" / "cut.jpg": photos[1].read_bytes()[:900],
    }
    for path, data in corrupt.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    (root / "notes.txt").write_text("field notes, not a photo\n")
    os.symlink("..", root / "nested" / "deeper" / "loop")
    return root, photos, sorted(corrupt)


@pytest.fixture(scope="module")
def reference(folder, tmp_path_factory):
    """The folder triaged by the command line on one worker."""
    root, _, _ = folder
    report = tmp_path_factory.mktemp("reference") / "report.csv"
    result = CliRunner().invoke(main, ["triage", str(root), "-o", str(report), "-j", "1"])
    return result, report


def _rows(path) -> list[dict]:
    """A report's rows; the outline, which only JSON reports carry, left out."""
    return [{k: v for k, v in row.items() if k != "outline"} for row in read_rows(path)]


# ---------------------------------------------------------------- finding photos


def test_find_photos_walks_in_order_skips_other_files_and_survives_loops(tmp_path):
    names = (
        "b.PNG",
        "a.jpg",
        ".hidden.bmp",
        "c.txt",
        "sub/x.tif",
        "z/y.jpeg",
        "sub/deep/w.TIFF",
        "w.jfif",
        "v.JPE",
    )
    for name in names:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(b"x")
    os.symlink("..", tmp_path / "sub" / "loop")
    os.symlink("self", tmp_path / "self")
    os.symlink("nowhere.png", tmp_path / "gone.png")
    listing = find_photos(tmp_path)
    names = [os.path.relpath(p, tmp_path) for p in listing.photos]
    # .jfif and .jpe: the names browsers and old tools give a JPEG.
    assert names == [
        ".hidden.bmp",
        "a.jpg",
        "b.PNG",
        "gone.png",
        "v.JPE",
        "w.jfif",
        "sub/x.tif",
        "sub/deep/w.TIFF",
        "z/y.jpeg",
    ]
    assert listing.problems == ()
    # Paths are joined to the folder as given.
    assert all(p.startswith(str(tmp_path) + os.sep) for p in listing.photos)


def test_a_folder_that_cannot_be_listed_becomes_an_error_row(tmp_path, default_lib, monkeypatch):
    _render_folder(tmp_path / "photos", 3)
    locked = str(tmp_path / "photos" / "nested")
    real = os.scandir

    def scandir(path):
        if os.fspath(path) == locked:
            raise PermissionError(13, "Permission denied")
        return real(path)

    monkeypatch.setattr(os, "scandir", scandir)
    assert find_photos(tmp_path / "photos").problems == ((locked, "cannot list folder (Permission denied)"),)
    summary = triage_folder(tmp_path / "photos", tmp_path / "r.csv", default_lib, TriageConfig(workers=1))
    assert (summary.n_rows, summary.n_errors) == (2, 1)
    assert _rows(tmp_path / "r.csv")[-1]["path"] == locked
    # Listed again: its photos get rows, and its own error row goes (it stayed for
    # good, with exit 1 and a warning that it was "no longer under" the folder).
    monkeypatch.setattr(os, "scandir", real)
    again = triage_folder(
        tmp_path / "photos", tmp_path / "r.csv", default_lib, TriageConfig(workers=1, resume=True)
    )
    assert (again.n_rows, again.n_errors, again.n_gone, again.failed) == (3, 0, 0, False)
    rows = _rows(tmp_path / "r.csv")
    assert sorted(r["path"] for r in rows) == sorted(find_photos(tmp_path / "photos").photos)
    assert all(r["error"] is None for r in rows)


@pytest.mark.parametrize(
    "settings",
    [{"workers": float("nan")}, {"html_limit": float("inf")}, {"thumbnail_size": 2.5}, {"window": 0}],
)
def test_triage_counts_must_be_whole_numbers(settings):
    # int() of nan and inf raised ValueError and OverflowError, and of 2.5 gave 2.
    with pytest.raises(ParameterError, match="must be a whole number"):
        TriageConfig(**settings)


@pytest.mark.parametrize(("make", "message"), [("missing", "folder not found"), ("file", "is a file")])
def test_find_photos_names_the_problem(tmp_path, make, message):
    target = tmp_path / "x"
    if make == "file":
        target.write_text("x")
    with pytest.raises(ParameterError, match=message):
        find_photos(target)


# ---------------------------------------------------------------- rows and ranking


def test_interest_is_mscore_times_the_matched_shapes_interest(default_lib):
    assert interest_score("five-armed-star", 0.75, 2.0) == 1.5
    assert interest_score(None, 0.75, 2.0) == 0.0
    record = {"path": "p.png", "match": "five-armed-star", "nearest": "five-armed-star", "mscore": 0.5}
    row = triage_row(record, default_lib)
    assert (row["shape_interest"], row["interest"]) == (2.0, 1.0)
    assert tuple(row) == ROW_KEYS and row["rank"] is None and row["novelty"] is None
    row = triage_row({**record, "match": None, "nearest": "circle"}, default_lib)
    assert (row["shape_interest"], row["interest"]) == (0.5, 0.0)
    error = triage_row({"path": "p.png", "error": "p.png: file is empty"}, default_lib)
    assert error["error"] == "p.png: file is empty" and error["interest"] is None


def test_rank_key_orders_interest_then_mscore_then_path_and_errors_last():
    rows = [
        {"path": "e2", "error": "x"},
        {"path": "b", "interest": 1.0, "mscore": 0.5},
        {"path": "a", "interest": 1.0, "mscore": 0.5},
        {"path": "c", "interest": 1.0, "mscore": 0.9},
        {"path": "e1", "error": "x"},
        {"path": "d", "interest": 2.0, "mscore": 0.1},
    ]
    assert [r["path"] for r in sorted(rows, key=rank_key)] == ["d", "c", "a", "b", "e1", "e2"]


_text = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00\r"), min_size=1)
_float = st.floats(allow_nan=False, allow_infinity=False)
_rows_strategy = st.lists(
    st.fixed_dictionaries(
        {
            "path": _text,
            "interest": _float,
            "match": st.none() | st.from_regex(r"[a-z0-9-]{1,12}", fullmatch=True),
            "nearest": st.from_regex(r"[a-z0-9-]{1,12}", fullmatch=True),
            "mscore": _float,
            "angle_deg": _float,
            "interesting": st.booleans(),
            "novel": st.none() | st.booleans(),
            "symmetry": st.integers(0, 36),
            "centroid": st.tuples(_float, _float).map(list),
            "error": st.none() | _text,
        }
    ),
    min_size=1,
    max_size=5,
    unique_by=lambda r: r["path"].strip(),
)


@pytest.mark.parametrize("suffix", [".csv", ".jsonl"])
@given(rows=_rows_strategy)
def test_rows_round_trip_exactly(tmp_path_factory, suffix, rows):
    path = tmp_path_factory.mktemp("rt") / f"r{suffix}"
    rows = [{**dict.fromkeys(ROW_KEYS), **r} for r in rows]
    with ReportJournal(path) as journal:
        for row in rows:
            journal.append(row)
    assert _rows(path) == rows


def test_finalize_ranks_once_per_photo_and_is_atomic(tmp_path):
    path = tmp_path / "r.csv"
    with ReportJournal(path) as journal:
        for name, interest in [("a", 0.2), ("b", 0.9), ("a", 0.95)]:
            journal.append(
                {**dict.fromkeys(ROW_KEYS), "path": name, "interest": interest, "mscore": interest}
            )
        journal.append({**dict.fromkeys(ROW_KEYS), "path": "c", "error": "c: file is empty"})
    ranked = finalize_report(path)
    rows = _rows(path)
    # A photo's latest attempt wins (a resume tried it again); errors come last without a rank.
    assert [(r["rank"], r["path"], r["interest"]) for r in rows] == [
        (1, "a", 0.95),
        (2, "b", 0.9),
        (None, "c", None),
    ]
    assert (ranked.n_rows, ranked.n_errors) == (3, 1)
    assert [p.name for p in tmp_path.iterdir()] == ["r.csv"]


def test_a_row_cut_short_by_a_crash_is_dropped_on_resume(tmp_path):
    path = tmp_path / "r.csv"
    with ReportJournal(path) as journal:
        journal.append(
            {**dict.fromkeys(ROW_KEYS), "path": 'a "quoted",\nname', "interest": 1.0, "mscore": 1.0}
        )
    with open(path, "ab") as fh:
        fh.write(b',b.png,0.5,"half a quoted\nfield')
    journal = ReportJournal(path, resume=True)
    journal.close()
    assert len(journal.done) == 1
    assert [r["path"] for r in _rows(path)] == ['a "quoted",\nname']


@given(
    attempts=st.lists(st.lists(st.integers(0, 4), min_size=1, max_size=4), min_size=1, max_size=6),
    order=st.randoms(use_true_random=False),
)
def test_the_ranking_keeps_each_photos_latest_attempt_and_each_rock_once(attempts, order):
    # Per photo, its attempts: 0 an error row, else that many rocks. The first
    # attempt lies in an earlier run's ranked rows, in any order; each later one
    # (a resume tried the photo again: it had failed, or changed) was appended
    # whole, its rocks by index, after the attempts before it.
    ranked, appended = [], []
    for photo, tries in enumerate(attempts):
        blocks = [[(photo, t, i) for i in range(max(n, 1))] for t, n in enumerate(tries)]
        ranked += blocks[0]
        appended.append(blocks[1:])
    order.shuffle(ranked)
    rows = list(ranked)
    while any(appended):
        photo = order.choice([k for k, left in enumerate(appended) if left])
        rows += appended[photo].pop(0)
    latest = {photo: len(tries) - 1 for photo, tries in enumerate(attempts)}
    expected = [i for i, (photo, t, _) in enumerate(rows) if t == latest[photo]]
    keep = latest_rows(
        np.array([r[0] for r in rows], np.int64),
        np.array([r[2] == 0 for r in rows], bool),
        np.array([r[0] * 100 + r[2] for r in rows], np.int64),
    )
    assert np.flatnonzero(keep).tolist() == expected


def test_the_journal_knows_which_photos_failed_last(tmp_path):
    path = tmp_path / "r.jsonl"
    row = {**dict.fromkeys(ROW_KEYS), "interest": 1.0, "mscore": 1.0}
    with ReportJournal(path) as journal:
        journal.append({**row, "path": "a.png", "error": "unreadable"})
        journal.append({**row, "path": "b.png", "error": "unreadable"})
        journal.append([{**row, "path": "b.png", "index": 0}, {**row, "path": "b.png", "index": 1}])
    journal = ReportJournal(path, resume=True)
    journal.close()
    assert journal.failed == {photo_key("a.png")}
    assert journal.done == {photo_key("a.png"), photo_key("b.png")}


@pytest.mark.parametrize("suffix", [".csv", ".html"])
def test_a_resume_tries_the_photos_that_failed_again(tmp_path, default_lib, suffix):
    # Error rows counted as done: a photo half copied when the run met it stayed
    # an error through every resume, unless its row was cut out of the report by hand.
    root = tmp_path / "photos"
    good = _render_folder(root, 3, shapes=[(s.name, s.params) for s in read_spec(default_spec_path())][:3])
    late = root / "late.png"
    late.write_bytes(good[0].read_bytes()[:300])
    report = tmp_path / f"r{suffix}"
    config = TriageConfig(workers=1)
    first = triage_folder(root, report, default_lib, config)
    assert first.n_errors == 1 and first.n_retried == 0
    shutil.copyfile(good[1], late)  # the copy finished
    config = TriageConfig(workers=1, resume=True)
    second = triage_folder(root, report, default_lib, config)
    assert (second.n_resumed, second.n_processed, second.n_retried) == (3, 1, 1)
    assert (second.n_rows, second.n_errors, second.n_changed) == (4, 0, 0)
    rows = _rows(report)
    assert sorted(Path(r["path"]).name for r in rows) == sorted([*(p.name for p in good), "late.png"])
    assert all(r["error"] is None for r in rows) and [r["rank"] for r in rows] == [1, 2, 3, 4]
    # Done now: a later resume leaves it be.
    third = triage_folder(root, report, default_lib, config)
    assert (third.n_resumed, third.n_processed, third.n_retried) == (4, 0, 0)
    assert _rows(report) == rows


def test_a_photo_that_fails_again_keeps_one_error_row(tmp_path, default_lib):
    root = tmp_path / "photos"
    _render_folder(root, 2)
    (root / "broken.png").write_bytes(b"not a photo")
    report = tmp_path / "r.jsonl"
    triage_folder(root, report, default_lib, TriageConfig(workers=1))
    again = triage_folder(root, report, default_lib, TriageConfig(workers=1, resume=True))
    assert (again.n_processed, again.n_retried, again.n_rows, again.n_errors) == (1, 1, 3, 1)
    rows = _rows(report)
    assert [Path(r["path"]).name for r in rows if r["error"] is not None] == ["broken.png"]
    assert len(rows) == 3
    result = CliRunner().invoke(main, ["triage", str(root), "-o", str(report), "-j", "1", "--resume"])
    # One error, not "1 errors".
    assert "2 ranked, 1 error;" in result.stdout


@pytest.mark.parametrize("suffix", [".csv", ".jsonl"])
def test_a_photo_whose_rows_the_disk_cut_short_leaves_none_and_is_done_again(tmp_path, suffix):
    # A full disk took part of a photo's write: its first rocks whole, the next cut
    # short. The resume dropped the cut row and counted the photo done, 3 of its 8
    # rocks kept for good.
    path = tmp_path / f"r{suffix}"
    row = {**dict.fromkeys(ROW_KEYS), "interest": 1.0, "mscore": 1.0}
    with ReportJournal(path) as journal:
        journal.append({**row, "path": "a.png"})
        size = path.stat().st_size

        class Full:
            def __init__(self, fh):
                self.fh = fh

            def write(self, data):
                self.fh.write(data[: len(data) // 2])
                raise OSError(28, "No space left on device")

            def __getattr__(self, name):
                return getattr(self.fh, name)

        journal._fh = Full(journal._fh)
        with pytest.raises(WriteError, match="No space left on device"):
            journal.append([{**row, "path": "b.png", "index": i} for i in range(8)])
        journal._fh = journal._fh.fh
    assert path.stat().st_size == size
    resumed = ReportJournal(path, resume=True)
    resumed.close()
    assert resumed.done == {photo_key("a.png")}


def test_a_foreign_file_is_not_taken_for_a_report(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("name,value\nx,1\n")
    with pytest.raises(ParameterError, match="not a rockscan triage report"):
        ReportJournal(path, resume=True)
    assert CSV_COLUMNS[0] == "rank" and "centroid_x" in CSV_COLUMNS


# ---------------------------------------------------------------- the acceptance folder


def test_folder_of_50_photos_5_corrupt_files_gives_50_ranked_rows_and_5_errors(folder, reference):
    _, photos, corrupt = folder
    result, report = reference
    assert result.exit_code == 1, result.output
    rows = _rows(report)
    ranked = [r for r in rows if r["error"] is None]
    errors = [r for r in rows if r["error"] is not None]
    assert len(ranked) == 50 and len(errors) == 5
    assert [r["rank"] for r in ranked] == list(range(1, 51))
    assert all(r["rank"] is None for r in errors)
    assert rows == ranked + errors
    interest = [r["interest"] for r in ranked]
    assert interest == sorted(interest, reverse=True)
    assert sorted(r["path"] for r in ranked) == sorted(map(str, photos))
    assert sorted(r["path"] for r in errors) == sorted(map(str, corrupt))
    assert not any("internal error" in r["error"] for r in errors)
    # The summary: counts, the top 10, the errors.
    out = result.stdout
    assert "55 photos found, 0 already in the report, 55 classified" in out
    assert "s; 1 other file skipped (.txt)\n" in out
    assert "50 ranked, 5 errors" in out
    top = out.split("top 10:\n")[1].split("errors (5):\n")
    assert len(top[0].strip().splitlines()) == 11
    assert top[0].splitlines()[1].split()[0] == "1" and str(ranked[0]["path"]) in top[0].splitlines()[1]
    assert sorted(line.strip() for line in top[1].strip().splitlines()) == sorted(r["error"] for r in errors)
    # Off a terminal: progress lines and each error row on stderr, nothing else.
    lines = result.stderr.splitlines()
    assert sorted(x.removeprefix("rockscan: error: ") for x in lines if "error: " in x) == sorted(
        r["error"] for r in errors
    )
    progress = [x for x in lines if x.startswith("rockscan: triage: ")]
    assert len(progress) + len(errors) == len(lines) and progress[-1].startswith("rockscan: triage: 55/55")


def test_every_row_is_what_classify_prints_for_the_photo(folder, reference):
    _, report = reference
    rows = {r["path"]: r for r in _rows(report)}
    result = CliRunner().invoke(main, ["classify", "--json", *rows])
    assert result.exit_code == 1
    printed = [json.loads(line) for line in result.stdout.splitlines()]
    assert [p["path"] for p in printed] == list(rows)
    for record in printed:
        row = rows[record["path"]]
        if "error" in record:
            assert row["error"] == record["error"]
        else:
            assert {k: row[k] for k in CLASSIFY_KEYS} == {k: record[k] for k in CLASSIFY_KEYS}


def test_two_worker_processes_give_the_same_report(folder, reference, tmp_path):
    root, _, _ = folder
    report = tmp_path / "report.jsonl"
    result = CliRunner().invoke(main, ["triage", str(root), "-o", str(report), "-j", "2"])
    assert result.exit_code == 1, result.output
    assert _rows(report) == _rows(reference[1])


def test_a_dask_cluster_gives_the_same_report(folder, reference, tmp_path):
    from distributed import LocalCluster

    root, _, _ = folder
    report = tmp_path / "report.csv"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        result = CliRunner().invoke(
            main, ["triage", str(root), "-o", str(report), "--scheduler", cluster.scheduler_address]
        )
    assert result.exit_code == 1, result.output
    assert report.read_bytes() == reference[1].read_bytes()


def test_an_unreachable_scheduler_names_the_address(folder, tmp_path, default_lib):
    root, _, _ = folder
    config = TriageConfig(scheduler="tcp://127.0.0.1:9", connect_timeout_s=0.5)
    with pytest.raises(ParameterError, match=r"cannot reach the Dask scheduler at tcp://127\.0\.0\.1:9"):
        triage_folder(root, tmp_path / "r.csv", default_lib, config)


# ---------------------------------------------------------------- nothing lost


def test_a_finished_report_resumed_says_so_without_a_progress_line(tmp_path):
    root = tmp_path / "photos"
    _render_folder(root, 3)
    report = tmp_path / "report.csv"
    args = ["triage", str(root), "-o", str(report), "-j", "1"]
    assert CliRunner().invoke(main, args).exit_code == 0
    result = CliRunner().invoke(main, [*args, "--resume"])
    assert "3 photos found, 3 already in the report, 0 classified" in result.stdout
    # No "0/0 photos" line.
    assert result.stderr == ""


def test_a_resumed_report_tries_its_errors_again_and_ranks_each_photo_once(folder, reference, tmp_path):
    root, _, _ = folder
    report = tmp_path / "report.csv"
    shutil.copyfile(reference[1], report)
    result = CliRunner().invoke(main, ["triage", str(root), "-o", str(report), "-j", "1", "--resume"])
    assert result.exit_code == 1
    assert (
        "55 photos found, 50 already in the report, 5 classified (5 of them failed before)" in result.stdout
    )
    # The corrupt files fail as before: one error row each, the report as it was.
    assert report.read_bytes() == reference[1].read_bytes()


def test_a_killed_run_resumed_ends_with_every_photo_once(folder, reference, tmp_path):
    root, _, _ = folder
    report = tmp_path / "report.csv"
    code = "import sys; from rockscan.cli import main; sys.argv[0] = 'rockscan'; main()"
    args = ["triage", str(root), "-o", str(report), "-j", "1"]
    proc = subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    rows_before_kill = 0
    while time.monotonic() < deadline and proc.poll() is None:
        if report.exists():
            # Less the provenance and column lines.
            rows_before_kill = report.read_bytes().count(b"\n") - 2
            if rows_before_kill >= 10:
                break
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the run finished before it could be killed"
    killed = _rows(report)
    assert 10 <= len(killed) < 55 and all(r["rank"] is None for r in killed)
    result = CliRunner().invoke(main, ["triage", str(root), "-o", str(report), "-j", "1", "--resume"])
    assert result.exit_code == 1, result.output
    # The corrupt files among the rows before the kill are tried again.
    failed = sum(r["error"] is not None for r in killed)
    done = len(killed) - failed
    retried = f" ({failed} of them failed before)" if failed else ""
    assert f"{done} already in the report, {55 - done} classified{retried}" in result.stdout
    assert report.read_bytes() == reference[1].read_bytes()


def test_ctrl_c_on_two_workers_ranks_what_is_done_and_says_how_to_finish(folder, reference, tmp_path):
    root, _, _ = folder
    report = tmp_path / "report.jsonl"
    code = "import sys; from rockscan.cli import main; sys.argv[0] = 'rockscan'; main()"
    args = ["triage", str(root), "-o", str(report), "-j", "2"]
    # A session of its own: Ctrl-C on a terminal reaches the whole process group.
    # Ctrl-C acts as at a terminal: a suite started in the background by a
    # shell without job control has SIGINT ignored, and the run would inherit it.
    proc = subprocess.Popen(
        [sys.executable, "-c", code, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if report.exists() and report.read_bytes().count(b"\n") >= 9:  # provenance and 8 rows
            break
        time.sleep(0.005)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert err.decode().strip().splitlines()[-1].startswith("rockscan: interrupted after ")
    assert "run again with --resume to finish" in err.decode()
    rows = _rows(report)
    assert 8 <= len(rows) < 55
    ranked = [r["rank"] for r in rows if r["error"] is None]
    assert ranked == list(range(1, len(ranked) + 1))
    result = CliRunner().invoke(main, [*args, "--resume"])
    assert result.exit_code == 1
    assert _rows(report) == _rows(reference[1])


def test_an_interrupted_run_keeps_complete_ranked_rows_and_resumes(folder, reference, tmp_path, default_lib):
    root, _, _ = folder
    report = tmp_path / "report.csv"
    seen = []

    def interrupt_after_12(done, total):
        seen.append((done, total))
        if done == 12:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        triage_folder(root, report, default_lib, TriageConfig(workers=1), progress=interrupt_after_12)
    assert seen == [(i, 55) for i in range(13)]
    rows = _rows(report)
    assert len(rows) == 12
    ranked = [r["rank"] for r in rows if r["error"] is None]
    assert ranked == list(range(1, len(ranked) + 1))
    # A crash in the middle of the next row leaves half a line behind.
    with open(report, "ab") as fh:
        fh.write(b",photos/half-written.png,0.9")
    summary = triage_folder(root, report, default_lib, TriageConfig(workers=1, resume=True))
    assert (summary.n_resumed, summary.n_processed, summary.n_rows, summary.n_errors) == (12, 43, 55, 5)
    assert summary.failed
    assert report.read_bytes() == reference[1].read_bytes()


def test_a_bug_on_one_photo_becomes_an_error_row(tmp_path, default_lib, monkeypatch):
    photos = _render_folder(tmp_path / "photos", 3)
    import rockscan.run.photo as triage_module

    real = triage_module.classify_path

    def flaky(path, *args, **kwargs):
        if path == str(photos[1]):
            raise TypeError("an unexpected bug")
        return real(path, *args, **kwargs)

    monkeypatch.setattr(triage_module, "classify_path", flaky)
    summary = triage_folder(tmp_path / "photos", tmp_path / "r.jsonl", default_lib, TriageConfig(workers=1))
    rows = {r["path"]: r for r in _rows(tmp_path / "r.jsonl")}
    assert rows[str(photos[1])]["error"] == "internal error, please report it: TypeError: an unexpected bug"
    assert rows[str(photos[0])]["rank"] is not None and rows[str(photos[2])]["rank"] is not None
    assert (summary.n_rows, summary.n_errors) == (3, 1)


def _die_on_bad(path: str) -> PhotoOutcome:
    if "bad" in path:
        os._exit(3)
    time.sleep(0.01)
    return PhotoOutcome({"path": path, "error": None})


def test_a_worker_process_that_dies_costs_only_its_photo():
    paths = [f"p{i}" for i in range(6)] + ["bad"] + [f"q{i}" for i in range(6)]
    with warnings.catch_warnings():
        # The pool forks this test process so that the test's worker function exists there.
        warnings.simplefilter("ignore", DeprecationWarning)
        backend = _ProcessBackend(2, _die_on_bad, None, (), context="fork")
        try:
            outcomes = dict(_run_backend(paths, backend, window=4, ordered=False))
        finally:
            backend.close()
    assert sorted(outcomes) == list(range(len(paths)))
    errors = {i: o.record["error"] for i, o in outcomes.items() if o.record["error"]}
    assert list(errors) == [6] and errors[6].startswith("the worker process died on this photo")


class _ThreadBackend:
    """Finishes photo i after (n - i) steps: the last submitted first."""

    def __init__(self, n: int) -> None:
        self.slots, self.n = 4, n
        self._pool = cf.ThreadPoolExecutor(4)

    def submit(self, path: str):
        i = int(path)
        return self._pool.submit(lambda: (time.sleep(0.005 * (self.n - i)), PhotoOutcome({"path": path}))[1])

    def restart(self) -> None:
        raise AssertionError("a thread pool does not break")

    def close(self) -> None:
        self._pool.shutdown()


def test_a_held_ctrl_c_is_raised_by_the_run_and_a_second_at_once():
    # Ctrl-C as at a terminal: a suite started in the background by a shell
    # without job control inherits SIGINT ignored, and nothing is held then.
    outside = signal.signal(signal.SIGINT, signal.default_int_handler)
    backend = _ThreadBackend(40)
    seen = []
    try:
        with held_interrupts() as stop, pytest.raises(KeyboardInterrupt):
            for i, _ in _run_backend(
                [str(i) for i in range(40)], backend, window=4, ordered=False, stop=stop
            ):
                seen.append(i)
                if len(seen) == 3:
                    signal.raise_signal(signal.SIGINT)
                    assert stop.is_set()  # held: this photo's row is still taken
                    seen.append("held")
        assert seen[3] == "held" and 4 <= len(seen) < 41
        with held_interrupts(), pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)
            signal.raise_signal(signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        backend.close()
        signal.signal(signal.SIGINT, outside)


def test_an_ignored_ctrl_c_stays_ignored_while_workers_run():
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with held_interrupts() as stop:
            signal.raise_signal(signal.SIGINT)
        assert not stop.is_set() and signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize("ordered", [True, False])
def test_outcomes_come_in_order_only_when_asked(ordered):
    backend = _ThreadBackend(8)
    try:
        order = [i for i, _ in _run_backend([str(i) for i in range(8)], backend, window=4, ordered=ordered)]
    finally:
        backend.close()
    assert sorted(order) == list(range(8))
    assert (order == list(range(8))) == ordered


# ---------------------------------------------------------------- command line


def test_without_output_the_ranked_rows_go_to_stdout(folder, reference):
    root, _, _ = folder
    result = CliRunner().invoke(main, ["triage", str(root), "-j", "1"])
    assert result.exit_code == 1
    header, *printed = [json.loads(line) for line in result.stdout.splitlines()]
    assert [{k: v for k, v in row.items() if k != "outline"} for row in printed] == _rows(reference[1])
    assert header == {"rockscan_report": read_provenance(reference[1])}
    assert "50 ranked, 5 errors" in result.stderr


@pytest.mark.parametrize(
    ("args", "status", "message"),
    [
        (["-o", "{tmp}/r.txt"], 2, "a report must end in .csv, .jsonl"),
        (["-o", "{tmp}/r.csv", "-j", "2", "--scheduler", "tcp://x:1"], 2, "not both"),
        (["--resume"], 2, "--resume needs the report"),
        (["-o", "{tmp}/r.csv", "-j", "0"], 2, "0 is not in the range x>=1"),
        # Usage errors, as the interface has them (exit 1 is a photo that failed):
        (["-o", "{tmp}/exists.csv"], 2, "exists: add --resume to continue it, or --overwrite"),
        (["-o", "{tmp}/cut.html"], 2, "cut.html.jsonl exists: add --resume"),
    ],
)
def test_usage_errors(tmp_path, args, status, message):
    (tmp_path / "exists.csv").write_text("x\n")
    (tmp_path / "cut.html.jsonl").write_text("x\n")  # the journal a cut-short HTML run leaves
    (tmp_path / "photos").mkdir()
    args = [a.format(tmp=tmp_path) for a in args]
    result = CliRunner().invoke(main, ["triage", str(tmp_path / "photos"), *args])
    assert result.exit_code == status
    assert message in result.stderr
    assert (tmp_path / "exists.csv").read_text() == "x\n"


def test_a_missing_folder_is_a_usage_error(tmp_path):
    result = CliRunner().invoke(main, ["triage", str(tmp_path / "nope"), "-o", str(tmp_path / "r.csv")])
    assert result.exit_code == 2
    assert f"Directory '{tmp_path / 'nope'}' does not exist" in result.stderr
    assert not (tmp_path / "r.csv").exists()


def test_an_empty_folder_gives_an_empty_report_and_success(tmp_path):
    (tmp_path / "photos").mkdir()
    result = CliRunner().invoke(main, ["triage", str(tmp_path / "photos"), "-o", str(tmp_path / "r.csv")])
    assert result.exit_code == 0, result.output
    provenance, columns = (tmp_path / "r.csv").read_text().splitlines()
    assert provenance.startswith("# rockscan_report {") and columns == ",".join(CSV_COLUMNS)
    assert _rows(tmp_path / "r.csv") == []
    assert "warning: no photos under" in result.stderr and "other file" not in result.stdout


def test_a_folder_without_photos_says_what_it_skipped(tmp_path):
    # A folder of a phone's HEIC photos gave an empty report without a word.
    folder = tmp_path / "phone"
    folder.mkdir()
    for name in ("IMG_0001.HEIC", "IMG_0002.webp", "IMG_0003.heic", "README"):
        (folder / name).write_bytes(b"x")
    result = CliRunner().invoke(main, ["triage", str(folder), "-o", str(tmp_path / "r.csv")])
    assert result.exit_code == 0, result.output
    assert "0 photos found, 0 already in the report, 0 classified in" in result.stdout
    assert "; 4 other files skipped (no ending, .heic, .webp)" in result.stdout
    assert f"rockscan: warning: no photos under {folder}: photos end in .png, .jpg," in result.stderr


def _run_on_terminal(args: list[str]) -> str:
    """Run the command line with stderr on a pseudo-terminal; return what it drew there."""
    leader, follower = pty.openpty()
    # A terminal 100 columns wide (a new pseudo-terminal has no size).
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    code = "import sys; from rockscan.cli import main; sys.argv[0] = 'rockscan'; main()"
    proc = subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.DEVNULL, stderr=follower)
    os.close(follower)
    chunks = []
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:
            break
        if not chunk:
            break
        chunks.append(chunk)
    proc.wait()
    os.close(leader)
    return b"".join(chunks).decode("utf-8", errors="replace")


def test_progress_bar_on_a_terminal_only(tmp_path):
    _render_folder(tmp_path / "photos", 4)
    drawn = _run_on_terminal(["triage", str(tmp_path / "photos"), "-o", str(tmp_path / "a.csv"), "-j", "1"])
    assert "4/4" in drawn and "photo" in drawn
    quiet = _run_on_terminal(
        ["triage", str(tmp_path / "photos"), "-o", str(tmp_path / "b.csv"), "-j", "1", "--quiet"]
    )
    assert quiet == ""


# ---------------------------------------------------------------- HTML and novelty


def test_html_report_has_a_thumbnail_with_overlay_per_photo(tmp_path, default_lib):
    photos = _render_folder(tmp_path / "photos", 4)
    (tmp_path / "photos" / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    report = tmp_path / "sheet.html"
    snapshots = []

    def look(done, total):
        page = report.read_text()
        snapshots.append((done, page.count('<figure class="card"'), "The run is still going" in page))

    config = TriageConfig(workers=1, refresh_s=0)
    summary = triage_folder(tmp_path / "photos", report, default_lib, config, progress=look)
    assert (summary.n_rows, summary.n_errors) == (5, 1)
    # While the run goes on, the page is a readable snapshot of the rows so far.
    assert [done for done, _, _ in snapshots] == list(range(6))
    assert snapshots[:2] == [(0, 0, True), (1, 1, True)]
    assert all(going and cards <= done for done, cards, going in snapshots)
    rows = _rows(report)
    page = report.read_text()
    assert "The run is still going" not in page
    assert page.count('<figure class="card"') == 5 and "sheet.html.jsonl" in page
    for row in rows:
        if row["error"] is not None:
            assert row["thumbnail"] is None and "no image" in page
            continue
        assert row["thumbnail"] in page
        head, data = row["thumbnail"].split(",", 1)
        assert head == "data:image/webp;base64"
        thumb = np.asarray(Image.open(io.BytesIO(base64.b64decode(data))).convert("RGB")).astype(int)
        assert thumb.shape == (115, 144, 3)  # 160 x 200 scaled to a longer side of 144
        blue = (thumb[..., 2] - thumb[..., 0] > 60) & (thumb[..., 2] > 120)
        yellow = (thumb[..., 0] > 170) & (thumb[..., 1] > 150) & (thumb[..., 2] < 110)
        # The outline over the matched shape (which shows at its edges), around the rock's centroid.
        assert blue.sum() > 5 and yellow.sum() > 100
        rr, cc = np.nonzero(blue | yellow)
        cx, cy = (np.array(row["centroid"]) + 0.5) * 144 / 200 - 0.5
        assert abs(cc.mean() - cx) < 6 and abs(rr.mean() - cy) < 6
    assert len(photos) == 4


def test_novel_rocks_are_flagged_once_added_and_remembered(tmp_path):
    shapes = [
        next((s.name, s.params) for s in read_spec(default_spec_path()) if s.name == "egg"),
        ("four-lobe", SuperformulaParams(4, 4, 0.6, 1, 1)),
        ("eight-lobe", SuperformulaParams(8, 8, 6, 10, 10)),
    ]
    photos = _render_folder(tmp_path / "photos", 6, seed=5, shapes=shapes)
    library = default_spec_path()
    observed = tmp_path / "observed.npz"
    runs = []
    for workers in ("1", "2"):
        observed.unlink(missing_ok=True)
        report = tmp_path / f"r{workers}.jsonl"
        args = ["triage", str(tmp_path / "photos"), "-o", str(report), "-j", workers]
        result = CliRunner().invoke(main, [*args, "--observed", str(observed), "-l", str(library)])
        assert result.exit_code == 0, result.output
        runs.append(_rows(report))
    assert runs[0] == runs[1]
    novel = sorted(Path(r["path"]).name for r in runs[0] if r["novel"])
    # The first photo of each new shape in walk order (root files first, then nested/...).
    assert novel == ["001-four-lobe.jpg", "002-eight-lobe.png"]
    assert all(r["novelty"] > 0 and r["nearest_observed"] for r in runs[0])
    assert "2 novel (observed library: 16 shapes)" in result.stdout
    kept = load_library(observed)
    assert kept.names[-2:] == ("seen-001-four-lobe", "seen-002-eight-lobe")
    again = CliRunner().invoke(
        main,
        ["triage", str(tmp_path / "photos"), "-o", str(tmp_path / "again.csv"), "--observed", str(observed)],
    )
    assert again.exit_code == 0
    assert not any(r["novel"] for r in _rows(tmp_path / "again.csv"))
    assert len(photos) == 6 and math.isfinite(runs[0][0]["novelty"])


def test_novel_shapes_a_killed_run_did_not_save_are_kept_and_not_flagged_again(tmp_path, monkeypatch):
    shapes = [
        ("four-lobe", SuperformulaParams(4, 4, 0.6, 1, 1)),
        ("eight-lobe", SuperformulaParams(8, 8, 6, 10, 10)),
    ]
    _render_folder(tmp_path / "photos", 4, seed=5, shapes=shapes)
    observed, report = tmp_path / "observed.npz", tmp_path / "r.jsonl"
    args = ["triage", str(tmp_path / "photos"), "-o", str(report), "-j", "1", "--observed", str(observed)]
    # The run is killed before its library is written: saving never happens.
    monkeypatch.setattr("rockscan.run.triage._TriageRun.save_observed", lambda self: None)
    assert CliRunner().invoke(main, args).exit_code == 0
    assert not observed.exists()
    pending = tmp_path / "observed.npz.pending"
    assert [name for name, _ in read_pending(pending)] == ["seen-000-four-lobe", "seen-003-eight-lobe"]
    # Resumed from scratch of the same photos, those shapes were novel again (each twice in the report).
    monkeypatch.undo()
    report.unlink()
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert not any(r["novel"] for r in _rows(report))
    assert load_library(observed).names[-2:] == ("seen-000-four-lobe", "seen-003-eight-lobe")
    assert not pending.exists()
    # A torn last line (a write cut short) is dropped.
    pending.write_bytes(b'{"name": "seen-x", "radii": [1.0, 1.')
    assert read_pending(pending) == []


def test_a_library_that_cannot_be_loaded_is_a_usage_error_and_writes_no_report(tmp_path):
    root = tmp_path / "photos"
    _render_folder(root, 1)
    report = tmp_path / "r.csv"
    result = CliRunner().invoke(
        main, ["triage", str(root), "-o", str(report), "--library", str(tmp_path / "no.npz")]
    )
    assert result.exit_code == 2 and "library file not found" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photos"]


def test_a_novel_rock_whose_row_was_not_written_is_novel_again_on_resume(tmp_path, default_lib, monkeypatch):
    # Its shape went into the observed library before its row was written; the
    # disk full, the resume compared the rock with its own shape: not novel,
    # interest 0, ranked last instead of first.
    root = tmp_path / "photos"
    _render_folder(root, 3)
    lobed = SuperformulaParams(m1=4.0, m2=4.0, n1=0.6, n2=1.0, n3=1.0)
    _render_folder(root / "odd", 1, shapes=[("four-lobed", lobed)])
    triage_folder(
        root, tmp_path / "ref.jsonl", default_lib, TriageConfig(workers=1), observed=tmp_path / "ref.npz"
    )
    real = ReportJournal.append

    def full_disk(self, rows):
        rows = [rows] if isinstance(rows, dict) else list(rows)
        if any("four-lobed" in r["path"] for r in rows):
            raise WriteError("r.jsonl: cannot write report (No space left on device)")
        return real(self, rows)

    report, observed = tmp_path / "r.jsonl", tmp_path / "seen.npz"
    monkeypatch.setattr(ReportJournal, "append", full_disk)
    with pytest.raises(WriteError):
        triage_folder(root, report, default_lib, TriageConfig(workers=1), observed=observed)
    monkeypatch.setattr(ReportJournal, "append", real)
    triage_folder(root, report, default_lib, TriageConfig(workers=1, resume=True), observed=observed)
    reference = {Path(r["path"]).name: r for r in _rows(tmp_path / "ref.jsonl")}
    resumed = {Path(r["path"]).name: r for r in _rows(report)}
    rock = "000-four-lobed.png"
    assert reference[rock]["novel"] is True and reference[rock]["rank"] == 1
    assert resumed[rock]["novel"] is True and resumed[rock]["rank"] == 1
    assert resumed[rock]["interest"] == pytest.approx(reference[rock]["interest"])
