"""``rockscan classify`` (and ``rockscan match``): the public JSON contract, errors, exit codes.

Every input kind and every bad input is checked twice: through click's
CliRunner and through :func:`rockscan.run.pipeline.classify_path`.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image
from test_imageio import BAD_FILES, make_bad_file

from rockscan.cli import main
from rockscan.core.library import ShapeSpec
from rockscan.core.render import RenderConfig, render_photo, render_scene
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import write_spec
from rockscan.io.photos import write_photo
from rockscan.run.pipeline import classify_image, classify_path

SHAPES = {
    "three-faced-blunt": SuperformulaParams(6, 6, 60, 55, 10),
    "teardrop": SuperformulaParams(1, 1, 0.5, 0.5, 0.5),
    "six-pointed-star": SuperformulaParams(6, 6, 0.2, 1.7, 1.7),
    "rounded-square": SuperformulaParams(4, 4, 4, 4, 4),
}
#: The interface's keys and their JSON types.
KEYS = {
    "path": str,
    "match": (str, type(None)),
    "nearest": str,
    "mscore": float,
    "distance": float,
    "angle_deg": float,
    "interesting": bool,
    "centroid": list,
}


def run(*args: str, **kwargs):
    return CliRunner().invoke(main, ["classify", *args], **kwargs)


def lines(output: str) -> list[dict]:
    return [json.loads(line) for line in output.splitlines()]


def angle_error(a: float, b: float, symmetry: int) -> float:
    period = 360.0 / symmetry if symmetry > 0 else 360.0
    return abs((a - b + period / 2) % period - period / 2)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """One photo per shape (240x320, PNG) and its truth."""
    folder = tmp_path_factory.mktemp("photos")
    out = {}
    for i, (name, params) in enumerate(SHAPES.items()):
        photo = render_photo(params, RenderConfig(rows=240, cols=320, area_fraction=0.15), rng=i, name=name)
        path = folder / f"{name}.png"
        write_photo(photo, path)
        out[name] = (str(path), photo.truth)
    return out


# ---------------------------------------------------------------- the JSON contract


def test_json_is_one_object_per_photo_in_input_order(rendered, tmp_path):
    paths = [rendered["teardrop"][0], str(tmp_path / "missing.png"), rendered["six-pointed-star"][0]]
    paths.append(rendered["teardrop"][0])
    result = run("--json", *paths)
    assert result.exit_code == 1
    records = lines(result.stdout)
    assert [r["path"] for r in records] == paths
    assert records[1] == {"path": paths[1], "error": f"{paths[1]}: file not found"}
    for record in (records[0], records[2], records[3]):
        for key, kind in KEYS.items():
            assert isinstance(record[key], kind), key
        assert len(record["centroid"]) == 2 and all(isinstance(v, float) for v in record["centroid"])
    assert records[0] == records[3]
    assert [records[0]["nearest"], records[2]["nearest"]] == ["teardrop", "six-pointed-star"]


def test_a_bug_on_one_photo_is_its_error_line_and_the_others_go_on(rendered, monkeypatch):
    # A broken build stopped the whole batch with a traceback at its first photo.
    import rockscan.run.pipeline as pipeline

    real = pipeline.classify_path
    teardrop, star = rendered["teardrop"][0], rendered["six-pointed-star"][0]

    def flaky(path, *args, **kwargs):
        if path == teardrop:
            raise AttributeError("an unexpected bug\nwith a second line")
        return real(path, *args, **kwargs)

    monkeypatch.setattr(pipeline, "classify_path", flaky)
    result = run("--json", teardrop, star)
    assert result.exit_code == 1
    first, second = lines(result.stdout)
    assert first == {
        "path": teardrop,
        "error": "internal error, please report it: AttributeError: an unexpected bug",
    }
    assert second["nearest"] == "six-pointed-star"
    assert (
        result.stderr
        == f"rockscan: error: {teardrop}: internal error, please report it: AttributeError: an unexpected bug\n"
    )


def test_json_values_are_the_truth_of_rendered_photos(rendered):
    result = run("--json", *(path for path, _ in rendered.values()))
    assert result.exit_code == 0, result.output
    for record, (name, (path, truth)) in zip(lines(result.stdout), rendered.items(), strict=True):
        assert record["path"] == path
        assert record["nearest"] == record["match"] == name
        assert record["interesting"] is True
        assert 0.5 < record["mscore"] <= 1.0 and record["distance"] >= 0
        np.testing.assert_allclose(record["centroid"], truth["centroid_xy"], atol=1.0)
        assert angle_error(record["angle_deg"], truth["angle_deg"], truth["symmetry"]) < 1.5
        assert 0.0 <= record["angle_deg"] < 360.0


def test_table_is_the_default(rendered, tmp_path):
    paths = [rendered["rounded-square"][0], str(tmp_path)]
    result = run(*paths, env={"COLUMNS": "120"})
    assert result.exit_code == 1
    header, good, bad = result.stdout.splitlines()
    assert header.split()[:4] == ["photo", "rock", "match", "nearest"]
    assert good.split()[1:4] == ["0", "rounded-square", "rounded-square"]
    assert bad.endswith(f"error: {tmp_path}: is a folder, not a photo")
    # The error also on standard error, where it shows when the table goes to a file.
    assert result.stderr == f"rockscan: error: {tmp_path}: is a folder, not a photo\n"


def test_all_good_exits_zero_and_table_matches_json(rendered):
    path = rendered["three-faced-blunt"][0]
    table, as_json = run(path, env={"COLUMNS": "120"}), run("--json", path)
    assert table.exit_code == as_json.exit_code == 0
    record = lines(as_json.stdout)[0]
    row = table.stdout.splitlines()[1].split()
    assert row[2:5] == [record["match"], record["nearest"], f"{record['mscore']:.3f}"]


def test_an_error_names_the_photo_as_it_was_given(tmp_path, monkeypatch):
    # Path() dropped the "./": the error named "missing.png" beside "path": "./missing.png",
    # and standard error named the photo twice.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.png").write_bytes(b"not a photo")
    given = ["./missing.png", ".//bad.png", f"{tmp_path}/../{tmp_path.name}/missing.png"]
    result = run("--json", *given)
    assert result.exit_code == 1
    for record, path in zip(lines(result.stdout), given, strict=True):
        assert record["path"] == path and record["error"].startswith(f"{path}: ")
    assert result.stderr.splitlines() == [f"rockscan: error: {r['error']}" for r in lines(result.stdout)]


def test_json_errors_also_go_to_stderr(rendered, tmp_path):
    missing = str(tmp_path / "missing.png")
    result = run("--json", rendered["teardrop"][0], missing)
    assert result.exit_code == 1
    assert lines(result.stdout)[1] == {"path": missing, "error": f"{missing}: file not found"}
    assert result.stderr == f"rockscan: error: {missing}: file not found\n"


# ---------------------------------------------------------------- the table


@pytest.mark.parametrize("columns", [80, 120, 200])
def test_table_fits_the_terminal_and_cuts_long_paths_in_the_middle(rendered, tmp_path, columns):
    deep = tmp_path / ("a-very-long-folder-name-" * 4) / "deeper"
    deep.mkdir(parents=True)
    long_path = deep / "the-star-photo.png"
    long_path.write_bytes(Path(rendered["six-pointed-star"][0]).read_bytes())
    spec = tmp_path / "long.toml"
    long_name = "six-pointed-star-with-a-name-too-long-for-any-table"
    write_spec(
        [ShapeSpec(long_name, SHAPES["six-pointed-star"]), ShapeSpec("blunt", SHAPES["three-faced-blunt"])],
        spec,
    )
    result = run(
        "--library",
        str(spec),
        str(long_path),
        rendered["three-faced-blunt"][0],
        env={"COLUMNS": str(columns)},
    )
    assert result.exit_code == 0, result.output
    header, star, blunt = result.stdout.splitlines()
    assert max(len(line) for line in (header, star, blunt)) <= columns
    # Every column starts (names) or ends (numbers) where its header does:
    # long names and paths push nothing out of line.
    for row in (star, blunt):
        for word in ("match", "nearest"):
            at = header.index(word)
            assert row[at - 1] == " " and row[at] != " ", (word, row)
        for word in ("rock", "MScore", "distance", "angle"):
            end = header.index(word) + len(word)
            assert row[end - 1] != " " and (end == len(row) or row[end] == " "), (word, row)
    # The centroid column (also in --json) gives way first: it shows where everything fits.
    assert ("centroid" in header) == (columns >= 200)
    cell = star.split()[0]
    if len(str(long_path)) > len(cell):
        head, tail = cell.split("...")
        assert str(long_path).startswith(head) and str(long_path).endswith(tail) and tail.endswith(".png")
        assert abs(len(head) - len(tail)) <= 1
    else:
        assert cell == str(long_path)
    names = star[header.index("match") : header.index("MScore")].split()
    assert len(names) == 2 and names[0] == names[1]
    assert long_name.startswith(names[0].split("...")[0]) and long_name.endswith(names[0].split("...")[-1])


def test_cut_middle_keeps_both_ends():
    from rockscan.cli._classify import _cut_middle

    assert _cut_middle("short", 10) == "short"
    assert _cut_middle("abcdefghijklmnopqrstuvwxyz", 10) == "abc...wxyz"
    assert all(len(_cut_middle("x" * 50, w)) == w for w in range(1, 50))


# ---------------------------------------------------------------- paths on standard input


def test_dash_reads_photo_paths_from_standard_input(rendered):
    star, blunt, drop = (rendered[n][0] for n in ("six-pointed-star", "three-faced-blunt", "teardrop"))
    result = run("--json", "-", input=f"{star}\n\n   \n{blunt}\r\n")
    assert result.exit_code == 0, result.output
    assert [r["path"] for r in lines(result.stdout)] == [star, blunt]
    # Mixed with paths: the piped ones stand where the '-' stands.
    result = run("--json", drop, "-", drop, input=f"{star}\n")
    assert [r["path"] for r in lines(result.stdout)] == [drop, star, drop]


@pytest.mark.parametrize(
    ("args", "stdin", "message"),
    [
        (["-", "-"], "x.png\n", "may be given once"),
        (["-"], "\n  \n", "standard input holds no photo paths"),
    ],
)
def test_dash_misuse_is_a_usage_error(args, stdin, message):
    result = run(*args, input=stdin)
    assert result.exit_code == 2 and message in result.stderr


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".bmp", ".tif"])
def test_dash_refuses_a_photo_piped_in_for_its_paths(rendered, suffix):
    pixels = np.asarray(Image.open(rendered["teardrop"][0]).convert("RGB"))[:, :-1]
    buffer = io.BytesIO()
    # An odd width: each BMP row ends in NUL padding, and so does the file.
    Image.fromarray(np.ascontiguousarray(pixels)).save(buffer, format=Image.registered_extensions()[suffix])
    result = run("-", input=buffer.getvalue())
    assert result.exit_code == 2 and "holds binary data" in result.stderr


def test_dash_reads_nul_ended_names_with_newlines_whole(rendered, tmp_path):
    # find -print0 exists for such names; one of them refused the whole batch as binary data.
    star = rendered["six-pointed-star"][0]
    odd = [
        str(tmp_path / "two\nlines.png"),
        str(tmp_path / "ends in return\r.png"),
        str(tmp_path / "BMW 1.png"),
    ]
    for name in odd:
        shutil.copyfile(star, name)
    result = run("--json", "-", input="".join(f"{n}\0" for n in [star, *odd]).encode())
    assert result.exit_code == 0, result.output
    rows = lines(result.stdout)
    assert [r["path"] for r in rows] == [star, *odd]
    assert len({r["match"] for r in rows}) == 1
    # One a line, "BMW 1.png" is a path too.
    result = run("--json", "-", input=f"{odd[2]}\n")
    assert result.exit_code == 0 and [r["path"] for r in lines(result.stdout)] == [odd[2]]


def test_dash_reads_paths_ended_by_nul_and_after_a_byte_order_mark(rendered):
    star, blunt = (rendered[n][0] for n in ("six-pointed-star", "three-faced-blunt"))
    # find -print0 was refused as "binary data (a photo itself?)"; Notepad's BOM was part of a path.
    result = run("--json", "-", input=f"{star}\0{blunt}\0".encode())
    assert result.exit_code == 0, result.output
    assert [r["path"] for r in lines(result.stdout)] == [star, blunt]
    result = run("--json", "-", input=b"\xef\xbb\xbf" + f"{star}\n".encode())
    assert result.exit_code == 0 and [r["path"] for r in lines(result.stdout)] == [star]


def _non_utf8_copy(source: str, folder: Path) -> bytes:
    """A copy of ``source`` under a name whose bytes are not UTF-8 (Latin-1 'roché.png')."""
    name = os.path.join(os.fsencode(folder), b"roch\xe9.png")
    try:
        with open(name, "wb") as fh:
            fh.write(Path(source).read_bytes())
    except (OSError, UnicodeError):
        pytest.skip("this file system takes only UTF-8 names")
    return name


def test_a_name_not_in_the_locales_encoding_is_classified_and_printed_escaped(rendered, tmp_path):
    # A strict UTF-8 terminal, as under a UTF-8 locale; the name arrives as an
    # argument and on standard input, and its bytes still name the file.
    name = _non_utf8_copy(rendered["teardrop"][0], tmp_path)
    env = {**os.environ, "PYTHONIOENCODING": "utf-8:strict"}
    command = [os.fsencode(sys.executable), b"-m", b"rockscan", b"classify"]
    outs = []
    for args, stdin in (([name], b""), ([b"--json", b"-"], name + b"\n")):
        done = subprocess.run(command + args, input=stdin, capture_output=True, env=env, check=False)
        assert done.returncode == 0, done.stderr.decode(errors="replace")
        assert b"Traceback" not in done.stderr
        outs.append(done.stdout.decode("utf-8"))
    table, json_lines = outs
    assert "teardrop" in table and "\\udce9.png" in table
    (record,) = lines(json_lines)
    # JSON escapes the byte as the file system decoded it: the name reads back whole.
    assert record["nearest"] == "teardrop" and os.fsencode(record["path"]) == name


# ---------------------------------------------------------------- sizes


def test_px_per_mm_adds_sizes_in_millimetres(rendered):
    path = rendered["teardrop"][0]
    plain = lines(run("--json", path).stdout)[0]
    assert not {"area_mm2", "equivalent_diameter_mm", "major_axis_mm", "minor_axis_mm"} & set(plain)
    result = run("--json", "--px-per-mm", "2.5", path)
    assert result.exit_code == 0, result.output
    record = lines(result.stdout)[0]
    assert record["area_mm2"] == pytest.approx(plain["area_px"] / 2.5**2, rel=1e-4)
    assert record["major_axis_mm"] >= record["minor_axis_mm"] > 0
    assert record["equivalent_diameter_mm"] == pytest.approx(
        np.sqrt(4 * record["area_mm2"] / np.pi), rel=1e-3
    )
    assert {k: v for k, v in record.items() if not k.endswith("_mm") and k != "area_mm2"} == plain


@pytest.mark.parametrize("px_per_mm", [1e-6, 1e-3, 1e4, 1e5, 1e6])
def test_sizes_keep_their_digits_over_the_whole_px_per_mm_range(rendered, px_per_mm):
    # Rounded to 4 decimals, a rock of 9,000 px had area_mm2 0.0 from 1e5 px/mm up,
    # and equal major and minor axes.
    path = rendered["teardrop"][0]
    plain = lines(run("--json", path).stdout)[0]
    record = lines(run("--json", "--px-per-mm", repr(px_per_mm), path).stdout)[0]
    assert record["area_mm2"] == pytest.approx(plain["area_px"] / px_per_mm**2, rel=1e-4)
    assert record["major_axis_mm"] > 1.05 * record["minor_axis_mm"] > 0
    coarse = lines(run("--json", "--px-per-mm", "1", path).stdout)[0]
    for key in ("major_axis_mm", "minor_axis_mm", "equivalent_diameter_mm"):
        assert record[key] == pytest.approx(coarse[key] / px_per_mm, rel=1e-5)


@pytest.mark.parametrize("value", ["0", "-1", "many"])
def test_px_per_mm_must_be_positive(rendered, value):
    result = run("--px-per-mm", value, rendered["teardrop"][0])
    assert result.exit_code == 2 and "--px-per-mm" in result.stderr


# ---------------------------------------------------------------- --all


@pytest.mark.parametrize("seed", [0, 1])
def test_all_classifies_every_rock_of_a_scene(tmp_path, seed):
    rng = np.random.default_rng(seed)
    names = [str(n) for n in rng.choice(sorted(SHAPES), size=3 + seed)]
    scene = render_scene(
        [SHAPES[n] for n in names], RenderConfig(area_fraction=0.05 * len(names)), rng=rng, names=names
    )
    path = tmp_path / "scene.png"
    write_photo(scene, path)
    result = run("--json", "--all", str(path))
    assert result.exit_code == 0, result.output
    records = lines(result.stdout)
    assert [r["index"] for r in records] == list(range(len(names)))
    assert all(r["path"] == str(path) for r in records)
    for truth in scene.truth["rocks"]:
        distance = [np.hypot(*np.subtract(r["centroid"], truth["centroid_xy"])) for r in records]
        found = records[int(np.argmin(distance))]
        assert min(distance) < 1.0
        assert found["nearest"] == truth["shape"]
        assert angle_error(found["angle_deg"], truth["angle_deg"], truth["symmetry"]) < 1.5
    # Without --all, one rock, and one of those.
    single = lines(run("--json", str(path)).stdout)
    assert len(single) == 1 and single[0]["index"] == 0
    assert min(np.hypot(*np.subtract(single[0]["centroid"], r["centroid"])) for r in records) < 1.0


# ---------------------------------------------------------------- bad inputs


def make_bad(folder: Path, kind: str, monkeypatch: pytest.MonkeyPatch) -> tuple[Path, str]:
    """A bad input of some kind and the start of its error message."""
    if kind in BAD_FILES:
        return make_bad_file(folder, kind), BAD_FILES[kind][1]
    if kind == "one-colour":
        path = folder / "grey.png"
        Image.fromarray(np.full((120, 160, 3), 128, np.uint8)).save(path)
        return path, "no rock found"
    if kind == "no-rock":
        path = folder / "ground.jpg"
        write_photo(render_scene([], RenderConfig(rows=240, cols=320, ground_texture=0.0), rng=2), path)
        return path, "no rock found"
    assert kind == "unreadable"
    path = folder / "locked.png"
    Image.fromarray(np.zeros((16, 16), np.uint8)).save(path)
    real_open = open

    def guarded(file, *args, **kwargs):
        if os.fspath(file) == str(path):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr("builtins.open", guarded)
    return path, "permission denied"


BAD_KINDS = [*sorted(BAD_FILES), "one-colour", "no-rock", "unreadable"]


@pytest.mark.parametrize("kind", BAD_KINDS)
def test_bad_input_gives_an_error_line_and_the_others_go_on(tmp_path, rendered, monkeypatch, kind):
    bad, message = make_bad(tmp_path, kind, monkeypatch)
    good = rendered["teardrop"][0]
    result = run("--json", good, str(bad), good)
    assert result.exit_code == 1
    assert not isinstance(result.exception, Exception) or isinstance(result.exception, SystemExit)
    first, error, last = lines(result.stdout)
    assert set(error) == {"path", "error"} and error["path"] == str(bad)
    assert message in error["error"] and "\n" not in error["error"]
    assert first["nearest"] == last["nearest"] == "teardrop"
    assert "Traceback" not in result.output
    table = run(str(bad))
    assert table.exit_code == 1 and f"error: {error['error']}" in table.stdout


@pytest.mark.parametrize("kind", BAD_KINDS)
def test_bad_input_is_an_error_result_of_classify_path(tmp_path, default_lib, monkeypatch, kind):
    bad, message = make_bad(tmp_path, kind, monkeypatch)
    result = classify_path(bad, default_lib)
    assert not result.ok and result.rocks == ()
    assert message in result.error
    assert result.records() == [{"path": str(bad), "error": result.error}]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "Missing argument"),
        (["--mscore-cutoff", "high", "x.png"], "is not a valid float"),
        (["--metric", "euclid", "x.png"], "'euclid' is not one of"),
        (["--no-such-option", "x.png"], "No such option"),
        (["--plot", "no-such-folder/plot.png", "x.png"], "does not exist"),
    ],
)
def test_usage_errors_exit_two(args, message):
    result = run(*args)
    assert result.exit_code == 2
    assert message in result.stderr


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [("nothing.npz", None, "library file not found"), ("bad.toml", "not a spec", "not valid TOML")],
)
def test_a_library_that_cannot_be_loaded_is_a_usage_error(rendered, tmp_path, name, content, message):
    # It exited 1, a photo's failure, with no line for any photo.
    library = tmp_path / name
    if content is not None:
        library.write_text(content)
    result = run("--json", "--library", str(library), rendered["teardrop"][0])
    assert result.exit_code == 2 and result.stdout == ""
    assert f"Invalid value for '--library' / '-l': {library}: {message}" in result.stderr
    assert "Traceback" not in result.stderr


def test_library_spec_limits_the_answers(rendered, tmp_path):
    spec = tmp_path / "four.toml"
    names = {"blunt": "three-faced-blunt", "star": "six-pointed-star", "square": "rounded-square"}
    shapes = [ShapeSpec(short, SHAPES[name]) for short, name in names.items()]
    write_spec([*shapes, ShapeSpec("disc", SuperformulaParams(0, 0, 1, 1, 1))], spec)
    result = run("--json", "--library", str(spec), rendered["three-faced-blunt"][0])
    assert result.exit_code == 0
    assert lines(result.stdout)[0]["nearest"] == "blunt"


# ---------------------------------------------------------------- --plot


def test_plot_writes_one_file_per_photo(rendered, tmp_path):
    one = tmp_path / "one.png"
    result = run("--plot", str(one), rendered["teardrop"][0])
    assert result.exit_code == 0 and one.stat().st_size > 10_000
    other = tmp_path / "copy"
    other.mkdir()
    twin = other / "teardrop.png"
    twin.write_bytes(Path(rendered["teardrop"][0]).read_bytes())
    # Several photos: the photo's name is added, and its position when two share a name;
    # a photo that fails gets no plot.
    paths = [rendered["teardrop"][0], str(twin), str(tmp_path / "gone.png")]
    result = run("--plot", str(tmp_path / "many.png"), *paths)
    assert result.exit_code == 1
    written = sorted(p.name for p in tmp_path.glob("many-*.png"))
    assert written == ["many-teardrop-0.png", "many-teardrop-1.png"]
    # Another run into the same names: refused, or with --overwrite replaced, and
    # plots of the earlier run that this one does not replace are named.
    paths = [rendered["teardrop"][0], rendered["six-pointed-star"][0]]
    refused = run("--plot", str(tmp_path / "many.png"), *[str(twin), *paths])
    assert refused.exit_code == 2 and "many-teardrop-0.png and 1 more exists" in refused.stderr
    result = run("--plot", str(tmp_path / "many.png"), *paths)
    assert result.exit_code == 0
    assert (
        "rockscan: warning: 2 other plots named" in result.stderr and "many-teardrop-0.png" in result.stderr
    )


def test_plot_says_what_it_wrote_and_refuses_to_replace_without_overwrite(rendered, tmp_path):
    target = tmp_path / "plot.png"
    result = run("--plot", str(target), rendered["teardrop"][0])
    assert result.exit_code == 0 and result.stderr == f"rockscan: drew {target}\n"
    first = target.read_bytes()
    again = run(
        "--plot", str(target), rendered["egg"][0] if "egg" in rendered else rendered["six-pointed-star"][0]
    )
    assert again.exit_code == 2 and "exists; give --overwrite" in again.stderr
    assert target.read_bytes() == first
    replaced = run("--plot", str(target), "--overwrite", rendered["six-pointed-star"][0])
    assert replaced.exit_code == 0 and f"drew {target}" in replaced.stderr
    assert target.read_bytes() != first
    quiet = run("-q", "--plot", str(target), "--overwrite", rendered["teardrop"][0])
    assert quiet.exit_code == 0 and quiet.stderr == ""


def test_plot_that_cannot_be_written_is_an_error_but_json_goes_on(rendered, tmp_path, monkeypatch):
    # A disk that fills while drawing: a name of a format matplotlib cannot draw is
    # refused before the work (tests/test_cli_outputs.py).
    from rockscan.core.errors import WriteError

    def full(figure, path, **kwargs):
        raise WriteError(f"{path}: cannot write the plot (No space left on device)")

    monkeypatch.setattr("rockscan.draw.plot.save_figure", full)
    target = tmp_path / "plot.png"
    result = run("--json", "--plot", str(target), rendered["teardrop"][0])
    assert result.exit_code == 1
    assert lines(result.stdout)[0]["nearest"] == "teardrop"
    assert result.stderr.startswith("rockscan: error:") and "cannot write the plot" in result.stderr


# ---------------------------------------------------------------- every input kind


def _variants(folder: Path, pixels: np.ndarray) -> dict[str, Path]:
    """The same photo in every format, mode and bit depth the interface names."""
    gray = np.asarray(Image.fromarray(pixels).convert("L"))
    opaque = np.dstack([pixels, np.full(pixels.shape[:2], 255, np.uint8)])
    out = {}
    for mode, arr in (("rgb", pixels), ("gray", gray), ("rgba", opaque)):
        for suffix in (".png", ".tif", ".bmp", ".jpg"):
            if suffix == ".jpg" and mode == "rgba":
                continue
            path = folder / f"{mode}-8{suffix}"
            if suffix == ".bmp" and mode == "rgba":
                cv2.imwrite(str(path), arr[..., [2, 1, 0, 3]])
            else:
                Image.fromarray(arr).save(path, **({"quality": 95} if suffix == ".jpg" else {}))
            out[path.stem + suffix] = path
        for suffix in (".png", ".tif"):
            path = folder / f"{mode}-16{suffix}"
            deep = arr.astype(np.uint16) * 257
            if deep.ndim == 3:
                order = [2, 1, 0] if deep.shape[2] == 3 else [2, 1, 0, 3]
                cv2.imwrite(str(path), deep[..., order])
            else:
                Image.fromarray(deep).save(path)
            out[path.stem + suffix] = path
    return out


def test_every_input_kind_gives_the_same_classification(tmp_path, default_lib):
    """PNG, TIFF, BMP, JPEG; gray, RGB, RGBA; 8 and 16 bits: same match, angle within
    1 degree and centroid within 1 pixel, through the CLI and classify_path alike."""
    photo = render_photo(
        SHAPES["teardrop"], RenderConfig(rows=240, cols=320, area_fraction=0.15, angle_deg=70.0), rng=5
    )
    variants = _variants(tmp_path, photo.pixels)
    assert len(variants) == 17
    reference = classify_path(variants["rgb-8.png"], default_lib).rocks[0]
    assert reference.match.nearest == "teardrop"
    result = run("--json", *(str(p) for p in variants.values()))
    assert result.exit_code == 0, result.output
    records = lines(result.stdout)
    for (name, path), record in zip(variants.items(), records, strict=True):
        direct = classify_path(path, default_lib)
        assert direct.ok, (name, direct.error)
        assert record == direct.records()[0], name
        assert record["nearest"] == "teardrop", name
        assert angle_error(record["angle_deg"], reference.match.angle_deg, 1) < 1.0, name
        np.testing.assert_allclose(record["centroid"], reference.centroid_xy, atol=1.0, err_msg=name)


def test_alpha_that_cuts_the_rock_out_is_the_outline(tmp_path, default_lib):
    photo = render_photo(
        SHAPES["six-pointed-star"],
        RenderConfig(rows=240, cols=320, area_fraction=0.2, angle_deg=12.0, noise=0.0, blur=0.0),
        rng=3,
    )
    gray = np.asarray(Image.fromarray(photo.pixels).convert("L")).astype(float)
    inside = np.abs(gray - np.median(gray)) > 0.5 * np.abs(gray - np.median(gray)).max()
    # The photo's colours say nothing (flat grey); only the alpha channel shows the rock.
    rgba = np.dstack([np.full((*gray.shape, 3), 90, np.uint8), np.where(inside, 255, 0).astype(np.uint8)])
    path = tmp_path / "cutout.png"
    Image.fromarray(rgba).save(path)
    rock = classify_path(path, default_lib).rocks[0]
    assert rock.match.nearest == "six-pointed-star"
    np.testing.assert_allclose(rock.centroid_xy, photo.truth["centroid_xy"], atol=1.0)


# ---------------------------------------------------------------- rotation and scale


@settings(max_examples=8)
@given(
    index=st.integers(0, 12),
    angle=st.floats(0.0, 360.0, exclude_max=True),
    area=st.floats(0.02, 0.6),
)
def test_rotation_and_scale_of_the_rock_are_found(default_lib, default_specs, index, angle, area):
    """Any turn and any size the interface allows: the right shape, and the angle
    within 1.5 degrees modulo the shape's symmetry."""
    spec = [s for s in default_specs if s.name != "circle"][index]
    config = RenderConfig(angle_deg=angle, area_fraction=area)
    photo = render_photo(spec.params, config, rng=index, name=spec.name)
    rock = classify_image(photo.pixels, default_lib)[0]
    assert rock.match.nearest == spec.name
    assert angle_error(rock.match.angle_deg, angle, photo.truth["symmetry"]) < 1.5
    np.testing.assert_allclose(rock.centroid_xy, photo.truth["centroid_xy"], atol=1.0)


