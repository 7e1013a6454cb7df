"""Spec files and library files: round trips, and clear errors for anything else."""

from __future__ import annotations

import io
import json
import pickle
import re
import tomllib
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rockscan.core.errors import LibraryError, ParameterError, SpecError
from rockscan.core.information import FaceConfig
from rockscan.core.library import Library, ShapeSpec
from rockscan.core.match import match_radii
from rockscan.io import (
    LIBRARY_VERSION,
    _npzsafe,
    default_spec_path,
    load_library,
    parse_spec,
    read_radii,
    read_spec,
    save_library,
    write_spec,
)
from rockscan.io import spec as spec_module


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
    assert shape.images == (str(path.parent / "a.png"), str(tmp_path / "b.jpg"))


def test_spec_images_written_and_read_back_name_the_same_files(tmp_path, monkeypatch):
    # The paths were written relative to the working folder and read relative to the
    # spec's: "specdir/coin.png" came back as "specdir/specdir/coin.png".
    monkeypatch.chdir(tmp_path)
    (tmp_path / "specdir").mkdir()
    write_spec([ShapeSpec("coin", images=("specdir/coin.png", str(tmp_path / "b.png")))], "specdir/lib.toml")
    assert 'images = ["coin.png", "../b.png"]' in (tmp_path / "specdir" / "lib.toml").read_text()
    monkeypatch.chdir(tmp_path / "specdir")
    (shape,) = read_spec("lib.toml")
    assert shape.images == (str(tmp_path / "specdir" / "coin.png"), str(tmp_path / "b.png"))


@pytest.mark.parametrize(
    ("shapes", "message"),
    [
        ([], "at least one shape"),
        ([ShapeSpec("a", images=("x.png",)), ShapeSpec("a", images=("y.png",))], "used twice: a"),
        ([ShapeSpec("a", images=("roch\udce9.png",))], "not valid UTF-8"),
    ],
)
def test_write_spec_refuses_what_read_spec_would(tmp_path, shapes, message):
    with pytest.raises(SpecError, match=message):
        write_spec(shapes, tmp_path / "s.toml")
    assert not (tmp_path / "s.toml").exists()


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


_TOML_FLOATS = st.floats(allow_nan=False, allow_infinity=False) | st.integers(-(10**6), 10**6)
_TOML_TEXT = st.text(st.characters(codec="utf-8", exclude_characters='"\\'), max_size=12)
_TOML_VALUES = (
    _TOML_FLOATS.map(lambda v: repr(v) if isinstance(v, float) else str(v))
    | _TOML_TEXT.map(lambda t: '"' + t + '"')
    | st.lists(_TOML_TEXT, max_size=3).map(lambda items: "[" + ", ".join(f'"{t}"' for t in items) + "]")
    | st.sampled_from(["1_000", "0x1f", "01", "1.", ".5", "inf", "nan", "true", "1e", "-0.0", "+3"])
)
_TOML_LINES = st.lists(
    st.sampled_from(["[[shape]]", "", "# a comment", "[shape]", "\t[[ shape ]]  "])
    | st.tuples(st.sampled_from(["name", "m1", "n3", "images", "k_2", "a b"]), _TOML_VALUES).map(
        lambda kv: f"{kv[0]} = {kv[1]}"
    ),
    max_size=12,
)


@given(lines=_TOML_LINES, newline=st.sampled_from(["\n", "\r\n"]))
def test_the_plain_spec_reader_agrees_with_tomllib(lines, newline):
    """Where it reads a text at all, it reads what tomllib does; elsewhere tomllib reads it."""
    text = newline.join(lines)
    fast = spec_module._simple_spec(text)
    try:
        full = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        full = None
    if fast is not None:
        assert fast == full
        assert [type(v) for t in fast["shape"] for v in t.values()] == [
            type(v) for t in full["shape"] for v in t.values()
        ]


