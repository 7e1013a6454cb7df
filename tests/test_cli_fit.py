"""Command line: ``library fit`` and ``library family``, with click's CliRunner."""

from __future__ import annotations

import json
import math
import os
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import PAPER_SHAPES
from PIL import Image

from rockscan.cli import main
from rockscan.core.library import Library, ShapeSpec, sanitize_name
from rockscan.core.polar import polar_angles, recenter_radii
from rockscan.core.render import render_photo
from rockscan.core.superformula import SuperformulaParams, shape_radii
from rockscan.io import read_spec, write_spec

EGG = SuperformulaParams(1, 1, 0.75, 0.75, 0.75)
STAR5 = SuperformulaParams(5, 5, 2.0, 7.0, 7.0)


@pytest.fixture
def runner():
    return CliRunner()


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    """Two rendered rocks whose file names are not shape names, and their truth."""
    folder = tmp_path_factory.mktemp("photos")
    out = {}
    for i, (stem, params) in enumerate([("Egg Rock_01", EGG), ("STAR.5", STAR5)]):
        photo = render_photo(params, rng=100 + i)
        path = folder / f"{stem}.png"
        path.write_bytes(photo.encode(".png"))
        out[str(path)] = (params, photo.truth["angle_deg"])
    return out


def curve_error(
    params: SuperformulaParams, angle_deg: float, true: SuperformulaParams, true_angle: float
) -> float:
    """RMS difference (percent of the mean radius) of two turned shapes about their centroids."""
    theta = polar_angles(360)
    curves = []
    for p, a in ((params, angle_deg), (true, true_angle)):
        r, _ = recenter_radii(p.radii(np.mod(theta - math.radians(a), 2 * np.pi)))
        curves.append(r / r.mean())
    return float(np.sqrt(np.mean((curves[0] - curves[1]) ** 2)) * 100)


# ---------------------------------------------------------------- fit


def test_fit_photos_writes_a_spec_named_after_the_files(runner, photos, tmp_path):
    spec = tmp_path / "fitted.toml"
    result = runner.invoke(main, ["library", "fit", *photos, "-o", str(spec), "--json"])
    assert result.exit_code == 0, result.output
    records = [json.loads(line) for line in result.stdout.splitlines()]
    assert [r["name"] for r in records] == ["egg-rock-01", "star-5"]
    assert [r["path"] for r in records] == list(photos)
    shapes = read_spec(spec)
    assert [s.name for s in shapes] == ["egg-rock-01", "star-5"]
    for record, shape, (true, true_angle) in zip(records, shapes, photos.values(), strict=True):
        assert record["params"] == shape.params.as_dict()
        assert 0 < record["rms_percent"] < 1.5
        assert curve_error(shape.params, record["angle_deg"], true, true_angle) < 1.5
    assert "wrote" in result.stderr
    # The spec is a library spec like any other.
    assert len(Library.from_shapes(shapes)) == 2


def test_fit_report_without_output_prints_the_spec(runner, photos):
    photo = next(iter(photos))
    result = runner.invoke(main, ["library", "fit", photo])
    assert result.exit_code == 0, result.output
    spec = tomllib.loads(result.stdout)
    assert [s["name"] for s in spec["shape"]] == ["egg-rock-01"]
    (line,) = result.stderr.splitlines()
    assert line.startswith("egg-rock-01") and "rms" in line and "%" in line


def test_fit_radii_files_text_and_npy(runner, tmp_path):
    radii = shape_radii(STAR5, 240) * 80.0
    (tmp_path / "star.txt").write_text(", ".join(f"{r:.6f}" for r in radii))
    np.save(tmp_path / "star-b.npy", np.roll(radii, 40))
    result = runner.invoke(
        main, ["library", "fit", str(tmp_path / "star.txt"), str(tmp_path / "star-b.npy"), "--json"]
    )
    assert result.exit_code == 0, result.output
    first, second = (json.loads(line) for line in result.stdout.splitlines())
    assert first["name"] == "star" and second["name"] == "star-b"
    assert first["rms_percent"] < 0.1 and second["rms_percent"] < 0.1
    # Rolled by 40 of 240 rays: turned by 60 degrees, i.e. 12 modulo the 72 of a 5-fold star.
    gap = (second["angle_deg"] - first["angle_deg"] - 60.0) % 72.0
    assert min(gap, 72.0 - gap) < 0.2


