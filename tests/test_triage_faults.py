"""A triage that survives its faults (issue cases 1-5): a lost or impossible scheduler, two runs on
one report, a killed parent, odd file names, a full disk and a hand-edited journal."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from rockscan.cli import main
from rockscan.core.errors import ParameterError
from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_spec_path, read_spec
from rockscan.io.report import ReportJournal, journal_path, lock_report, read_rows
from rockscan.run.triage import TriageConfig, triage_folder

CLI = "import sys; from rockscan.cli import main; sys.argv[0] = 'rockscan'; main()"
#: Guards against a hang only; no test measures time.
HANG_S = 120


def _render(root: Path, n: int, size=(120, 150), seed=0) -> list[Path]:
    specs = [(s.name, s.params) for s in read_spec(default_spec_path())]
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    out = []
    for i in range(n):
        name, params = specs[i % len(specs)]
        path = root / f"{i:03d}-{name}.png"
        path.write_bytes(
            render_photo(params, RenderConfig(rows=size[0], cols=size[1]), rng=rng).encode(".png")
        )
        out.append(path)
    return out


@pytest.fixture(scope="module")
def photos(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("faults") / "photos"
    _render(root, 24)
    return root


def _n_rows(report: Path) -> int:
    try:
        return sum(1 for _ in read_rows(report))
    except ParameterError:
        return 0


def _wait_for_rows(report: Path, proc: subprocess.Popen, n: int) -> None:
    deadline = time.monotonic() + HANG_S
    while time.monotonic() < deadline and proc.poll() is None and _n_rows(report) < n:
        time.sleep(0.02)
    assert proc.poll() is None, "the run ended before the fault could be made"


def _children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (Linux /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(entry))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


# ---------------------------------------------------------------- case 2: two runs on one report


def test_a_second_run_on_a_report_is_refused_at_once_and_the_first_finishes(photos, tmp_path):
    report = tmp_path / "r.csv"
    args = ["triage", str(photos), "-o", str(report), "-j", "1", "-q"]
    first = subprocess.Popen(
        [sys.executable, "-c", CLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    _wait_for_rows(report, first, 2)
    second = CliRunner().invoke(main, [*args, "--resume"])
    assert second.exit_code == 1
    assert (
        second.stderr
        == f"rockscan: error: {report}: another rockscan run is writing this report; wait for it to end\n"
    )
    first.communicate(timeout=HANG_S)
    assert first.returncode == 0
    rows = list(read_rows(report))
    assert sorted(r["path"] for r in rows) == sorted(str(p) for p in photos.iterdir())
    assert [r["rank"] for r in rows] == list(range(1, 25))
    # The lock ends with its run, and the report resumes.
    assert not (tmp_path / ".r.csv.lock").exists()
    assert CliRunner().invoke(main, [*args, "--resume"]).exit_code == 0


def test_the_lock_is_held_for_the_run_and_the_journal_only_appended(tmp_path):
    report = tmp_path / "r.jsonl"
    with lock_report(report):
        with pytest.raises(ParameterError, match="another rockscan run is writing"):
            with lock_report(report):
                pass
    with lock_report(report):  # released
        pass
    journal = ReportJournal(report, provenance={"x": 1})
    assert journal._fh.mode == "ab"
    journal.close()


# ---------------------------------------------------------------- case 4: a killed parent


@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGTERM])
def test_workers_end_with_their_parent(photos, tmp_path, how):
    report = tmp_path / "r.jsonl"
    args = ["triage", str(photos), "-o", str(report), "-j", "2", "-q"]
    proc = subprocess.Popen(
        [sys.executable, "-c", CLI, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    _wait_for_rows(report, proc, 1)
    workers = _children(proc.pid)
    assert len(workers) >= 2
    proc.send_signal(how)
    _, err = proc.communicate(timeout=HANG_S)
    deadline = time.monotonic() + HANG_S
    while time.monotonic() < deadline and any(_alive(w) for w in workers):
        time.sleep(0.05)
    assert not any(_alive(w) for w in workers), "orphaned workers"
    if how == signal.SIGTERM:
        # Stopped as by Ctrl-C: the rows so far ranked, and how to finish.
        assert proc.returncode == 130 and b"run again with --resume" in err
        rows = list(read_rows(report))
        assert [r["rank"] for r in rows] == list(range(1, len(rows) + 1))
    assert b"Traceback" not in err


# ---------------------------------------------------------------- case 1: Dask


def test_a_scheduler_address_that_cannot_work_is_one_clear_line(photos, tmp_path):
    code = f"""