def test_a_written_spec_takes_the_plain_reader(default_specs, tmp_path):
    shapes = [*default_specs, ShapeSpec("from-photos", images=("a b.png", "c.jpg"), interest=2.5)]
    text = write_spec(shapes)
    assert spec_module._simple_spec(text) == tomllib.loads(text)
    assert spec_module._simple_spec("# made by hand\n" + text) is None  # tomllib's turn


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
    # Excel's and Notepad's "CSV UTF-8" starts with a byte-order mark.
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + b"1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0\n")
    np.testing.assert_allclose(read_radii(tmp_path / "bom.csv"), np.arange(1.0, 9.0))
    np.save(tmp_path / "r.npy", np.arange(1.0, 21.0))
    assert read_radii(tmp_path / "r.npy").size == 20
    # numpy.savetxt's header and notes after a '#' were "could not convert string to float".
    np.savetxt(tmp_path / "saved.txt", np.arange(1.0, 13.0), header="radii of rock 7")
    with open(tmp_path / "saved.txt", "a") as fh:
        fh.write("13  # the last ray\n")
    np.testing.assert_allclose(read_radii(tmp_path / "saved.txt"), np.arange(1.0, 14.0))
    np.testing.assert_allclose(read_radii(tmp_path / "saved.txt"), np.loadtxt(tmp_path / "saved.txt"))
    (tmp_path / "bad.txt").write_text("1 2 three")
    with pytest.raises(ParameterError, match="cannot read radii"):
        read_radii(tmp_path / "bad.txt")
    # A table of two columns would be read with its columns interleaved.
    (tmp_path / "table.txt").write_text("\n".join(f"{i} {i + 1}" for i in range(1, 11)))
    with pytest.raises(ParameterError, match="not a table"):
        read_radii(tmp_path / "table.txt")
    for bad, message in [
        (np.zeros(20, dtype=[("a", "f8"), ("b", "f8")]), "real numbers"),
        (np.ones(20, complex), "real numbers"),
        (np.ones(20, bool), "real numbers"),
        (np.ones((2, 10)), "1-D"),
    ]:
        np.save(tmp_path / "bad.npy", bad)
        with pytest.raises(ParameterError, match=message):
            read_radii(tmp_path / "bad.npy")
    (tmp_path / "huge.txt").write_text("1e308 " * 8)
    with pytest.raises(ParameterError, match="at most 1e"):
        read_radii(tmp_path / "huge.txt")
    (tmp_path / "short.txt").write_text("1 2 3")
    with pytest.raises(ParameterError, match="at least 8"):
        read_radii(tmp_path / "short.txt")
    with pytest.raises(ParameterError, match="not found"):
        read_radii(tmp_path / "none.txt")


def test_data_files_are_found_installed_or_not():
    from rockscan.io import data_path

    assert data_path("default_library.toml").is_file()
    assert (data_path("examples") / "coin.png").is_file()


# ---------------------------------------------------------------- hostile library files


