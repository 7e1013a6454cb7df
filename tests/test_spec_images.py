"""Spec shapes given by example photos (``images = [...]``) instead of parameters."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image

from rockscan.cli import main
from rockscan.core.errors import SpecError
from rockscan.core.information import FaceConfig, information_face
from rockscan.core.library import ShapeSpec
from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.superformula import SuperformulaParams, shape_radii
from rockscan.io import read_spec, write_spec
from rockscan.run.pipeline import classify_image, library_from_spec, measure_rocks

STAR5 = SuperformulaParams(5, 5, 2.0, 7.0, 7.0)
EGG = SuperformulaParams(1, 1, 0.75, 0.75, 0.75)
#: Examples at these turns: a library that did not align them would blur the star.
TURNS = (0.0, 23.0, 131.0)


def rms_percent(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a / a.mean() - b / b.mean()) ** 2)) * 100.0)


def best_turn(radii: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """radii rolled to the reference by brute force (least squares over every roll)."""
    a = radii / radii.mean()
    b = reference / reference.mean()
    errors = [np.sum((np.roll(a, -k) - b) ** 2) for k in range(a.size)]
    return np.roll(radii, -int(np.argmin(errors)))


@pytest.fixture(scope="module")
def example_spec(tmp_path_factory):
    """A spec in a folder: the paper's triangle and blunt by parameters, a star by
    three example photos in a sub-folder, given by paths relative to the spec."""
    folder = tmp_path_factory.mktemp("lib")
    (folder / "examples").mkdir()
    names = []
    for i, turn in enumerate(TURNS):
        photo = render_photo(STAR5, RenderConfig(angle_deg=turn), rng=40 + i)
        name = f"examples/star-{i}.png"
        (folder / name).write_bytes(photo.encode(".png"))
        names.append(name)
    listed = ", ".join(json.dumps(n) for n in names)
    spec = folder / "spec.toml"
    spec.write_text(
        '[[shape]]\nname = "triangle"\nm1 = 3\nm2 = 3\nn1 = 1500\nn2 = 1500\nn3 = 1500\n\n'
        '[[shape]]\nname = "egg"\nm1 = 1\nm2 = 1\nn1 = 0.75\nn2 = 0.75\nn3 = 0.75\n\n'
        f'[[shape]]\nname = "found-star"\nimages = [{listed}]\ninterest = 3\n',
        encoding="utf-8",
    )
    return spec


def test_image_paths_are_relative_to_the_spec(example_spec):
    shapes = read_spec(example_spec)
    star = shapes[2]
    assert star.params is None and star.interest == 3.0
    assert star.images == tuple(str(example_spec.parent / f"examples/star-{i}.png") for i in range(3))


def test_face_of_an_example_shape_is_the_mean_of_its_aligned_examples_faces(example_spec):
    shapes = read_spec(example_spec)
    config = FaceConfig(n_angles=180)
    library = library_from_spec(shapes, face_config=config)
    assert library.names == ("triangle", "egg", "found-star")
    assert library.params[2] is None and library.interest[2] == 3.0
    # The oracle: measure each photo, turn each to the first by brute force, average the faces.
    measured = []
    for path in shapes[2].images:
        with Image.open(path) as image:
            radii = measure_rocks(np.asarray(image), 180)[1][0].radii
        measured.append(radii / radii.mean())
    aligned = np.array([best_turn(r, measured[0]) for r in measured])
    face = information_face(aligned, config).mean(axis=0)
    np.testing.assert_allclose(library.faces()[2], face, atol=1e-9)
    np.testing.assert_allclose(library.radii[2], aligned.mean(axis=0) / aligned.mean(), atol=1e-12)
    # Shapes given by parameters are built as Library.from_shapes builds them.
    np.testing.assert_allclose(library.radii[1], shape_radii(EGG, 180), atol=1e-12)


def test_examples_turned_differently_reinforce_rather_than_blur(example_spec):
    library = library_from_spec(read_spec(example_spec))
    star = library.radii[2]
    true = shape_radii(STAR5, 360)
    assert rms_percent(best_turn(star, true), true) < 1.0
    # Averaging the same examples without turning them would wash the arms out.
    shapes = read_spec(example_spec)
    unaligned = []
    for path in shapes[2].images:
        with Image.open(path) as image:
            radii = measure_rocks(np.asarray(image), 360)[1][0].radii
        unaligned.append(radii / radii.mean())
    blurred = np.mean(unaligned, axis=0)
    assert rms_percent(best_turn(blurred, true), true) > 3.0


def test_fresh_photos_of_the_example_shape_match_it(example_spec):
    library = library_from_spec(read_spec(example_spec))
    rng = np.random.default_rng(5)
    for params, name in [(STAR5, "found-star")] * 3 + [(EGG, "egg")] * 2:
        photo = render_photo(params, rng=rng)
        assert classify_image(photo.pixels, library)[0].match.nearest == name


def test_cli_builds_and_classifies_with_an_example_shape(example_spec, tmp_path):
    runner = CliRunner()
    lib = tmp_path / "lib.npz"
    built = runner.invoke(main, ["library", "build", str(example_spec), "-o", str(lib)])
    assert built.exit_code == 0, built.output
    assert "3 shapes" in built.stdout
    photo_path = tmp_path / "new-star.png"
    photo_path.write_bytes(render_photo(STAR5, rng=77).encode(".png"))
    for library in (lib, example_spec):
        result = runner.invoke(main, ["classify", str(photo_path), "--library", str(library), "--json"])
        assert result.exit_code == 0, result.output
        assert json.loads(result.stdout)["nearest"] == "found-star"


def test_a_missing_or_empty_example_is_a_one_line_error_naming_shape_and_file(tmp_path):
    blank = tmp_path / "blank.png"
    Image.fromarray(np.full((80, 80), 90, np.uint8)).save(blank)
    cases = [("gone.png", "gone.png"), ("blank.png", "no rock")]
    for image, text in cases:
        spec = tmp_path / "spec.toml"
        spec.write_text(
            '[[shape]]\nname = "egg"\nm1 = 1\nm2 = 1\nn1 = 0.75\nn2 = 0.75\nn3 = 0.75\n\n'
            f'[[shape]]\nname = "mine"\nimages = ["{image}"]\n'
        )
        with pytest.raises(SpecError, match=r"shape 'mine': example .*") as caught:
            library_from_spec(read_spec(spec))
        assert text in str(caught.value).lower()
        result = CliRunner().invoke(main, ["library", "build", str(spec), "-o", str(tmp_path / "l.npz")])
        assert result.exit_code == 1
        assert result.stderr.startswith("rockscan: error: ") and len(result.stderr.splitlines()) == 1
        assert "shape 'mine'" in result.stderr


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ('images = ["a.png"]\nm1 = 1\nm2 = 1\nn1 = 1\nn2 = 1\nn3 = 1', "not both"),
        ('images = "a.png"', "images must be a list of file paths"),
        ("images = [1, 2]", "images must be a list of file paths"),
        ("images = []", "missing"),
    ],
)
def test_malformed_image_entries_are_refused(tmp_path, entry, message):
    spec = tmp_path / "spec.toml"
    spec.write_text(f'[[shape]]\nname = "mine"\n{entry}\n')
    with pytest.raises(SpecError, match=message):
        read_spec(spec)


@given(
    paths=st.lists(
        st.text(
            st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), min_size=1, max_size=12
        ),
        min_size=1,
        max_size=3,
    )
)
def test_image_lists_survive_a_write_and_read(tmp_path_factory, paths):
    folder = tmp_path_factory.mktemp("round")
    absolute = tuple(str(folder / p.replace("/", "_")) for p in paths)
    spec = folder / "spec.toml"
    write_spec([ShapeSpec("mine", images=absolute, interest=0.5), ShapeSpec("egg", EGG)], spec)
    mine, egg = read_spec(spec)
    assert mine.images == absolute and mine.interest == 0.5 and mine.params is None
    assert egg.params == EGG