import sys
from rockscan.io import default_library
from rockscan.run.triage import TriageConfig, triage_folder
from rockscan.core.errors import ParameterError
for i, address in enumerate(["nonsense://x:1", "tls://127.0.0.1:9", "inproc://x", "tcp://127.0.0.1:9"]):
    try:
        triage_folder({str(photos)!r}, f"{tmp_path}/r{{i}}.csv", default_library(),
                      TriageConfig(scheduler=address, connect_timeout_s=1))
    except ParameterError as exc:
        print(exc)
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_S)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 4
    assert "nonsense://x:1: unknown address scheme 'nonsense'" in lines[0]
    assert "tls:// needs TLS certificates" in lines[1]
    assert "inproc:// reaches only a scheduler inside this process" in lines[2]
    assert lines[3].startswith("cannot reach the Dask scheduler at tcp://127.0.0.1:9")


def test_a_killed_dask_worker_loses_no_photo_and_a_killed_scheduler_is_a_clear_error(
    photos, tmp_path, default_lib
):
    pytest.importorskip("distributed")
    port = 20000 + os.getpid() % 20000
    address = f"tcp://127.0.0.1:{port}"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    scheduler = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--port", str(port), "--no-dashboard"],
        **quiet,
    )
    worker = [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--no-nanny"]
    workers = [subprocess.Popen([*worker, "--no-dashboard"], **quiet) for _ in range(2)]
    try:
        # A worker killed mid-run: the scheduler gives its photos to the other one.
        report = tmp_path / "r.jsonl"
        killed = []

        def kill_one(done, total):
            if done == 3 and not killed:
                workers[0].kill()
                killed.append(done)

        config = TriageConfig(scheduler=address, connect_timeout_s=60)
        summary = triage_folder(photos, report, default_lib, config, progress=kill_one)
        assert killed and summary.n_errors == 0
        rows = list(read_rows(report))
        assert sorted(r["path"] for r in rows) == sorted(str(p) for p in photos.iterdir())
        assert all(r["error"] is None for r in rows)
        # The scheduler killed mid-run: a clear error at once, the rows so far ranked.
        root = tmp_path / "photos"
        _render(root, 12, size=(200, 260), seed=1)
        report = tmp_path / "r.csv"
        args = ["triage", str(root), "-o", str(report), "--scheduler", address, "-q"]
        proc = subprocess.Popen(
            [sys.executable, "-c", CLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        _wait_for_rows(report, proc, 3)
        scheduler.kill()
        _, err = proc.communicate(timeout=HANG_S)
    finally:
        for p in (scheduler, *workers):
            p.kill()
            p.wait()
    assert proc.returncode == 1, err.decode()
    (line,) = err.decode().splitlines()
    assert line.startswith(f"rockscan: error: lost the Dask scheduler at {address}") and "--resume" in line
    rows = list(read_rows(report))
    assert 3 <= len(rows) < 12 and [r["rank"] for r in rows] == list(range(1, len(rows) + 1))
    result = CliRunner().invoke(main, ["triage", str(root), "-o", str(report), "-j", "1", "--resume", "-q"])
    assert result.exit_code == 0 and len(list(read_rows(report))) == 12


# ---------------------------------------------------------------- case 5: names, disk, hand edits


def _odd_names() -> list[bytes]:
    allowed = bytes(b for b in range(1, 256) if b != ord("/"))
    return [
        b"carriage\rreturn.png",
        b"new\nline.png",
        b'quote",comma and tab\t.png',
        b"\xff\xfenot-utf8.png",
        b"#hash-first.png",
        allowed[:120] + b".png",
        allowed[120:] + b".png",
    ]


@pytest.fixture(scope="module")
def odd_folder(tmp_path_factory) -> tuple[Path, list[str]]:
    root = tmp_path_factory.mktemp("odd") / "photos"
    source = _render(tmp_path_factory.mktemp("odd-source"), 1)[0].read_bytes()
    names = []
    for name in _odd_names():
        os.makedirs(os.fsencode(root), exist_ok=True)
        path = os.path.join(os.fsencode(root), name)
        with open(path, "wb") as fh:
            fh.write(source)
        names.append(os.fsdecode(path))
    return root, sorted(names)


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".html", ".geojson"])
def test_odd_file_names_round_trip_and_resume(odd_folder, tmp_path, suffix):
    root, names = odd_folder
    report = tmp_path / f"r{suffix}"
    args = ["triage", str(root), "-o", str(report), "-j", "1"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    rows = list(read_rows(report))
    assert sorted(r["path"] for r in rows) == names and all(r["error"] is None for r in rows)
    # Cut the last row as a crash would, and resume.
    journal = journal_path(report)
    data = journal.read_bytes()
    journal.write_bytes(data[: data.rstrip(b"\r\n").rfind(b"\n") + 1])
    again = CliRunner().invoke(main, [*args, "--resume"])
    assert again.exit_code == 0, again.output
    assert "6 already in the report, 1 classified" in again.stdout
    assert sorted(r["path"] for r in read_rows(report)) == names
    if suffix == ".geojson":
        collection = json.loads(report.read_bytes())
        assert sorted(f["properties"]["path"] for f in collection["features"]) == names
    if suffix == ".html":
        page = report.read_bytes().decode("utf-8")  # valid UTF-8 whatever the names
        assert page.count('<figure class="card"') == 7 and "%FF%FEnot-utf8.png" in page


def test_a_full_disk_is_a_clear_message_and_the_report_stays_readable_and_resumable(photos, tmp_path):
    report = tmp_path / "r.csv"
    args = ["triage", str(photos), "-o", str(report), "-j", "1", "-q"]
    # The provenance and column lines, and a few rows.
    limit = 3000

    def small_disk() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    proc = subprocess.run(
        [sys.executable, "-c", CLI, *args],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        preexec_fn=small_disk,
    )
    assert proc.returncode == 1
    (line,) = proc.stderr.splitlines()
    assert line.startswith(f"rockscan: error: {report}: cannot write report (File too large)")
    assert "run again with --resume" in line
    kept = list(read_rows(report))
    assert 1 <= len(kept) < 24 and report.stat().st_size <= limit
    result = CliRunner().invoke(main, [*args, "--resume"])
    assert result.exit_code == 0, result.output
    rows = list(read_rows(report))
    assert sorted(r["path"] for r in rows) == sorted(str(p) for p in photos.iterdir())


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("interest", "x", "interest holds 'x', not a number"),
        ("interesting", 1, "interesting holds 1, not true or false"),
    ],
)
def test_a_hand_edited_journal_is_one_clear_line(photos, tmp_path, field, value, message):
    report = tmp_path / "r.jsonl"
    args = ["triage", str(photos), "-o", str(report), "-j", "1", "-q"]
    assert CliRunner().invoke(main, args).exit_code == 0
    header, first, *rest = report.read_text().splitlines(keepends=True)
    row = json.loads(first)
    row[field] = value
    report.write_text(header + json.dumps(row) + "\n" + "".join(rest))
    result = CliRunner().invoke(main, [*args, "--resume"])
    assert result.exit_code == 1
    assert result.stderr == f"rockscan: error: {report}: row 1: {message}; was it edited?\n"
    with pytest.raises(ParameterError, match=message):
        list(read_rows(report))