CLASSIFY, MATCH = ["classify", "x.png"], ["match", "--params", "6,6,60,55,10"]
TRIAGE, BUILD = ["triage", "."], ["library", "build", "spec.toml"]
NOT_FINITE, OUT_OF_RANGE = "is not a finite number", "is not in the range"


@pytest.mark.parametrize(
    ("command", "option", "value", "message"),
    [
        *[(CLASSIFY, "--px-per-mm", v, NOT_FINITE) for v in ("nan", "inf", "-inf")],
        (CLASSIFY, "--px-per-mm", "0", OUT_OF_RANGE),
        # An area of inf mm2 stopped a JSON report with a traceback.
        (CLASSIFY, "--px-per-mm", "1e-300", OUT_OF_RANGE),
        (CLASSIFY, "--px-per-mm", "1e300", OUT_OF_RANGE),
        *[
            (CLASSIFY, o, "nan", NOT_FINITE)
            for o in ("--distance-cutoff", "--mscore-cutoff", "--residual-cutoff")
        ],
        *[(MATCH, "--rotate", v, NOT_FINITE) for v in ("nan", "inf")],
        (MATCH, "--distance-cutoff", "nan", NOT_FINITE),
        *[
            (TRIAGE, o, v, NOT_FINITE)
            for o in ("--novelty-threshold", "--novelty-weight")
            for v in ("nan", "inf")
        ],
        *[(TRIAGE, o, "-1", OUT_OF_RANGE) for o in ("--novelty-threshold", "--novelty-weight")],
        *[
            (BUILD, o, v, NOT_FINITE)
            for o in ("--sigma", "--resolution", "--tolerance")
            for v in ("nan", "inf")
        ],
        *[(BUILD, o, v, OUT_OF_RANGE) for o in ("--sigma", "--resolution") for v in ("0", "-1")],
        *[(BUILD, "--tolerance", v, OUT_OF_RANGE) for v in ("-0.1", "1.5")],
    ],
)
def test_a_number_option_out_of_its_range_is_a_usage_error(command, option, value, message):
    # nan passes click's FloatRange (every comparison with it is false); a
    # setting refused only when the command runs was a traceback or exit 1.
    result = CliRunner().invoke(main, [*command, option, value])
    assert result.exit_code == 2, result.output
    assert f"'{option}'" in result.stderr and message in result.stderr
    assert "Traceback" not in result.output