def _members(path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {name: z.read(name) for name in z.namelist()}


def _zipped(path, members: dict[str, bytes], method: int = zipfile.ZIP_STORED) -> None:
    with zipfile.ZipFile(path, "w", compression=method) as z:
        for name, content in members.items():
            z.writestr(name, content)


def _npy(header: bytes, data: bytes = b"", version: int = 1) -> bytes:
    """A .npy member with a given header text (padded as numpy pads it)."""
    text = header + b" " * (-(len(header) + 11) % 64) + b"\n"
    size = len(text).to_bytes(2 if version == 1 else 4, "little")
    return b"\x93NUMPY" + bytes([version, 0]) + size + text + data


def _load_quietly(path) -> tuple[LibraryError, int]:
    """The error of loading ``path`` and the most Python memory it took (bytes)."""
    tracemalloc.start()
    try:
        with pytest.raises(LibraryError) as info:
            load_library(path)
        return info.value, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _with_components(tmp_path, default_specs, values: np.ndarray, method: int) -> Path:
    members = _members(_saved(tmp_path, default_specs))
    header = f"{{'descr': '<f8', 'fortran_order': False, 'shape': {values.shape}, }}".encode()
    members["components.npy"] = _npy(header) + values.tobytes()
    _zipped(tmp_path / "big.npz", members, method)
    return tmp_path / "big.npz"


def test_a_zip_bomb_is_refused_before_it_is_inflated(tmp_path, default_specs):
    """16 MiB of zeros deflate a thousandfold: refused from the sizes the archive declares."""
    path = _with_components(tmp_path, default_specs, np.zeros((1024, 2048)), zipfile.ZIP_DEFLATED)
    assert path.stat().st_size < 16 * 2**20 // 100
    error, peak = _load_quietly(path)
    assert re.search(r"array 'components' would inflate [\d,]+ times \(a zip bomb", str(error)), str(error)
    assert peak < 2 * 2**20


@pytest.mark.parametrize("method", [zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED])
def test_arrays_past_the_budget_are_refused_before_they_are_read(
    tmp_path, default_specs, monkeypatch, method
):
    monkeypatch.setattr(_npzsafe, "MAX_ARCHIVE_BYTES", 8 * 2**20)
    noise = np.random.default_rng(0).random((1024, 1100))  # 8.6 MiB that do not deflate
    error, peak = _load_quietly(_with_components(tmp_path, default_specs, noise, method))
    assert re.search(r"array 'components' would take 9,011,\d+ bytes, past the 8,388,608", str(error)), str(
        error
    )
    assert peak < 2 * 2**20


def test_a_header_claiming_745_gib_is_refused_without_allocating(tmp_path, default_specs):
    members = _members(_saved(tmp_path, default_specs))
    members["mean.npy"] = _npy(b"{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 1000000), }")
    _zipped(tmp_path / "huge.npz", members)
    error, peak = _load_quietly(tmp_path / "huge.npz")
    assert "its header describes 800,000,000,000 bytes of data, the archive holds 0" in str(error)
    assert peak < 2 * 2**20


@pytest.mark.parametrize(
    ("member", "message"),
    [
        (_npy(b"{'descr': '<f8', 'fortran_order': False, 'shape': (3,"), "header is not readable"),
        (
            _npy(b"{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }\x00\xff"),
            "header is not readable",
        ),
        (_npy(b"{'descr': '|O', 'fortran_order': False, 'shape': (1,), }", b"\0" * 8), "not a plain number"),
        (_npy(b"{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (1,), }"), "not numpy's"),
        (_npy(b"{'descr': '<q9', 'fortran_order': False, 'shape': (1,), }"), "not readable"),
        (_npy(b"{'descr': '<f8', 'fortran_order': False, 'shape': (-1,), }"), "is not a shape"),
        (_npy(b"{'descr': '<f8', 'fortran_order': False, 'shape': (True,), }"), "is not a shape"),
        (_npy(b"{'descr': '<f8', 'fortran_order': 0, 'shape': (1,), }"), "not numpy's"),
        (_npy(b"{'descr': '<f8', 'shape': (1,), }"), "not numpy's"),
        (_npy(b"[1, 2]"), "not numpy's"),
        (_npy(b"{'descr': '<f8', 'fortran_order': False, 'shape': (1,), }", version=7), "version 7"),
        (b"\x93NUMPY\x01\x00\xff\xff" + b" " * 70000, "too long"),
        (b"\x93NUMPY\x01", "not a .npy array"),
        (b"plain bytes", "not a .npy array"),
    ],
)
def test_every_header_fault_is_one_library_error(tmp_path, default_specs, member, message):
    members = _members(_saved(tmp_path, default_specs))
    members["weights.npy"] = member
    _zipped(tmp_path / "bad.npz", members)
    error, _ = _load_quietly(tmp_path / "bad.npz")
    assert re.search(f"array 'weights': .*{message}", str(error)), str(error)
    assert "\n" not in str(error) and "pickle" not in str(error)


def _patched(data: bytes, at: int, value: bytes) -> bytes:
    return data[:at] + value + data[at + len(value) :]


def test_every_zip_fault_is_one_library_error(tmp_path, default_specs):
    good = _saved(tmp_path, default_specs)
    data = good.read_bytes()
    directory = data.rindex(b"PK\x01\x02")  # the last member's central directory entry
    local = data.index(b"PK\x03\x04")
    bzip = tmp_path / "bzip2.npz"
    _zipped(bzip, _members(good), zipfile.ZIP_BZIP2)
    rng = np.random.default_rng(3)
    cases = {
        # Flag bit 0 (encrypted) in the central directory and the local header.
        "encrypted.npz": (_patched(_patched(data, directory + 8, b"\x01"), local + 6, b"\x01"), "encrypted"),
        "bzip2.npz": (bzip.read_bytes(), "unsupported method"),
        "patched.npz": (_patched(_patched(data, directory + 8, b"\x20"), local + 6, b"\x20"), "corrupt"),
        "pk-noise.npz": (b"PK" + rng.bytes(4000), "truncated or corrupt"),
        "zip64.npz": (_patched(data, data.rindex(b"PK\x05\x06") + 8, b"\xff\xff\xff\xff"), "zip64"),
        "many.npz": (_many_members(), "an archive of 300 members"),
    }
    for name, (content, message) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        error, _ = _load_quietly(path)
        assert re.search(message, str(error)), (name, str(error))
        assert "\n" not in str(error) and "pickle" not in str(error)


def _many_members() -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as z:
        for i in range(300):
            z.writestr(f"m{i}.npy", b"")
    return buffer.getvalue()


def _with_metadata(tmp_path, default_specs, name, text: bytes):
    members = _members(_saved(tmp_path, default_specs))
    size = len(text)
    members["metadata.npy"] = _npy(
        f"{{'descr': '|u1', 'fortran_order': False, 'shape': ({size},), }}".encode(), text
    )
    _zipped(tmp_path / name, members)
    return tmp_path / name


def _good_metadata(tmp_path, default_specs) -> dict:
    with np.load(_saved(tmp_path, default_specs)) as z:
        return json.loads(z["metadata"].tobytes())


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda meta: [meta], "metadata is not a JSON object"),
        (lambda meta: {**meta, "names": [1, 2, 3, 4]}, "shape name 1 must match"),
        (lambda meta: {**meta, "names": ["Circle", "b", "c", "d"]}, "shape name 'Circle' must match"),
        (lambda meta: {**meta, "names": "abcd"}, "no list of shape names"),
        (lambda meta: {**meta, "face": [1, 2]}, "inconsistent"),
        (lambda meta: {**meta, "params": [[1, 2]] * 4}, "inconsistent"),
        (
            lambda meta: {**meta, "face": {**meta["face"], "ray_length": 1e300, "resolution": 1e-300}},
            "sections",
        ),
        (
            lambda meta: {**meta, "face": {**meta["face"], "n_angles": float("inf")}},
            "n_angles must be an integer",
        ),
    ],
)
def test_metadata_is_validated(tmp_path, default_specs, edit, message):
    text = json.dumps(edit(_good_metadata(tmp_path, default_specs))).encode()
    error, _ = _load_quietly(_with_metadata(tmp_path, default_specs, "meta.npz", text))
    assert re.search(message, str(error)), str(error)