def test_fit_keeps_going_after_a_bad_input_and_exits_1(runner, photos, tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("1 2 oops")
    blank = tmp_path / "blank.png"
    Image.fromarray(np.full((64, 64), 128, np.uint8)).save(blank)
    photo = next(iter(photos))
    spec = tmp_path / "out.toml"
    result = runner.invoke(main, ["library", "fit", str(bad), photo, str(blank), "-o", str(spec), "--json"])
    assert result.exit_code == 1
    bad_line, good_line, blank_line = (json.loads(line) for line in result.stdout.splitlines())
    assert bad_line["path"] == str(bad) and "cannot read radii" in bad_line["error"]
    assert good_line["name"] == "egg-rock-01"
    assert blank_line["path"] == str(blank) and "no rock" in blank_line["error"].lower()
    assert [s.name for s in read_spec(spec)] == ["egg-rock-01"]
    plain = runner.invoke(main, ["library", "fit", str(bad), "-o", str(spec)])
    assert plain.exit_code == 1
    assert plain.stderr.startswith("rockscan: error: ") and len(plain.stderr.splitlines()) == 1
    assert "Traceback" not in plain.output


def test_fit_appends_to_a_spec_and_keeps_names_unique(runner, photos, tmp_path):
    spec = tmp_path / "lib.toml"
    write_spec([ShapeSpec("egg-rock-01", EGG), ShapeSpec("star", STAR5)], spec)
    photo = next(iter(photos))
    result = runner.invoke(main, ["library", "fit", photo, photo, "-o", str(spec), "--append"])
    assert result.exit_code == 0, result.output
    names = [s.name for s in read_spec(spec)]
    assert names == ["egg-rock-01", "star", "egg-rock-01-2", "egg-rock-01-3"]
    assert read_spec(spec)[1].params == STAR5


def test_fit_append_keeps_the_specs_comments(runner, photos, tmp_path):
    # The spec was rewritten from its shapes: a hand-made library lost its notes.
    spec = tmp_path / "lib.toml"
    written = "# my rocks: keep these notes\n" + write_spec([ShapeSpec("star", STAR5)]).replace(
        'name = "star"', 'name = "star"  # the one from site 4'
    )
    spec.write_text(written)
    result = runner.invoke(main, ["library", "fit", next(iter(photos)), "-o", str(spec), "--append"])
    assert result.exit_code == 0, result.output
    assert spec.read_text().startswith(written.rstrip("\n") + "\n\n[[shape]]")
    names = [shape.name for shape in read_spec(spec)]
    assert len(names) == 2 and names[0] == "star"


def test_fit_plot_draws_outline_and_curve(runner, photos, tmp_path):
    png = tmp_path / "fits.png"
    result = runner.invoke(
        main, ["library", "fit", *photos, "-o", str(tmp_path / "s.toml"), "--plot", str(png)]
    )
    assert result.exit_code == 0, result.output
    assert f"drew {png}" in result.stdout
    with Image.open(png) as image:
        assert image.format == "PNG"
        pixels = np.asarray(image.convert("RGB")).astype(int)
    red = (pixels[..., 0] > 200) & (pixels[..., 1] < 120) & (pixels[..., 2] < 120)
    assert red[:, : pixels.shape[1] // 2].sum() > 200 and red[:, pixels.shape[1] // 2 :].sum() > 200


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["--append"], "--append needs -o SPEC"),
        (["--plot", "/no/such/folder/p.png"], "does not exist"),
        (["-o", "/no/such/folder/s.toml"], "does not exist"),
    ],
)
def test_fit_usage_errors_exit_2(runner, photos, args, text):
    result = runner.invoke(main, ["library", "fit", next(iter(photos)), *args])
    assert result.exit_code == 2
    assert text in result.output


def test_fit_needs_an_input(runner):
    result = runner.invoke(main, ["library", "fit"])
    assert result.exit_code == 2
    assert "Missing argument" in result.output


# ---------------------------------------------------------------- family


@pytest.fixture
def paper_spec(tmp_path):
    path = tmp_path / "paper.toml"
    shapes = [ShapeSpec(name, p) for name, p in PAPER_SHAPES.items()]
    write_spec([*shapes, ShapeSpec("star", STAR5, interest=2.0)], path)
    return path


