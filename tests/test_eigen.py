"""Eigenfaces (Turk & Pentland 1991): the basis, projections and distances."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from rockscan.core.eigen import EigenBasis
from rockscan.core.errors import ParameterError


def _faces(rng, n=6, shape=(12, 5)):
    return rng.normal(size=(n, *shape))


def test_basis_is_orthonormal_and_spans_the_faces(rng):
    faces = _faces(rng)
    basis = EigenBasis.from_faces(faces)
    assert basis.n_components == 5  # one fewer than the faces: the mean is removed
    np.testing.assert_allclose(basis.components @ basis.components.T, np.eye(5), atol=1e-12)
    assert np.all(np.diff(basis.eigenvalues) <= 0)
    rebuilt = basis.mean + basis.weights @ basis.components
    np.testing.assert_allclose(rebuilt, faces.reshape(6, -1), atol=1e-12)
    np.testing.assert_allclose(basis.mean, faces.reshape(6, -1).mean(axis=0))


def test_same_subspace_as_an_svd(rng):
    faces = _faces(rng, n=8, shape=(40,))
    basis = EigenBasis.from_faces(faces)
    centered = faces - faces.mean(axis=0)
    _, s, vt = np.linalg.svd(centered, full_matrices=False)
    keep = s > 1e-10 * s[0]
    np.testing.assert_allclose(basis.eigenvalues, s[keep] ** 2, rtol=1e-10)
    projector = basis.components.T @ basis.components
    np.testing.assert_allclose(projector, vt[keep].T @ vt[keep], atol=1e-10)


def test_more_faces_than_pixels_uses_the_covariance(rng):
    faces = rng.normal(size=(30, 4))
    basis = EigenBasis.from_faces(faces)
    assert basis.n_components == 4
    np.testing.assert_allclose(basis.distances(faces[3])[3], 0, atol=1e-12)


def test_duplicate_faces_leave_zero_eigenvalues_out(rng):
    faces = _faces(rng, n=3)
    basis = EigenBasis.from_faces(np.concatenate([faces, faces]))
    assert basis.n_components == 2


def test_library_faces_have_zero_distance_to_themselves(rng):
    faces = _faces(rng)
    eps = EigenBasis.from_faces(faces).distances(faces)
    np.testing.assert_allclose(np.diag(eps), 0, atol=1e-12)
    expected = np.linalg.norm(faces.reshape(6, 1, -1) - faces.reshape(1, 6, -1), axis=2)
    np.testing.assert_allclose(eps, expected, rtol=1e-10)


@given(arrays(np.float64, (12, 5), elements=st.floats(-3, 3)))
def test_eigenspace_distance_plus_residual_is_the_face_distance(sample):
    # Paper notes, note 10: eps_k^2 + dffs^2 = ||Gamma - F_k||^2 for every k.
    faces = _faces(np.random.default_rng(7))
    basis = EigenBasis.from_faces(faces)
    eps = basis.distances(sample)
    dffs = basis.residual(sample)
    direct = np.linalg.norm(faces.reshape(6, -1) - sample.ravel(), axis=1)
    np.testing.assert_allclose(eps**2 + dffs**2, direct**2, rtol=1e-9, atol=1e-9)


def test_truncation_keeps_the_strongest_components(rng):
    faces = _faces(rng)
    full = EigenBasis.from_faces(faces)
    two = EigenBasis.from_faces(faces, n_components=2)
    assert two.n_components == 2
    np.testing.assert_allclose(two.eigenvalues, full.eigenvalues[:2])


def test_batches_project_like_single_faces(rng):
    faces = _faces(rng)
    basis = EigenBasis.from_faces(faces)
    batch = rng.normal(size=(3, 4, 12, 5))
    omega = basis.project(batch)
    assert omega.shape == (3, 4, 5)
    np.testing.assert_allclose(omega[1, 2], basis.project(batch[1, 2]), atol=1e-12)
    assert basis.distances(batch).shape == (3, 4, 6)


def test_errors(rng):
    with pytest.raises(ParameterError, match="at least two faces"):
        EigenBasis.from_faces(rng.normal(size=(1, 10)))
    with pytest.raises(ParameterError, match="finite"):
        EigenBasis.from_faces(np.array([[0.0, np.inf], [1.0, 2.0]]))
    basis = EigenBasis.from_faces(_faces(rng))
    with pytest.raises(ParameterError, match="60 pixels"):
        basis.project(np.zeros(7))
    with pytest.raises(ValueError, match="read-only"):
        basis.mean[0] = 1.0


# ---------------------------------------------------------------- large libraries


def _low_rank_faces(rng, n=40, rank=5, shape=(12, 5)):
    """Faces that all lie in an affine space of ``rank`` dimensions."""
    base = rng.normal(size=(rank, int(np.prod(shape))))
    return (rng.normal(size=(n, rank)) @ base + rng.normal(size=base.shape[1])).reshape(n, *shape)


def test_streamed_basis_on_a_sample_that_spans_equals_the_exact_one(rng):
    faces = _low_rank_faces(rng)
    exact = EigenBasis.from_faces(faces)
    chunks = (faces[i : i + 7] for i in range(0, len(faces), 7))
    streamed = EigenBasis.from_face_stream(faces[::4], chunks, n_components=8)
    assert exact.n_components == streamed.n_components == 5
    np.testing.assert_allclose(streamed.mean, exact.mean, atol=1e-12)
    np.testing.assert_allclose(streamed.eigenvalues, exact.eigenvalues, rtol=1e-9)
    sample = rng.normal(size=(3, 12, 5))
    np.testing.assert_allclose(streamed.distances(sample), exact.distances(sample), rtol=1e-9)
    np.testing.assert_allclose(streamed.residual(sample), exact.residual(sample), rtol=1e-9)
    np.testing.assert_allclose(streamed.components @ streamed.components.T, np.eye(5), atol=1e-12)


def test_streamed_basis_truncates_to_the_strongest_directions(rng):
    faces = rng.normal(size=(30, 60)) * np.linspace(3, 0.1, 60)
    streamed = EigenBasis.from_face_stream(faces, [faces[:11], faces[11:]], n_components=4)
    exact = EigenBasis.from_faces(faces, n_components=4)
    assert streamed.n_components == 4
    # Fitted on every face, the kept directions are the exact basis's, turned.
    np.testing.assert_allclose(
        streamed.components.T @ streamed.components, exact.components.T @ exact.components, atol=1e-10
    )
    # A library face's own distance is 0 whatever was dropped.
    np.testing.assert_allclose(np.diag(streamed.distances(faces)), 0, atol=1e-10)


def test_streamed_basis_errors(rng):
    with pytest.raises(ParameterError, match="at least 1"):
        EigenBasis.from_face_stream(rng.normal(size=(4, 6)), [], n_components=0)
    with pytest.raises(ParameterError, match="two faces"):
        EigenBasis.from_face_stream(rng.normal(size=(4, 6)), [rng.normal(size=(1, 6))], n_components=2)
    with pytest.raises(ParameterError, match="finite"):
        EigenBasis.from_face_stream(rng.normal(size=(4, 6)), [np.full((3, 6), np.nan)], n_components=2)


def test_distances_to_some_shapes_only(rng):
    faces = _faces(rng)
    basis = EigenBasis.from_faces(faces)
    sample = rng.normal(size=(12, 5))
    eps, dffs = basis.distances_and_residual(sample, shapes=[4, 1])
    np.testing.assert_allclose(eps, basis.distances(sample)[[4, 1]])
    assert dffs == pytest.approx(basis.residual(sample))


def test_large_build_helpers_equal_the_per_shape_ones(default_specs):
    from rockscan.core.information import FaceConfig, information_face
    from rockscan.core.library import _FaceTable, shapes_radii, symmetry_orders
    from rockscan.core.polar import symmetry_order
    from rockscan.core.render import random_superformula
    from rockscan.core.superformula import shape_radii

    params = [s.params for s in default_specs if s.params is not None]
    params += [random_superformula(np.random.default_rng(i)) for i in range(20)]
    radii = shapes_radii(params, 360)
    expected = np.array([shape_radii(p, 360) for p in params])
    np.testing.assert_allclose(radii, expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(symmetry_orders(expected), [symmetry_order(r) for r in expected])
    for config in (
        FaceConfig(),
        FaceConfig(kind="information-shape", reference=params[0]),
        FaceConfig(sigma=0.05),
    ):
        np.testing.assert_allclose(
            _FaceTable(config).faces(expected), information_face(expected, config), atol=1e-11
        )


def test_a_library_built_the_large_way_matches_its_own_shapes(default_specs):
    from rockscan.core.library import Library
    from rockscan.core.match import match_radii

    shapes = [s for s in default_specs if s.params is not None]
    large_way = Library.from_shapes(shapes, exact_limit=0, n_components=6)
    exact = Library.from_shapes(shapes)
    assert large_way.basis.n_components == 6
    np.testing.assert_allclose(large_way.radii, exact.radii, rtol=1e-12)
    np.testing.assert_array_equal(large_way.symmetry, exact.symmetry)
    for k in (0, 3, len(shapes) - 1):
        m = match_radii(np.roll(exact.radii[k], 40), large_way)
        assert m.nearest == shapes[k].name
        assert m.distance == pytest.approx(0.0, abs=1e-6)


def test_a_large_build_in_threads_equals_one_in_turn(monkeypatch):
    """Faces made two chunks at a time, in buffers that take turns: the same basis to the last bit."""
    from rockscan.core import library as library_module
    from rockscan.core.information import FaceConfig
    from rockscan.core.library import Library, ShapeSpec
    from rockscan.core.render import random_superformula

    rng = np.random.default_rng(3)
    shapes = [ShapeSpec(f"s-{i}", random_superformula(rng)) for i in range(200)]
    config = FaceConfig(n_angles=64, resolution=0.05)
    monkeypatch.setattr(library_module, "_CHUNK", 16)  # 13 chunks through 4 buffers
    built = [Library.from_shapes(shapes, face_config=config, exact_limit=0, n_components=8)]
    monkeypatch.setattr(library_module, "_BUILD_THREADS", 1)
    built.append(Library.from_shapes(shapes, face_config=config, exact_limit=0, n_components=8))
    threaded, serial = built
    for name in ("mean", "components", "eigenvalues", "weights"):
        np.testing.assert_array_equal(getattr(threaded.basis, name), getattr(serial.basis, name))
    np.testing.assert_array_equal(threaded.cutoffs, serial.cutoffs)


def test_a_truncated_fit_makes_the_same_leading_eigenfaces(rng):
    faces = rng.normal(size=(30, 40))
    full = EigenBasis.from_faces(faces)
    few = EigenBasis.from_faces(faces, n_components=5)
    np.testing.assert_allclose(few.eigenvalues, full.eigenvalues[:5], rtol=1e-12)
    np.testing.assert_allclose(few.components, full.components[:5], atol=1e-12)
    np.testing.assert_allclose(few.weights, full.weights[:, :5], atol=1e-12)
