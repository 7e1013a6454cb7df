"""Spec files and library files: round trips, and clear errors for anything else."""

from __future__ import annotations

import json
import pickle
import zipfile

import numpy as np
import pytest

from rockscan.errors import LibraryError, ParameterError, SpecError
from rockscan.information import FaceConfig
from rockscan.io import (
    LIBRARY_VERSION,
    default_spec_path,
    load_library,
    parse_spec,
    read_radii,
    read_spec,
    save_library,
    write_spec,
)
from rockscan.library import Library
from rockscan.match import match_radii


def test_default_spec_is_shipped_and_valid(default_specs):
    assert default_spec_path().is_file()
    assert len(default_specs) >= 12
    assert all(s.params is not None for s in default_specs)


def test_spec_round_trip(tmp_path, default_specs):
    path = tmp_path / "lib.toml"
    write_spec(default_specs, path)
    assert read_spec(path) == default_specs


def test_spec_images_are_relative_to_the_spec(tmp_path):
    path = tmp_path / "sub" / "spec.toml"
    path.parent.mkdir()
    path.write_text('[[shape]]\nname = "mine"\nimages = ["a.png", "../b.jpg"]\ninterest = 3\n')
    (shape,) = read_spec(path)
    assert shape.params is None and shape.interest == 3
    assert shape.images == (str(path.parent / "a.png"), str(path.parent / "../b.jpg"))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[[shape]\nname=", "not valid TOML"),
        ('title = "x"\n', "needs \\[\\[shape\\]\\] tables"),
        ('[[shape]]\nname = "a"\nm1 = 4\nm2 = 4\nn1 = 2\nn2 = 2\n', "missing n3"),
        (
            '[[shape]]\nname = "a"\nm1 = 4\nm2 = 4\nn1 = 2\nn2 = 2\nn3 = 2\ncolour = 1\n',
            "unknown keys colour",
        ),
        ('[[shape]]\nname = "a"\nm1 = 4\nm2 = 4\nn1 = 0\nn2 = 2\nn3 = 2\n', "n1 must be non-zero"),
        ('[[shape]]\nname = "a"\nm1 = 4\nm2 = 4\nn1 = 1\nn2 = 2\nn3 = 2\na = -1\n', "a must be positive"),
        ('[[shape]]\nname = "Rock 1"\nm1 = 4\nm2 = 4\nn1 = 1\nn2 = 2\nn3 = 2\n', "must match"),
        ('[[shape]]\nname = "a"\nm1 = 4\nm2 = 4\nn1 = 1\nn2 = 2\nn3 = 2\n' * 2, "used twice"),
        ('[[shape]]\nname = "a"\nimages = "x.png"\n', "images must be a list"),
    ],
)
def test_bad_specs_name_the_problem(tmp_path, text, message):
    path = tmp_path / "spec.toml"
    path.write_text(text)
    with pytest.raises(SpecError, match=message):
        read_spec(path)


def test_missing_spec(tmp_path):
    with pytest.raises(SpecError, match="spec file not found"):
        read_spec(tmp_path / "nope.toml")
    with pytest.raises(SpecError, match="shape 1 is not a table"):
        parse_spec({"shape": [3]})


@pytest.mark.parametrize(
    "config",
    [FaceConfig(), FaceConfig(kind="radii", n_angles=180), FaceConfig(grid="cartesian", cartesian_size=32)],
)
def test_library_file_round_trip(tmp_path, default_specs, config):
    lib = Library.from_shapes(default_specs[:5], face_config=config)
    path = tmp_path / "lib.npz"
    save_library(lib, path)
    again = load_library(path)
    assert again.names == lib.names and again.params == lib.params and again.face_config == config
    np.testing.assert_array_equal(again.radii, lib.radii)
    np.testing.assert_array_equal(again.basis.components, lib.basis.components)
    np.testing.assert_array_equal(again.symmetry, lib.symmetry)
    sample = np.roll(lib.radii[2], 17) * 5
    a, b = match_radii(sample, again), match_radii(sample, lib)
    assert (a.nearest, a.mscore, a.angle_deg) == (b.nearest, b.mscore, b.angle_deg)
    # No stray temporary file is left behind.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lib.npz"]


def _saved(tmp_path, default_specs):
    path = tmp_path / "good.npz"
    save_library(Library.from_shapes(default_specs[:4]), path)
    return path


def _rewrite(src, dst, change):
    """Copy a library archive, letting ``change`` edit its arrays."""
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    np.savez(dst, **arrays)