def test_family_writes_the_spec_and_its_variants(runner, paper_spec, tmp_path):
    out = tmp_path / "family.toml"
    result = runner.invoke(
        main, ["library", "family", str(paper_spec), "star", "--vary", "n1=0.8:1.2:5", "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert f"wrote {out}: 4 variants of star (8 shapes)" in result.stdout
    shapes = read_spec(out)
    assert [s.name for s in shapes[4:]] == ["star-n1-0-8", "star-n1-0-9", "star-n1-1-1", "star-n1-1-2"]
    assert [s.params.n1 for s in shapes[4:]] == pytest.approx([1.6, 1.8, 2.2, 2.4])
    assert all(s.interest == 2.0 for s in shapes[4:])
    assert len(Library.from_shapes(shapes)) == 8


def test_family_to_stdout_absolute_and_one_at_a_time(runner, paper_spec):
    result = runner.invoke(
        main,
        [
            "library",
            "family",
            str(paper_spec),
            "rounded-triangle",
            "--vary",
            "m=3,4",
            "--vary",
            "n=1500,1650",
            "--absolute",
            "--one-at-a-time",
            "--variants-only",
        ],
    )
    assert result.exit_code == 0, result.output
    shapes = tomllib.loads(result.stdout)["shape"]
    assert [s["name"] for s in shapes] == ["rounded-triangle-m-4", "rounded-triangle-n-1650"]
    assert (shapes[0]["m1"], shapes[0]["m2"], shapes[0]["n1"]) == (4.0, 4.0, 1500.0)
    assert (shapes[1]["n1"], shapes[1]["n2"], shapes[1]["n3"]) == (1650.0, 1650.0, 1650.0)


@pytest.mark.parametrize(
    ("vary", "text"),
    [
        ("n1=0.8:1.2", "is not NAME=START:STOP:COUNT"),
        ("n1=0.8:1.2:x", "COUNT must be a whole number"),
        ("z=1,2", "unknown parameter 'z'"),
        ("n1", "is not NAME=START:STOP:COUNT"),
    ],
)
def test_family_vary_syntax_is_a_usage_error(runner, paper_spec, vary, text):
    result = runner.invoke(main, ["library", "family", str(paper_spec), "star", "--vary", vary])
    assert result.exit_code == 2
    assert "Invalid value for --vary" in result.output and text in result.output
    assert "Traceback" not in result.output


def test_family_needs_vary(runner, paper_spec):
    result = runner.invoke(main, ["library", "family", str(paper_spec), "star"])
    assert result.exit_code == 2
    assert "Missing option '--vary'" in result.output


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["nope", "--vary", "n1=1.1"], "has no shape 'nope'; it has rounded-triangle"),
        (["star", "--vary", "n1=0:1:2"], "variant 'star-n1-0'"),
        (["star", "--vary", "n1=1"], "every variant equals the base shape"),
        (["star", "--vary", "n=1.1", "--vary", "n2=1.2"], "varied twice"),
    ],
)
def test_family_errors_are_one_line(runner, paper_spec, args, text):
    result = runner.invoke(main, ["library", "family", str(paper_spec), *args])
    assert result.exit_code == 1
    assert result.stderr.startswith("rockscan: error: ") and len(result.stderr.splitlines()) == 1
    assert text in result.stderr


def test_family_refuses_names_the_spec_already_has(runner, paper_spec, tmp_path):
    once = tmp_path / "once.toml"
    assert (
        runner.invoke(
            main, ["library", "family", str(paper_spec), "star", "--vary", "n1=1.1", "-o", str(once)]
        ).exit_code
        == 0
    )
    again = runner.invoke(main, ["library", "family", str(once), "star", "--vary", "n1=1.1"])
    assert again.exit_code == 1
    assert "already has shapes named star-n1-1-1" in again.stderr


def test_fit_warns_when_two_photos_give_one_shape(runner, photos, tmp_path):
    # Written without a word, the spec was then refused by library build.
    photo = next(iter(photos))
    result = runner.invoke(main, ["library", "fit", photo, photo, "-o", str(tmp_path / "s.toml")])
    assert result.exit_code == 0
    stem = sanitize_name(os.path.splitext(os.path.basename(photo))[0])
    assert f"{stem}-2 fits the same shape as {stem}; library build refuses the two together" in result.stderr
