"""``rockscan render``: photos and truth files, reproducible, in every format; errors."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from click.testing import CliRunner

from rockscan.cli import main
from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_spec_path, read_image, read_spec
from rockscan.run.pipeline import classify_path


def render(*args: str):
    return CliRunner().invoke(main, ["render", *args])


def test_one_photo_per_spec_shape_with_truth_beside_it(tmp_path, default_lib):
    out = tmp_path / "out"
    result = render("-o", str(out), "--size", "240x320", "--seed", "3")
    assert result.exit_code == 0, result.output
    specs = read_spec(default_spec_path())
    photos = sorted(out.glob("*.png"))
    assert [p.stem for p in photos] == [f"{i:04d}-{s.name}" for i, s in enumerate(specs)]
    truth = json.loads((out / f"{photos[1].stem}.json").read_text())
    assert truth["photo"] == photos[1].name and truth["seed"] == 3 and truth["index"] == 1
    assert truth["shape"] == specs[1].name and truth["params"] == specs[1].params.as_dict()
    for key in ("angle_deg", "scale_px", "center_xy", "centroid_xy", "rock_lighter", "symmetry"):
        assert key in truth
    settings = truth["render"]
    for key in ("rock_texture", "ground_texture", "gradient", "shadow", "noise", "blur", "jpeg_quality"):
        assert key in settings
    assert settings["outline_noise"] == 0.0 and (settings["rows"], settings["cols"]) == (240, 320)
    record = classify_path(photos[1], default_lib).rocks[0]
    assert record.match.nearest == truth["shape"]
    np.testing.assert_allclose(record.centroid_xy, truth["centroid_xy"], atol=1.0)


def test_photo_i_is_render_photo_with_seed_and_index(tmp_path):
    result = render("-o", str(tmp_path), "-n", "3", "--shape", "egg", "--seed", "11", "--size", "96x128")
    assert result.exit_code == 0, result.output
    egg = next(s for s in read_spec(default_spec_path()) if s.name == "egg")
    photo = render_photo(egg.params, RenderConfig(rows=96, cols=128), rng=[11, 2], name="egg")
    np.testing.assert_array_equal(read_image(tmp_path / "0002-egg.png").pixels, photo.pixels)
    truth = json.loads((tmp_path / "0002-egg.json").read_text())
    assert truth["angle_deg"] == photo.truth["angle_deg"]


def test_same_seed_same_bytes_other_seed_other_photos(tmp_path):
    for name, seed in (("a", "5"), ("b", "5"), ("c", "6")):
        assert render("-o", str(tmp_path / name), "-n", "2", "--seed", seed, "--size", "64x80").exit_code == 0
    a, b, c = (sorted((tmp_path / n).iterdir()) for n in "abc")
    assert [p.read_bytes() for p in a] == [p.read_bytes() for p in b]
    assert a[0].read_bytes() != c[0].read_bytes()


@pytest.mark.parametrize(
    ("args", "suffix", "shape", "dtype"),
    [
        (["--format", "tif", "--bits", "16"], ".tif", (64, 80, 3), np.uint16),
        (["--gray", "--bits", "16"], ".png", (64, 80), np.uint16),
        (["--gray", "--format", "bmp"], ".bmp", (64, 80), np.uint8),
        (["--jpeg", "80"], ".jpg", (64, 80, 3), np.uint8),
    ],
)
def test_formats_bits_and_gray(tmp_path, args, suffix, shape, dtype):
    result = render("-o", str(tmp_path), "-n", "1", "--size", "64x80", *args)
    assert result.exit_code == 0, result.output
    (photo,) = tmp_path.glob(f"*{suffix}")
    image = read_image(photo)
    assert image.pixels.shape == shape and image.pixels.dtype == dtype


def test_camera_and_outline_settings_reach_the_truth(tmp_path):
    args = ["--shadow", "0.5", "--pebbles", "7", "--gradient", "0.4", "--noise", "0.03", "--blur", "1.5"]
    args += ["--outline-noise", "0.05", "--polarity", "dark", "--angle", "33", "--area", "0.2"]
    result = render("-o", str(tmp_path), "-n", "1", "--size", "96x128", *args)
    assert result.exit_code == 0, result.output
    truth = json.loads(next(tmp_path.glob("*.json")).read_text())
    assert truth["angle_deg"] == 33.0 and truth["rock_lighter"] is False
    settings = truth["render"]
    assert (settings["shadow"], settings["pebbles"], settings["gradient"]) == (0.5, 7, 0.4)
    assert (settings["noise"], settings["blur"], settings["outline_noise"]) == (0.03, 1.5, 0.05)
    assert truth["area_fraction"] == pytest.approx(0.2, rel=0.05)


def test_scenes_list_every_rock(tmp_path, default_lib):
    result = render("-o", str(tmp_path), "-n", "1", "--rocks", "3", "--seed", "2", "--area", "0.15")
    assert result.exit_code == 0, result.output
    truth = json.loads((tmp_path / "0000-scene.json").read_text())
    assert len(truth["rocks"]) == 3
    found = classify_path(tmp_path / "0000-scene.png", default_lib, all_rocks=True).rocks
    assert len(found) == 3
    for rock in truth["rocks"]:
        match = min(found, key=lambda r: np.hypot(*np.subtract(r.centroid_xy, rock["centroid_xy"])))
        assert match.match.nearest == rock["shape"]


def test_custom_spec(tmp_path):
    spec = tmp_path / "mine.toml"
    spec.write_text('[[shape]]\nname = "hex"\nm1 = 6.0\nm2 = 6.0\nn1 = 8.0\nn2 = 8.0\nn3 = 8.0\n')
    result = render(str(spec), "-o", str(tmp_path / "out"), "-n", "2", "--size", "64x64")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "out").glob("*.png")) == ["0000-hex.png", "0001-hex.png"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--size", "big"], "must be ROWSxCOLS"),
        (["--shape", "no-such-shape"], "not in the spec: no-such-shape"),
        (["--area", "0.95"], "area_fraction must be between"),
        (["--bits", "16", "--jpeg", "90"], "JPEG photos are 8 bits"),
        (["--bits", "16", "--format", "bmp"], "BMP photos are 8 bits"),
        (["-n", "0"], "0 is not in the range x>=1"),
        (["--size", "8x8"], "at least 16"),
        (["--pebbles", "-2"], "not in the range x>=0"),
    ],
)
def test_usage_errors_exit_two(tmp_path, args, message):
    result = render("-o", str(tmp_path), *args)
    assert result.exit_code == 2
    assert message in result.stderr


def test_output_that_is_a_file_is_one_error_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    result = render("-o", str(blocker / "sub"), "-n", "1")
    assert result.exit_code == 1
    assert result.stderr.startswith("rockscan: error:") and result.stderr.count("\n") == 1


def test_missing_spec_is_one_error_line(tmp_path):
    result = render(str(tmp_path / "none.toml"), "-o", str(tmp_path))
    assert result.exit_code == 1
    assert result.stderr == f"rockscan: error: {tmp_path / 'none.toml'}: spec file not found\n"


# ---------------------------------------------------------------- earlier runs, progress


def test_a_folder_of_an_earlier_render_is_refused_or_replaced_whole(tmp_path):
    out = tmp_path / "out"
    assert render("-o", str(out), "-n", "4", "--seed", "5", "--size", "64x80").exit_code == 0
    (out / "notes.txt").write_text("mine")
    (out / "0009-not-a-render.json").write_text("{}")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    refused = render("-o", str(out), "-n", "2", "--seed", "99", "--size", "64x80")
    assert refused.exit_code == 2
    assert "holds 4 photos of an earlier render; give --overwrite" in refused.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    replaced = render("-o", str(out), "-n", "2", "--seed", "99", "--size", "64x80", "--overwrite")
    assert replaced.exit_code == 0, replaced.output
    # None of the earlier run is left; files that are not a render's stay.
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(
        [
            "0000-rounded-triangle.png",
            "0000-rounded-triangle.json",
            "0001-three-faced-blunt.png",
            "0001-three-faced-blunt.json",
            "notes.txt",
            "0009-not-a-render.json",
        ]
    )
    assert all(
        json.loads((out / n).read_text()).get("seed") == 99
        for n in names
        if n.startswith("000") and n.endswith(".json") and n[3] != "9"
    )
    assert "removed the 4 photos of an earlier render" in replaced.stderr
    assert replaced.stderr.endswith(f"rockscan: wrote 2 photos with truth (seed 99) to {out}\n")


@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]])
def test_a_users_own_file_under_a_name_the_render_writes_is_never_replaced(tmp_path, overwrite):
    # It was replaced without a word, exit 0: "--overwrite" is for an earlier render's files.
    out = tmp_path / "out"
    out.mkdir()
    (out / "0001-three-faced-blunt.png").write_bytes(b"my photo")
    (out / "0003-circle.json").write_text("my notes")
    result = render("-o", str(out), "-n", "4", "--size", "64x80", *overwrite)
    assert result.exit_code == 2
    assert "holds 0001-three-faced-blunt.png and 1 more, not of an earlier render" in result.stderr
    assert sorted(p.name for p in out.iterdir()) == ["0001-three-faced-blunt.png", "0003-circle.json"]
    assert (out / "0001-three-faced-blunt.png").read_bytes() == b"my photo"
    scenes = render("-o", str(out), "-n", "1", "--rocks", "3", "--size", "64x80")
    assert scenes.exit_code == 0, scenes.output


def test_a_file_system_that_refuses_writes_is_one_line(tmp_path, monkeypatch):
    # On a read-only mount the temporary file is never made, and removing it
    # fails too (EROFS): that second error escaped as a traceback.
    import errno
    import os as os_module
    from pathlib import Path as PathType

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    real_open = open

    def refusing_open(file, mode="r", *args, **kwargs):
        if "w" in mode and ".tmp" in os_module.fspath(file):
            read_only()
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr("builtins.open", refusing_open)
    monkeypatch.setattr(PathType, "unlink", read_only)
    result = render("-o", str(tmp_path / "out"), "-n", "1", "--size", "64x80")
    assert result.exit_code == 1
    assert result.stderr.strip().endswith("cannot write the photo (Read-only file system)")
    # Exited, not raised: an uncaught error is the runner's exception.
    assert isinstance(result.exception, SystemExit) and "Traceback" not in result.stderr


def test_a_rock_drawn_smaller_than_asked_is_said(tmp_path):
    # A star at 60% of the frame was drawn at 26%, without a word (its truth file had it).
    out = tmp_path / "big"
    result = render("-o", str(out), "--shape", "five-armed-star", "--area", "0.6", "--size", "120x160")
    assert result.exit_code == 0, result.output
    truth = json.loads((out / "0000-five-armed-star.json").read_text())
    assert truth["area_fraction"] < 0.5
    assert (
        f"1 of the rocks did not fit the frame at 60% of it and were drawn smaller "
        f"(0000-five-armed-star at {100 * truth['area_fraction']:.3g}%)" in result.stderr
    )
    fits = render("-o", str(tmp_path / "fits"), "--shape", "circle", "--area", "0.3", "--size", "120x160")
    assert fits.exit_code == 0 and "warning" not in fits.stderr


def test_off_a_terminal_a_long_render_logs_its_progress(tmp_path):
    result = render("-o", str(tmp_path / "a"), "-n", "20", "--size", "32x32", "--shape", "circle")
    assert result.exit_code == 0, result.output
    progress = [line for line in result.stderr.splitlines() if "rendered" in line]
    # Every tenth of the run (and every 10 s besides, on a slow machine).
    assert {f"rockscan: rendered {k}/20 photos" for k in range(2, 21, 2)} <= set(progress)
    assert all(re.fullmatch(r"rockscan: rendered \d+/20 photos", line) for line in progress)
    assert progress[-1] == "rockscan: rendered 20/20 photos"
    quiet = render("-o", str(tmp_path / "b"), "-n", "20", "--size", "32x32", "--shape", "circle", "-q")
    assert quiet.exit_code == 0 and quiet.stderr == "" and quiet.stdout == ""


def test_option_defaults_are_the_settings_dataclasses_defaults():
    from rockscan.core.information import FaceConfig

    runner = CliRunner()
    render_help = " ".join(runner.invoke(main, ["render", "--help"]).output.split())
    build_help = " ".join(runner.invoke(main, ["library", "build", "--help"]).output.split())
    config, face = RenderConfig(), FaceConfig()
    for option, value in [
        ("--size", f"{config.rows}x{config.cols}"),
        ("--contrast", config.contrast),
        ("--blur", config.blur),
        ("--bits", config.bit_depth),
    ]:
        assert re.search(
            rf"{option} \S+ (?:(?! --[a-z]).)*?\[default: {re.escape(str(value))}\]", render_help
        ), option
    for option, value in [("--sigma", face.sigma), ("--n-angles", face.n_angles), ("--grid", face.grid)]:
        # A bounded option's range follows its default: "[default: 360; 8<=x<=3600]".
        assert re.search(
            rf"{option} \S+ (?:(?! --[a-z]).)*?\[default: {re.escape(str(value))}[;\]]", build_help
        ), option


def test_a_render_without_options_uses_the_render_settings_defaults(tmp_path):
    runner = CliRunner()
    result = runner.invoke(main, ["render", "-o", str(tmp_path), "-n", "1"])
    assert result.exit_code == 0, result.output
    (truth_path,) = tmp_path.glob("*.json")
    settings = json.loads(truth_path.read_text())["render"]
    config = RenderConfig()
    assert (settings["rows"], settings["cols"], settings["contrast"]) == (
        config.rows,
        config.cols,
        config.contrast,
    )
