"""Eigenfaces (Turk & Pentland 1991): the basis, projections and distances."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from rockscan.eigen import EigenBasis
from rockscan.errors import ParameterError


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
