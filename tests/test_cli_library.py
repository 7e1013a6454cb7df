"""Command line: library build/show and match, with click's CliRunner."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from click.testing import CliRunner

from rockscan.cli import main
from rockscan.core.superformula import SuperformulaParams, shape_radii
from rockscan.io import default_spec_path, load_library


@pytest.fixture
def runner():
    return CliRunner()


def test_build_and_show(runner, tmp_path):
    out = tmp_path / "lib.npz"
    result = runner.invoke(main, ["library", "build", str(default_spec_path()), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "14 shapes, 13 eigenfaces" in result.output
    assert len(load_library(out)) == 14
    shown = runner.invoke(main, ["library", "show", str(out), "--plot", str(tmp_path / "shapes.png")])
    assert shown.exit_code == 0
    assert "six-pointed-star" in shown.output and "circle" in shown.output
    assert (tmp_path / "shapes.png").stat().st_size > 10_000
    as_json = runner.invoke(main, ["library", "show", str(out), "--json"])
    records = [json.loads(line) for line in as_json.stdout.splitlines()]
    assert len(records) == 14 and records[2]["name"] == "six-pointed-star" and records[2]["symmetry"] == 6


@pytest.mark.parametrize("face", ["information", "radii", "information-shape"])
def test_build_face_kinds(runner, tmp_path, face):
    args = [
        "library",
        "build",
        str(default_spec_path()),
        "-o",
        str(tmp_path / "l.npz"),
        "--face",
        face,
        "--n-angles",
        "180",
    ]
    if face == "information-shape":
        args += ["--reference", "rounded-triangle"]
    result = runner.invoke(main, args)
    assert result.exit_code == 0, result.output
    assert load_library(tmp_path / "l.npz").face_config.kind == face


def test_build_errors_are_one_line(runner, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[shape]]\nname = "x"\nm1 = 4\nm2 = 4\nn1 = 0\nn2 = 1\nn3 = 1\n')
    result = runner.invoke(main, ["library", "build", str(bad), "-o", str(tmp_path / "l.npz")])
    assert result.exit_code == 1
    assert result.stderr.count("\n") == 1 and "n1 must be non-zero" in result.stderr
    assert "Traceback" not in result.output
    usage = runner.invoke(main, ["library", "build", str(default_spec_path())])
    assert usage.exit_code == 2


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--face", "information-shape"], "needs --reference NAME"),
        (["--face", "information-shape", "--reference", "nope"], "'nope' is not a Superformula shape"),
        (["--reference", "circle"], "--reference is for --face information-shape"),
        (["--resolution", "10"], "resolution must be at most half of ray_length"),
        # Refused from the options: built first, it took 2 GB (20 GB at 1e-5) before the refusal.
        (["--resolution", "0.0001"], "would take at least 403,200,000 bytes, past the 268,435,456"),
    ],
)
def test_build_options_at_fault_are_usage_errors(runner, tmp_path, options, message):
    # They exited 1, a failure, where a bad option value is a usage error.
    out = tmp_path / "l.npz"
    result = runner.invoke(main, ["library", "build", str(default_spec_path()), "-o", str(out), *options])
    assert result.exit_code == 2 and message in result.stderr
    assert not out.exists()


def test_show_refuses_a_corrupt_library(runner, tmp_path):
    bad = tmp_path / "lib.npz"
    bad.write_bytes(b"PK\x03\x04 broken")
    result = runner.invoke(main, ["library", "show", str(bad)])
    assert result.exit_code == 1
    assert result.stderr.startswith("rockscan: error: ") and result.stderr.count("\n") == 1


def test_match_superformula_parameters(runner):
    result = runner.invoke(main, ["match", "--params", "6,6,0.2,1.7,1.7", "--rotate", "25", "--json"])
    assert result.exit_code == 0, result.output
    record = json.loads(result.stdout)
    assert record["nearest"] == "six-pointed-star" and record["interesting"] is True
    assert record["mscore"] == pytest.approx(1.0, abs=1e-6)
    assert record["angle_deg"] % 60 == pytest.approx(25.0, abs=0.1)


def test_match_radii_file_at_another_sampling(runner, tmp_path):
    radii = shape_radii(SuperformulaParams(1, 1, 0.5, 0.5, 0.5), 720) * 40
    path = tmp_path / "rock.txt"
    np.savetxt(path, radii)
    result = runner.invoke(main, ["match", "--radii", str(path)])
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith("nearest teardrop")


def test_match_with_a_spec_as_library_and_the_papers_method(runner, tmp_path):
    spec = tmp_path / "paper.toml"
    spec.write_text(
        '[[shape]]\nname = "rounded-triangle"\nm1 = 3\nm2 = 3\nn1 = 1500\nn2 = 1500\nn3 = 1500\n'
        '[[shape]]\nname = "six-pointed-star"\nm1 = 6\nm2 = 6\nn1 = 0.2\nn2 = 1.7\nn3 = 1.7\n'
    )
    result = runner.invoke(
        main,
        [
            "match",
            "--params",
            "6,6,0.205,1.71,1.71",
            "--library",
            str(spec),
            "--method",
            "paper",
            "--no-scan",
            "--json",
        ],
    )
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["nearest"] == "six-pointed-star"


@pytest.mark.parametrize(
    ("args", "code", "text"),
    [
        (["match"], 2, "exactly one of --params or --radii"),
        (["match", "--params", "1,2,3"], 2, "5 or 7"),
        (["match", "--params", "a,b,c,d,e"], 2, "5 or 7"),
        # Parameters no Superformula has are a bad option value (exit 2), as a word is.
        (["match", "--params", "4,4,0,1,1"], 2, "n1 must be non-zero"),
        (["match", "--params", "2,4,1,1,1"], 2, "unbounded"),
        (["match", "--params", "4,4,2,,2,2"], 2, "5 or 7"),
        (["match", "--radii", "/nonexistent/r.txt"], 1, "not found"),
        (["match", "--params", "4,4,2,2,2", "--library", "/nonexistent.npz"], 2, "library file not found"),
    ],
)
def test_match_errors(runner, args, code, text):
    result = runner.invoke(main, args)
    assert result.exit_code == code
    assert text in result.output + result.stderr
    assert "Traceback" not in result.output + result.stderr


def test_help_and_version(runner):
    assert runner.invoke(main, ["--help"]).exit_code == 0
    assert "rockscan" in runner.invoke(main, ["--version"]).output


# ---------------------------------------------------------------- the built-in library by name


def test_default_names_the_built_in_library(runner, tmp_path):
    from rockscan.io import default_library

    names = default_library().names
    shown = runner.invoke(main, ["library", "show", "default", "--json"])
    assert shown.exit_code == 0
    assert [json.loads(line)["name"] for line in shown.stdout.splitlines()] == list(names)
    assert runner.invoke(main, ["library", "show", "--json"]).stdout == shown.stdout
    table = runner.invoke(main, ["library", "show", "default"])
    assert table.stdout.startswith("default (built-in): 14 shapes")
    matched = runner.invoke(main, ["match", "--params", "6,6,60,55,10", "--library", "default", "--json"])
    assert json.loads(matched.stdout)["nearest"] == "three-faced-blunt"


def test_plot_alone_draws_beside_with_the_librarys_name(runner, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(main, ["library", "show", str(default_spec_path()), "--plot"])
    assert result.exit_code == 0, result.output
    assert result.stderr == "rockscan: drew default_library.png\n"
    assert os.path.getsize("default_library.png") > 10_000
    named = runner.invoke(main, ["library", "show", "default", "--plot", "mine.png", "-q"])
    assert named.exit_code == 0 and named.stderr == "" and os.path.isfile("mine.png")


# ---------------------------------------------------------------- examples


def test_examples_copies_the_photos_and_refuses_to_replace_them(runner, tmp_path):
    from rockscan.io import data_path

    out = tmp_path / "ex"
    result = runner.invoke(main, ["examples", str(out)])
    assert result.exit_code == 0, result.output
    shipped = sorted(
        p.name for p in data_path("examples").iterdir() if p.is_file() and not p.name.startswith(("_", "."))
    )
    assert sorted(p.name for p in out.iterdir()) == shipped and "coin.png" in shipped
    assert (out / "coin.png").read_bytes() == (data_path("examples") / "coin.png").read_bytes()
    assert result.stderr == f"rockscan: copied 4 example photos ({len(shipped)} files) to {out}\n"
    (out / "coin.png").write_bytes(b"changed")
    again = runner.invoke(main, ["examples", str(out)])
    assert again.exit_code == 2 and "give --overwrite" in again.stderr
    assert (out / "coin.png").read_bytes() == b"changed"
    assert runner.invoke(main, ["examples", str(out), "--overwrite"]).exit_code == 0
    classified = runner.invoke(main, ["classify", "--json", str(out / "coin.png")])
    assert json.loads(classified.stdout)["nearest"] == "circle"


def test_show_keeps_its_columns_in_line_for_a_long_name(runner, tmp_path):
    spec = tmp_path / "names.toml"
    spec.write_text(
        '[[shape]]\nname = "site-12-meteorite-candidate-a"\nm1 = 3\nm2 = 3\nn1 = 2\nn2 = 5\nn3 = 5\n'
        '[[shape]]\nname = "circle"\nm1 = 0\nm2 = 0\nn1 = 1\nn2 = 1\nn3 = 1\n'
    )
    result = runner.invoke(main, ["library", "show", str(spec)])
    assert result.exit_code == 0, result.output
    header, *rows = result.output.splitlines()[1:4]
    width = header.index("symmetry") - 1
    for row, (name, order) in zip(
        rows, [("site-12-meteorite-candidate-a", "3"), ("circle", "circle")], strict=True
    ):
        assert row[:width].rstrip() == name and row[width] == " "
        assert row[width + 1 : width + 9].strip() == order


def test_match_says_what_decided_against_the_cutoffs_library_show_prints(runner, tmp_path):
    # The cutoff show printed could not be compared with anything match or classify
    # printed: rocks under it were rejected, on a distance no output gave.
    shown = {
        row["name"]: row
        for row in map(json.loads, runner.invoke(main, ["library", "show", "--json"]).output.splitlines())
    }
    result = runner.invoke(main, ["match", "--params", "7,7,2,7,7", "--json"])
    record = json.loads(result.output)
    assert record["decided_by"] == "calibrated-cutoff" and record["interesting"] is False
    assert record["sensor_distance"] > record["cutoff_distance"]
    row = shown[record["nearest"]]
    low, high = sorted((row["clean_cutoff"], row["cutoff"]))
    assert low <= record["cutoff_distance"] <= high
    text = runner.invoke(main, ["match", "--params", "7,7,2,7,7"]).output
    assert (
        f"(sensor distance {record['sensor_distance']:.3g} > cutoff {record['cutoff_distance']:.3g})" in text
    )