@pytest.mark.parametrize("option", ["--distance-cutoff", "--mscore-cutoff", "--residual-cutoff"])
def test_an_infinite_cutoff_turns_its_test_off(rendered, option):
    # The cutoffs stay open to inf (a test the sample always passes) and to any
    # finite value; nan alone is refused.
    path = rendered["teardrop"][0]
    value = "-inf" if option == "--mscore-cutoff" else "inf"
    result = run("--json", option, value, path)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["nearest"] == "teardrop"


# ---------------------------------------------------------------- rockscan match


def test_match_finds_shape_and_rotation_without_a_photo():
    result = CliRunner().invoke(main, ["match", "--params", "6,6,60,55,10", "--rotate", "25", "--json"])
    assert result.exit_code == 0, result.output
    record = json.loads(result.stdout)
    assert record["nearest"] == "three-faced-blunt" and record["interesting"] is True
    assert angle_error(record["angle_deg"], 25.0, 3) < 0.5


@pytest.mark.parametrize(
    "args",
    [["match"], ["match", "--params", "1,2,3"], ["match", "--params", "6,6,60,55,10", "--radii", "r.txt"]],
)
def test_match_usage_errors_exit_two(args):
    assert CliRunner().invoke(main, args).exit_code == 2


# ---------------------------------------------------------------- the command line as a whole