def _meta(arrays, **updates):
    meta = json.loads(arrays["metadata"].tobytes())
    meta.update(updates)
    arrays["metadata"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)


def test_corrupt_truncated_and_foreign_files_are_refused(tmp_path, default_specs):
    good = _saved(tmp_path, default_specs)
    data = good.read_bytes()
    cases = {}
    cases["truncated.npz"] = (data[: len(data) // 2], "truncated or corrupt|not a rockscan library")
    flipped = bytearray(data)
    flipped[len(data) // 3] ^= 0xFF
    cases["flipped.npz"] = (bytes(flipped), "truncated or corrupt|not a rockscan library|inconsistent")
    cases["text.npz"] = (b"hello, this is not a library\n", "not a rockscan library")
    cases["empty.npz"] = (b"", "file is empty, not a rockscan library")
    cases["zip.npz"] = (b"PK\x03\x04" + b"\0" * 40, "truncated or corrupt|not a rockscan library")
    cases["pickle.npz"] = (pickle.dumps({"names": ["a"]}), "not a rockscan library")
    for name, (content, message) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(LibraryError, match=message):
            load_library(path)


def test_other_numpy_files_are_refused(tmp_path, default_specs):
    good = _saved(tmp_path, default_specs)
    np.save(tmp_path / "array.npy", np.arange(5))
    with pytest.raises(LibraryError, match="bare numpy array"):
        load_library(tmp_path / "array.npy")
    np.savez(tmp_path / "other.npz", x=np.arange(3))
    with pytest.raises(LibraryError, match="missing metadata"):
        load_library(tmp_path / "other.npz")
    np.savez(tmp_path / "objects.npz", metadata=np.array([{"a": 1}], dtype=object))
    with pytest.raises(LibraryError, match="not a rockscan library"):
        load_library(tmp_path / "objects.npz")
    edits = {
        "foreign.npz": (lambda a: _meta(a, format="someone-else"), "format is 'someone-else'"),
        "future.npz": (lambda a: _meta(a, version=LIBRARY_VERSION + 1), "newer than this rockscan reads"),
        "names.npz": (lambda a: _meta(a, names=["x"]), "disagree|must be \\(n_shapes"),
        "nan.npz": (lambda a: a.__setitem__("components", a["components"] * np.nan), "non-finite"),
        "shape.npz": (lambda a: a.__setitem__("mean", a["mean"][:10]), "inconsistent|does not fit|must be"),
        "meta.npz": (
            lambda a: a.__setitem__("metadata", np.frombuffer(b"{not json", np.uint8)),
            "metadata is corrupt",
        ),
    }
    for name, (change, message) in edits.items():
        _rewrite(good, tmp_path / name, change)
        with pytest.raises(LibraryError, match=message):
            load_library(tmp_path / name)


def test_missing_or_folder_library(tmp_path):
    with pytest.raises(LibraryError, match="library file not found"):
        load_library(tmp_path / "nope.npz")
    with pytest.raises(LibraryError, match="is a folder"):
        load_library(tmp_path)


def test_library_files_hold_no_pickles(tmp_path, default_specs):
    good = _saved(tmp_path, default_specs)
    with zipfile.ZipFile(good) as z:
        for name in z.namelist():
            header = z.read(name)[:128]
            assert b"'descr': '|O'" not in header and b"pickle" not in header


def test_radii_files(tmp_path):
    (tmp_path / "r.txt").write_text(" ".join(["1.0"] * 10) + "\n2, 3\n")
    np.testing.assert_allclose(read_radii(tmp_path / "r.txt"), [1.0] * 10 + [2, 3])
    np.save(tmp_path / "r.npy", np.arange(1.0, 21.0))
    assert read_radii(tmp_path / "r.npy").size == 20
    (tmp_path / "bad.txt").write_text("1 2 three")
    with pytest.raises(ParameterError, match="cannot read radii"):
        read_radii(tmp_path / "bad.txt")
    (tmp_path / "short.txt").write_text("1 2 3")
    with pytest.raises(ParameterError, match="at least 8"):
        read_radii(tmp_path / "short.txt")
    with pytest.raises(ParameterError, match="not found"):
        read_radii(tmp_path / "none.txt")


def test_data_files_are_found_installed_or_not():
    from rockscan.io import data_path

    assert data_path("default_library.toml").is_file()
    assert (data_path("examples") / "coin.png").is_file()
