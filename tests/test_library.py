"""Libraries: building from specs and radii, validation, the default library."""

from __future__ import annotations

import numpy as np
import pytest

from rockscan.core.errors import LibraryError, ParameterError, SpecError
from rockscan.core.information import FaceConfig
from rockscan.core.library import Library, ShapeSpec
from rockscan.core.polar import polygon_centroid_xy, radii_to_xy
from rockscan.core.superformula import SuperformulaParams, shape_radii


def test_default_library_has_the_papers_shapes_and_a_circle(default_lib):
    assert len(default_lib) >= 12
    assert {"rounded-triangle", "three-faced-blunt", "six-pointed-star", "circle"} <= set(default_lib.names)
    assert default_lib.symmetry[default_lib.index("circle")] == 0
    assert default_lib.basis.n_components == len(default_lib) - 1
    assert default_lib.interest[default_lib.index("five-armed-star")] == 2.0
    # Its cutoffs come from the same calibration as any library's, at the paper's 20%.
    assert default_lib.calibration is not None and default_lib.tolerance == 0.2
    assert default_lib.cutoffs.shape == (len(default_lib),) and np.all(default_lib.cutoffs > 0)


def test_shape_radii_are_centred_and_normalised():
    radii = shape_radii(SuperformulaParams(1, 1, 0.5, 0.5, 0.5), 360)
    assert radii.mean() == pytest.approx(1.0)
    np.testing.assert_allclose(polygon_centroid_xy(radii_to_xy(radii)), 0, atol=5e-3)
    # a = b only scales: the normalised radii are the same.
    np.testing.assert_allclose(
        shape_radii(SuperformulaParams(5, 5, 2, 7, 7, a=3, b=3), 360),
        shape_radii(SuperformulaParams(5, 5, 2, 7, 7), 360),
        rtol=1e-9,
    )


def test_unbounded_superformula_is_refused():
    with pytest.raises(ParameterError, match="unbounded or degenerate"):
        shape_radii(SuperformulaParams(2, 4, 1, 1, 1), 360)
    with pytest.raises(LibraryError, match="shape 'bad'"):
        Library.from_shapes(
            [
                ShapeSpec("ok", SuperformulaParams(4, 4, 2, 2, 2)),
                ShapeSpec("bad", SuperformulaParams(2, 4, 1, 1, 1)),
            ]
        )


def test_faces_of_the_library_are_the_shapes_faces(paper_lib):
    from rockscan.core.information import information_face

    np.testing.assert_allclose(paper_lib.faces(), information_face(paper_lib.radii), atol=1e-12)


def test_library_from_radii_and_given_faces():
    rng = np.random.default_rng(0)
    radii = 1 + 0.1 * rng.random((4, 360))
    lib = Library.from_radii(["a", "b", "c", "d"], radii, face_config=FaceConfig(kind="radii"))
    assert lib.radii.mean(axis=1) == pytest.approx(np.ones(4))
    faces = np.repeat(np.arange(4.0)[:, None, None], 360, axis=1)
    custom = Library.from_radii(
        ["a", "b", "c", "d"], radii, face_config=FaceConfig(kind="radii"), faces=faces
    )
    np.testing.assert_allclose(custom.faces(), faces, atol=1e-12)


@pytest.mark.parametrize(
    ("names", "radii", "message"),
    [
        ([], np.ones((0, 360)), "at least one shape"),
        (["a", "a"], np.ones((2, 360)) + np.arange(2)[:, None], "unique; repeated: a"),
        (["a", "B"], np.ones((2, 360)), "must match"),
        (["a", "b"], np.ones((3, 360)), "one row per name"),
        (["a", "b"], -np.ones((2, 360)), "finite and positive"),
    ],
)
def test_bad_libraries_are_refused(names, radii, message):
    with pytest.raises(LibraryError, match=message):
        Library.from_radii(names, radii)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"name": "Bad Name", "params": SuperformulaParams(4, 4, 2, 2, 2)}, "must match"),
        ({"name": "x"}, "give Superformula parameters or example images"),
        ({"name": "x", "params": SuperformulaParams(4, 4, 2, 2, 2), "images": ("a.png",)}, "not both"),
        ({"name": "x", "params": SuperformulaParams(4, 4, 2, 2, 2), "interest": -1}, "interest"),
    ],
)
def test_bad_shape_specs_are_refused(kwargs, message):
    with pytest.raises(SpecError, match=message):
        ShapeSpec(**kwargs)


def test_library_lookup_and_immutability(paper_lib):
    assert paper_lib.index("six-pointed-star") == 2
    with pytest.raises(LibraryError, match="no shape named 'moon'"):
        paper_lib.index("moon")
    with pytest.raises(ValueError, match="read-only"):
        paper_lib.radii[0, 0] = 2.0
    # interest and symmetry too: default_library() is one object, and a caller's
    # edit of its symmetry changed every later match's angle.
    for array in (paper_lib.interest, paper_lib.symmetry):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0


def test_a_library_copies_what_it_is_given_and_leaves_it_writable():
    interest = np.array([1.0, 2.0])
    radii = np.ones((2, 360))
    radii[1] += 0.2 * np.cos(3 * np.linspace(0, 2 * np.pi, 360, endpoint=False))
    lib = Library.from_radii(["a", "b"], radii, interest=interest)
    interest[0] = 5.0
    assert lib.interest.tolist() == [1.0, 2.0] and interest.flags.writeable


def test_a_shape_given_twice_is_refused_and_a_close_variant_is_not():
    # Two copies left no cutoff that takes a sample to either of them.
    egg = shape_radii(SuperformulaParams(1, 1, 0.75, 0.75, 0.75), 360)
    star = shape_radii(SuperformulaParams(5, 5, 2, 7, 7), 360)
    with pytest.raises(LibraryError, match="shapes a, b have one outline"):
        Library.from_radii(["a", "b", "c"], np.stack([egg, egg * 3.0, star]))
    close = shape_radii(SuperformulaParams(1, 1, 0.75 * 1.01, 0.75, 0.75), 360)
    assert len(Library.from_radii(["a", "b", "c"], np.stack([egg, close, star]))) == 3