def test_python_dash_m_rockscan_is_rockscan(rendered):
    path = rendered["teardrop"][0]
    done = subprocess.run(
        [sys.executable, "-m", "rockscan", "classify", "--json", path],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    direct, here = json.loads(done.stdout), lines(run("--json", path).stdout)[0]
    assert set(direct) == set(here) and direct["nearest"] == here["nearest"] == "teardrop"
    assert direct["mscore"] == pytest.approx(here["mscore"], rel=1e-9)
    usage = subprocess.run(
        [sys.executable, "-m", "rockscan", "nope"], capture_output=True, text=True, check=False
    )
    assert usage.returncode == 2 and "Usage: rockscan" in usage.stderr


def _commands(group, prefix=()):
    for name, command in group.commands.items():
        yield (*prefix, name), command
        if hasattr(command, "commands"):
            yield from _commands(command, (*prefix, name))


def test_every_command_takes_quiet_and_verbose():
    for path, command in _commands(main):
        opts = {opt for p in command.params for opt in getattr(p, "opts", [])}
        assert {"-q", "-v"} <= opts, path


def test_verbose_logs_debug_lines_and_quiet_silences_info(rendered, tmp_path):
    path = rendered["teardrop"][0]
    verbose = run("-v", path)
    assert verbose.exit_code == 0 and "rockscan: debug: rockscan.run.pipeline:" in verbose.stderr
    assert f"{path}: 1 rock(s)" in verbose.stderr
    assert run(path).stderr == ""
    # Before the command, for the whole run.
    plot = tmp_path / "p.png"
    before = CliRunner().invoke(main, ["-q", "classify", "--plot", str(plot), path])
    assert before.exit_code == 0 and before.stderr == "" and plot.is_file()


def test_a_file_name_with_a_newline_or_a_tab_keeps_the_table_in_line(rendered, tmp_path):
    source = Path(rendered["teardrop"][0]).read_bytes()
    names = ["two\nlines.png", "a\ttab.png", "plain.png"]
    for name in names:
        (tmp_path / name).write_bytes(source)
    result = run(*(str(tmp_path / n) for n in names), env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    header, *rows = result.stdout.splitlines()
    assert len(rows) == 3 and "two\\nlines.png" in rows[0] and "a\\ttab.png" in rows[1]
    # Every row's rock index under the header's "rock" (right-aligned, 4 wide).
    assert {row.index(" 0  ") + 1 for row in rows} == {header.index("rock") + 3}
