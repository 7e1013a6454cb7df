"""What a command writes never destroys what the user gave it, and bad values are
refused before any work (usage errors, exit 2), with ``CliRunner``."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from rockscan.cli import main
from rockscan.core.errors import WriteError
from rockscan.core.library import ShapeSpec
from rockscan.core.render import render_photo
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import _npzsafe, default_library, save_library, write_spec

EGG = SuperformulaParams(1, 1, 0.75, 0.75, 0.75)


@pytest.fixture
def runner():
    return CliRunner()


@pytest.fixture
def photo(tmp_path):
    path = tmp_path / "egg.png"
    path.write_bytes(render_photo(EGG, rng=3).encode(".png"))
    return path


@pytest.fixture
def spec(tmp_path):
    path = tmp_path / "lib.toml"
    write_spec([ShapeSpec("egg", EGG), ShapeSpec("star", SuperformulaParams(5, 5, 2, 7, 7))], path)
    return path


def refused(result, text):
    return result.exit_code == 2 and text in result.stderr and "Traceback" not in result.output


def test_a_library_is_never_written_over_its_spec(runner, spec):
    before = spec.read_bytes()
    # The .npz was written over the TOML it was built from, and the build said so with exit 0.
    assert refused(runner.invoke(main, ["library", "build", str(spec), "-o", str(spec)]), "must end in .npz")
    assert refused(
        runner.invoke(main, ["library", "build", str(spec), "-o", str(spec.with_suffix(".txt"))]),
        "must end in .npz",
    )
    assert spec.read_bytes() == before


def test_fit_writes_neither_its_spec_nor_its_plot_over_a_photo(runner, photo, tmp_path):
    before = photo.read_bytes()
    assert refused(runner.invoke(main, ["library", "fit", str(photo), "-o", str(photo)]), "must end in .toml")
    assert refused(runner.invoke(main, ["library", "fit", str(photo), "--plot", str(photo)]), "is an input")
    assert photo.read_bytes() == before
    other = tmp_path / "earlier.png"
    other.write_bytes(b"an earlier plot")
    assert refused(runner.invoke(main, ["library", "fit", str(photo), "--plot", str(other)]), "--overwrite")
    assert other.read_bytes() == b"an earlier plot"
    drawn = runner.invoke(main, ["library", "fit", str(photo), "--plot", str(other), "--overwrite"])
    assert drawn.exit_code == 0, drawn.output
    assert other.read_bytes()[:4] == b"\x89PNG"


def test_show_draws_over_a_file_only_when_told(runner, photo, spec):
    before = photo.read_bytes()
    assert refused(runner.invoke(main, ["library", "show", str(spec), "--plot", str(photo)]), "--overwrite")
    assert photo.read_bytes() == before
    assert (
        runner.invoke(main, ["library", "show", str(spec), "--plot", str(photo), "--overwrite"]).exit_code
        == 0
    )
    assert photo.read_bytes()[:4] == b"\x89PNG" and photo.read_bytes() != before


def test_family_is_never_written_over_its_spec(runner, spec):
    before = spec.read_bytes()
    result = runner.invoke(
        main, ["library", "family", str(spec), "egg", "--vary", "n1=0.9,1.1", "-o", str(spec)]
    )
    assert refused(result, "is an input")
    assert spec.read_bytes() == before


def test_a_radii_file_fit_cannot_read_is_one_error_and_the_batch_is_written(runner, photo, tmp_path):
    # A structured array raised a TypeError: the batch stopped, its fits lost.
    bad = tmp_path / "struct.npy"
    np.save(bad, np.zeros(360, dtype=[("a", "f8"), ("b", "f8")]))
    out = tmp_path / "fitted.toml"
    result = runner.invoke(main, ["library", "fit", str(bad), str(photo), "-o", str(out)])
    assert result.exit_code == 1
    assert "radii must be real numbers" in result.stderr and "Traceback" not in result.output
    assert 'name = "egg"' in out.read_text()


def test_triage_checks_what_it_would_write_at_its_end_before_it_starts(runner, photo, tmp_path):
    folder = photo.parent
    report = tmp_path / "report.jsonl"
    # The observed library's folder was found missing after every photo was classified.
    result = runner.invoke(main, ["triage", str(folder), "-o", str(report), "--observed", "nowhere/o.npz"])
    assert refused(result, "does not exist")
    assert not report.exists()
    # A malformed address left a report behind, then waited out a minute's timeout.
    result = runner.invoke(main, ["triage", str(folder), "-o", str(report), "--scheduler", "garbage"])
    assert refused(result, "no port in the address")
    assert not report.exists()
    assert refused(runner.invoke(main, ["triage", str(folder), "-o", "nowhere/r.csv"]), "does not exist")


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["render", "--seed", "-1"], "'--seed'"),
        (["render", "--rocks", "99999999999999999999"], "'--rocks'"),
        (["render", "--pebbles", "1000000"], "pebbles must be from 0 to"),
        (["render", "--noise", "1e308"], "noise must be at most"),
        (["library", "fit", "x.png", "--seed", "-1"], "'--seed'"),
        (["library", "build", "x.toml", "-o", "x.npz", "--n-angles", "1000000000"], "'--n-angles'"),
        (["library", "build", "x.toml", "-o", "x.npz", "--components", "0"], "'--components'"),
        (["match", "--params", "4,4,0,1,1"], "n1 must be non-zero"),
    ],
)
def test_values_past_what_a_command_can_do_are_usage_errors(runner, tmp_path, args, text):
    if args[0] == "render":
        args = [*args, "-o", str(tmp_path / "out"), "-n", "1", "--size", "64x80"]
    assert refused(runner.invoke(main, args), text)


def test_a_library_past_what_a_file_may_hold_is_refused_before_it_is_written(tmp_path, monkeypatch):
    # It was written (400 MB at 3,600 rays of 1,000 sections), then refused by every command.
    monkeypatch.setattr(_npzsafe, "MAX_ARCHIVE_BYTES", 10_000)
    target = tmp_path / "big.npz"
    with pytest.raises(WriteError, match="a library file may hold"):
        save_library(default_library(), target)
    assert not target.exists()


@pytest.mark.parametrize(
    "args",
    [
        ["classify", "{photo}", "--plot", ""],
        ["classify", ""],
        ["classify", "-l", "", "{photo}"],
        ["triage", ""],
        ["render", "-o", "", "-n", "1"],
        ["examples", ""],
        ["match", "--radii", ""],
        ["library", "build", "", "-o", "{tmp}/lib.npz"],
        ["library", "fit", "{photo}", "-o", ""],
        ["library", "family", "{spec}", "egg", "--vary", "n1=1.1", "-o", ""],
    ],
)
def test_an_empty_path_is_a_usage_error(runner, photo, spec, tmp_path, monkeypatch, args):
    # The operating system reads "" as the current folder: triage walked it, and
    # classify --plot "" drew nothing and exited 0.
    monkeypatch.chdir(tmp_path)
    args = [a.format(photo=photo, spec=spec, tmp=tmp_path) for a in args]
    before = sorted(p.name for p in tmp_path.iterdir())
    assert refused(runner.invoke(main, args), "an empty name")
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_classify_never_draws_over_a_photo_it_reads_even_with_overwrite(runner, photo, tmp_path):
    before = photo.read_bytes()
    # --overwrite drew the figure over the photo, then classified the figure.
    result = runner.invoke(main, ["classify", str(photo), "--plot", str(photo), "--overwrite"])
    assert refused(result, "is an input")
    other = tmp_path / "out-egg.png"
    other.write_bytes(before)
    result = runner.invoke(
        main, ["classify", str(photo), str(other), "--plot", str(tmp_path / "out.png"), "--overwrite"]
    )
    assert refused(result, "out-egg.png is an input")
    assert photo.read_bytes() == before and other.read_bytes() == before


def test_triage_observed_is_a_library_and_never_the_report_or_the_library_in_use(runner, photo, tmp_path):
    lib = tmp_path / "lib.npz"
    save_library(default_library(), lib)
    before = lib.read_bytes()
    folder = str(photo.parent)
    report = str(tmp_path / "r.csv")
    # The observed library was written over the report (a zip named .csv), or over the library.
    assert refused(runner.invoke(main, ["triage", folder, "-o", report, "--observed", report]), "end in .npz")
    result = runner.invoke(main, ["triage", folder, "-o", report, "-l", str(lib), "--observed", str(lib)])
    assert refused(result, "is an input")
    assert refused(runner.invoke(main, ["triage", folder, "--observed", str(tmp_path / "o.toml")]), ".npz")
    assert lib.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["egg.png", "lib.npz"]


def test_the_groups_quiet_quiets_triage(runner, photo, tmp_path):
    report = tmp_path / "out" / "r.csv"
    report.parent.mkdir()
    loud = runner.invoke(main, ["triage", str(photo.parent), "-o", str(report), "-j", "1"])
    assert loud.exit_code == 0 and "ranked" in loud.output
    result = runner.invoke(
        main, ["-q", "triage", str(photo.parent), "-o", str(report), "-j", "1", "--overwrite"]
    )
    assert result.exit_code == 0 and result.output == ""


def test_an_output_folder_that_cannot_be_written_is_refused_before_the_run(
    runner, photo, tmp_path, monkeypatch
):
    # Found at the end, it lost the observed library of a whole run. (Root may write
    # anywhere, so the folder's permission is what os.access answers here.)
    locked = tmp_path / "locked"
    locked.mkdir()
    real = __import__("os").access
    monkeypatch.setattr("os.access", lambda p, mode: False if str(p) == str(locked) else real(p, mode))
    report = str(tmp_path / "r.csv")
    result = runner.invoke(
        main, ["triage", str(photo.parent), "-o", report, "--observed", str(locked / "o.npz")]
    )
    assert refused(result, "cannot write in folder")
    assert not (tmp_path / "r.csv").exists()


@pytest.mark.parametrize(
    "args",
    [
        ["classify", "{photo}", "--plot", "{tmp}/c.txt"],
        ["library", "fit", "{photo}", "-o", "{tmp}/q.toml", "--plot", "{tmp}/q.txt"],
        ["library", "show", "--plot", "{tmp}/s.txt"],
    ],
)
def test_a_plot_of_a_format_matplotlib_cannot_draw_is_refused_before_the_work(runner, photo, tmp_path, args):
    # The work was done (a spec written), then "cannot write the plot" with exit 1.
    before = sorted(p.name for p in tmp_path.iterdir())
    result = runner.invoke(main, [a.format(photo=photo, tmp=tmp_path) for a in args])
    assert refused(result, "cannot draw a .txt file")
    assert sorted(p.name for p in tmp_path.iterdir()) == before
