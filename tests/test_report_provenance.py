"""Reports that know how they were made: provenance in every format, resume only with the same settings."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from rockscan.cli import main
from rockscan.core.library import Library
from rockscan.core.match import MatchConfig
from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_spec_path, load_library, read_spec, save_library
from rockscan.io.report import ReportSettingsError, journal_path, read_provenance, read_rows
from rockscan.run.pipeline import ClassifyConfig
from rockscan.run.provenance import library_hash, report_provenance
from rockscan.run.triage import TriageConfig, triage_folder

FORMATS = (".csv", ".jsonl", ".html", ".geojson")


@pytest.fixture(scope="module")
def photos(tmp_path_factory) -> Path:
    """Three small rendered photos."""
    root = tmp_path_factory.mktemp("prov") / "photos"
    root.mkdir()
    specs = [(s.name, s.params) for s in read_spec(default_spec_path())][:3]
    rng = np.random.default_rng(3)
    for i, (name, params) in enumerate(specs):
        photo = render_photo(params, RenderConfig(rows=120, cols=150), rng=rng, name=name)
        (root / f"{i}-{name}.png").write_bytes(photo.encode(".png"))
    return root


def _files(report: Path) -> dict[str, bytes]:
    """Every file beside a report, by name."""
    return {p.name: p.read_bytes() for p in sorted(report.parent.iterdir())}


@pytest.mark.parametrize("suffix", FORMATS)
def test_every_format_records_version_library_hash_method_cutoffs_and_options(
    photos, tmp_path, default_lib, suffix
):
    report = tmp_path / f"r{suffix}"
    config = TriageConfig(workers=1, classify=ClassifyConfig(match=MatchConfig(mscore_cutoff=0.4)))
    triage_folder(photos, report, default_lib, config)
    expected = json.loads(json.dumps(report_provenance(default_lib, config, folder=photos)))
    assert read_provenance(report) == expected
    assert expected["photos"] == {"folder": os.path.abspath(photos), "relative_to": None}
    assert expected["library"]["sha256"] == library_hash(default_lib)
    # The per-shape cutoffs are the library's (in its hash); the user's own are recorded too.
    assert expected["cutoffs"] == {"tolerance": 0.2, "distance": None, "mscore": 0.4, "residual": None}
    assert expected["method"]["metric"] == "auto" and expected["options"]["all_rocks"] is False
    assert expected["rockscan"] == __import__("rockscan").__version__
    if suffix == ".html":
        page = report.read_text()
        footer = page[page.index("<footer>") :]
        assert library_hash(default_lib) in footer and "mscore 0.4" in footer
        embedded = footer.split('id="provenance-json">')[1].split("</script>")[0]
        assert json.loads(embedded) == expected
    if suffix == ".geojson":
        assert json.loads(report.read_text())["rockscan_report"] == expected


def test_the_library_hash_is_its_content_in_every_process(tmp_path, default_lib):
    path = tmp_path / "lib.npz"
    save_library(default_lib, path)
    assert library_hash(load_library(path)) == library_hash(default_lib)
    code = (
        "from rockscan.io import default_library; from rockscan.run.provenance import library_hash; "
        "print(library_hash(default_library()))"
    )
    for threads in ("1", "2"):
        env = {**os.environ, "OPENBLAS_NUM_THREADS": threads, "OMP_NUM_THREADS": threads}
        out = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
        assert out.stdout.strip() == library_hash(default_lib)
    # Another interest weight, or one shape fewer, is another library.
    shapes = read_spec(default_spec_path())
    heavier = [*shapes[:-1], type(shapes[-1])(**{**vars(shapes[-1]), "interest": 9.0})]
    assert library_hash(Library.from_shapes(heavier)) != library_hash(default_lib)
    assert library_hash(Library.from_shapes(shapes[:-1])) != library_hash(default_lib)


@pytest.mark.parametrize(
    ("suffix", "change", "named"),
    [
        (".csv", ["--mscore-cutoff", "0.9"], "cutoffs.mscore null (report) vs 0.9 (now)"),
        (".html", ["--method", "paper"], "method.angle_metric"),
        (".jsonl", ["--all"], "options.all_rocks false (report) vs true (now)"),
        (".geojson", ["-l", "LIB"], "library.sha256"),
        # auto ranks clean rocks as eigenspace does: its rows are not sensor's.
        (".jsonl", ["--metric", "sensor"], 'method.metric "auto" (report) vs "sensor" (now)'),
        # Another folder's photos would join the report.
        (".csv", ["FOLDER"], "the report is of the photos in "),
    ],
)
def test_resume_with_other_settings_exits_2_and_leaves_the_report_byte_for_byte(
    photos, tmp_path, suffix, change, named
):
    report = tmp_path / "out" / f"r{suffix}"
    report.parent.mkdir()
    first = CliRunner().invoke(main, ["triage", str(photos), "-o", str(report), "-j", "1", "-q"])
    assert first.exit_code == 0, first.output
    # Make the report look like an interrupted run: one row short.
    lines = journal_path(report).read_bytes().splitlines(keepends=True)
    journal_path(report).write_bytes(b"".join(lines[:-1]))
    before = _files(report)
    folder = str(photos)
    if change == ["FOLDER"]:
        other = tmp_path / "other"
        shutil.copytree(photos, other)
        folder, change = str(other), []
    change = [str(_small_library(tmp_path)) if a == "LIB" else a for a in change]
    result = CliRunner().invoke(main, ["triage", folder, "-o", str(report), "-j", "1", "--resume", *change])
    assert result.exit_code == 2, result.output
    (line,) = result.stderr.splitlines()
    assert line.startswith(f"rockscan: error: {report} was made with other settings (") and named in line
    assert "--overwrite" in line
    assert _files(report) == before
    # With the same settings it resumes.
    again = CliRunner().invoke(main, ["triage", str(photos), "-o", str(report), "-j", "1", "--resume"])
    assert again.exit_code == 0, again.output
    assert "2 already in the report, 1 classified" in again.stdout


def _small_library(tmp_path: Path) -> Path:
    path = tmp_path / "small.npz"
    save_library(Library.from_shapes(read_spec(default_spec_path())[:4]), path)
    return path


def test_a_report_that_records_nothing_is_not_resumed(photos, tmp_path, default_lib):
    report = tmp_path / "old.jsonl"
    row = {"path": "x.png", "error": "x.png: file is empty"}
    report.write_text(json.dumps(row) + "\n")
    with pytest.raises(ReportSettingsError, match="does not record how it was made"):
        triage_folder(photos, report, default_lib, TriageConfig(workers=1, resume=True))
    assert report.read_text() == json.dumps(row) + "\n"
    # It still reads.
    assert [r["path"] for r in read_rows(report)] == ["x.png"]


def test_resume_from_another_working_folder_is_refused_not_doubled(photos, tmp_path, monkeypatch):
    # Rows keep the paths as given: resumed from elsewhere, "../photos/a.png" was
    # another photo than "photos/a.png", and every photo went into the report twice.
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(photos.parent)
    report = tmp_path / "out" / "r.jsonl"
    report.parent.mkdir()
    args = ["-o", str(report), "-j", "1", "-q"]
    assert CliRunner().invoke(main, ["triage", photos.name, *args]).exit_code == 0
    before = _files(report)
    monkeypatch.chdir(tmp_path / "elsewhere")
    result = CliRunner().invoke(main, ["triage", os.path.relpath(photos), *args, "--resume"])
    # Said as what to do: "photos.relative_to "/tmp/..." (report) vs null (now)" left the user guessing.
    expected = (
        f"the report names its photos from {photos.parent}: give the folder as {photos.name} from there"
    )
    assert result.exit_code == 2 and expected in result.stderr
    assert _files(report) == before
    monkeypatch.chdir(photos.parent)
    assert CliRunner().invoke(main, ["triage", photos.name, *args, "--resume"]).exit_code == 0


def test_a_report_reached_through_a_link_is_written_to_its_target(photos, tmp_path):
    # Through "latest.csv -> runs/sol.csv", the new rows went into the target
    # unranked and a file of its own took the link's place: two reports disagreed.
    folder = tmp_path / "photos"
    folder.mkdir()
    first, *later = sorted(photos.iterdir())
    shutil.copy(first, folder)
    (tmp_path / "runs").mkdir()
    target = tmp_path / "runs" / "sol.csv"
    args = ["-j", "1", "-q"]
    assert CliRunner().invoke(main, ["triage", str(folder), "-o", str(target), *args]).exit_code == 0
    link = tmp_path / "latest.csv"
    link.symlink_to(Path("runs") / "sol.csv")
    for path in later:
        shutil.copy(path, folder)
    result = CliRunner().invoke(main, ["triage", str(folder), "-o", str(link), "--resume", *args])
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and link.resolve() == target.resolve()
    rows = list(read_rows(target))
    assert [r["rank"] for r in rows] == [1, 2, 3]
    assert sorted(Path(r["path"]).name for r in rows) == sorted(p.name for p in photos.iterdir())


@pytest.mark.parametrize("report", ["sheet.html.jsonl", "map.geojson.jsonl"])
def test_the_journal_of_an_html_or_geojson_report_is_not_taken_for_a_report(photos, tmp_path, report):
    # A run on the journal ran beside the report's own run (each locked its own
    # name) and wrote rows without thumbnails into the sheet.
    result = CliRunner().invoke(main, ["triage", str(photos), "-o", str(tmp_path / report), "-q"])
    assert result.exit_code == 2
    assert (
        f"the journal the report {tmp_path / report[: -len('.jsonl')]} keeps while it runs" in result.stderr
    )
    assert list(tmp_path.iterdir()) == []


def test_resume_with_another_observed_library_is_refused(photos, tmp_path):
    # A slip in --observed's path started a new, empty library: shapes the first
    # file had seen were called novel again, in the same report.
    report = tmp_path / "r.csv"
    args = ["triage", str(photos), "-o", str(report), "-j", "1", "-q"]
    first = CliRunner().invoke(main, [*args, "--observed", str(tmp_path / "seen.npz")])
    assert first.exit_code == 0, first.output
    before = _files(report)
    other = CliRunner().invoke(main, [*args, "--observed", str(tmp_path / "sen.npz"), "--resume"])
    assert other.exit_code == 2
    # Whole paths: shortened in the middle, the two names read alike.
    assert (
        f'options.novelty.file "{tmp_path / "seen.npz"}" (report) vs "{tmp_path / "sen.npz"}" (now)'
        in other.stderr
    )
    assert _files(report) == before and not (tmp_path / "sen.npz").exists()
    again = CliRunner().invoke(main, [*args, "--observed", str(tmp_path / "seen.npz"), "--resume"])
    assert again.exit_code == 0, again.output
    # Left out on resume: the refusal names the file whole (it read {"file": "/t...33875}).
    left_out = CliRunner().invoke(main, [*args, "--resume"])
    assert left_out.exit_code == 2
    assert f'options.novelty.file "{tmp_path / "seen.npz"}" (report) vs null (now)' in left_out.stderr
    assert _files(report) == before


def test_a_resume_says_which_rows_no_longer_fit_the_folder(photos, tmp_path):
    # A photo removed, renamed or replaced under its name kept its old row without
    # a word: "10 photos found ... 12 ranked".
    folder = tmp_path / "photos"
    shutil.copytree(photos, folder)
    report = tmp_path / "r.csv"
    args = ["triage", str(folder), "-o", str(report), "-j", "1", "-q"]
    assert CliRunner().invoke(main, args).exit_code == 0
    first, second, third = sorted(folder.iterdir())
    first.unlink()
    second.rename(folder / "renamed.png")
    # Replaced under its name: later than the report's last write.
    os.utime(third, (report.stat().st_mtime + 5, report.stat().st_mtime + 5))
    result = CliRunner().invoke(main, [*args[:-1], "--resume"])
    assert result.exit_code == 0, result.output
    assert "2 photos in the report are no longer under" in result.stderr
    assert "1 photo in the report was changed after it was last written" in result.stderr
    # Still so at the next resume: the rows are what they were.
    again = CliRunner().invoke(main, [*args[:-1], "--resume"])
    assert "changed after" in again.stderr and "2 photos in the report are no longer" in again.stderr
    fresh = CliRunner().invoke(main, [*args[:-1], "--overwrite"])
    assert fresh.exit_code == 0 and "warning" not in fresh.stderr


def test_a_killed_runs_temporary_report_is_removed_by_the_next_run(photos, tmp_path, default_lib):
    # kill -9 while the report was ranked left ".r.csv.tmpPID" (25 MB for a large report)
    # beside it for good.
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    )
    leftover = tmp_path / f".r.csv.tmp{int(dead.stdout)}"
    leftover.write_bytes(b"x" * 1000)
    running = tmp_path / f".r.csv.tmp{os.getppid()}"  # a live process's: not touched
    running.write_bytes(b"x")
    other = tmp_path / f".other.csv.tmp{int(dead.stdout)}"  # another file's
    other.write_bytes(b"x")
    triage_folder(photos, tmp_path / "r.csv", default_lib, TriageConfig(workers=1))
    assert not leftover.exists() and running.exists() and other.exists()