@pytest.mark.parametrize("text", [b"[" * 100_000 + b"]" * 100_000, b'{"format": ' + b"9" * 5000 + b"}"])
def test_metadata_that_json_cannot_take_is_corrupt(tmp_path, default_specs, text):
    error, _ = _load_quietly(_with_metadata(tmp_path, default_specs, "meta.npz", text))
    assert "library metadata is corrupt" in str(error)


def test_an_archive_saved_compressed_still_loads(tmp_path, default_specs):
    good = _saved(tmp_path, default_specs)
    _zipped(tmp_path / "deflated.npz", _members(good), zipfile.ZIP_DEFLATED)
    again = load_library(tmp_path / "deflated.npz")
    np.testing.assert_array_equal(again.basis.components, load_library(good).basis.components)


@pytest.mark.parametrize(
    ("array", "change", "message"),
    [
        # Loaded, saved again, and reported as a match's symmetry of -5.
        ("symmetry", lambda a: a - 10, "symmetry must be whole orders"),
        ("symmetry", lambda a: a.astype(np.float64) + 0.5, "symmetry must be whole orders"),
        ("eigenvalues", lambda a: np.where(np.arange(a.size) == 0, np.nan, a), "eigenvalues must be finite"),
        ("radii", lambda a: -a, "must be non-negative"),
        ("interest", lambda a: a - 5, "must be non-negative"),
    ],
)
def test_a_library_whose_arrays_were_tampered_with_is_refused(
    tmp_path, default_specs, array, change, message
):
    path = tmp_path / "tampered.npz"
    _rewrite(
        _saved(tmp_path, default_specs), path, lambda arrays: arrays.update({array: change(arrays[array])})
    )
    error, _ = _load_quietly(path)
    assert message in str(error)
