"""Fuzzed photos and library files: each decodes or raises a RockscanError, quietly.

The mutator and the seeds live in scripts/fuzz_readers.py (which runs it for
minutes); here it runs a fixed number of inputs of a fixed seed, so a failure
replays anywhere. ``ROCKSCAN_FUZZ_EXAMPLES`` sets how many (default 300), and
``ROCKSCAN_FUZZ_SEED`` the seed.
"""

from __future__ import annotations

import importlib.util
import io
import os
import sys
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from rockscan.core.errors import ImageReadError

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "fuzz_readers.py"
EXAMPLES = int(os.environ.get("ROCKSCAN_FUZZ_EXAMPLES", "300"))
SEED = int(os.environ.get("ROCKSCAN_FUZZ_SEED", "20261201"))


@pytest.fixture(scope="module")
def fuzz():
    spec = importlib.util.spec_from_file_location("fuzz_readers", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["fuzz_readers"] = module
    spec.loader.exec_module(module)
    yield module
    del sys.modules["fuzz_readers"]


def test_every_fuzzed_photo_and_library_reads_or_raises_a_rockscan_error(fuzz, tmp_path):
    tried, findings = fuzz.fuzz(count=EXAMPLES, seed=SEED, folder=tmp_path / "findings")
    assert tried == EXAMPLES
    assert not findings, "\n".join(f"{f.kind} from {f.seed}: {f.problem}" for f in findings[:20])


def test_the_seeds_are_valid_and_cover_every_format(fuzz, tmp_path):
    photos, libraries = fuzz.photo_seeds(), fuzz.library_seeds()
    wide = {name for name in photos if name.startswith("float")}
    formats = {Image.open(io.BytesIO(data)).format for name, data in photos.items() if name not in wide}
    assert formats == {"PNG", "JPEG", "TIFF", "BMP"}
    # Pillow cannot open colour TIFFs of floating-point samples; OpenCV decodes them.
    assert wide and all(photos[name][:4] in (b"II*\x00", b"MM\x00*") for name in wide)
    for kind, seeds in (("photo", photos), ("library", libraries)):
        for name, data in seeds.items():
            path = tmp_path / name
            path.write_bytes(data)
            assert fuzz.check(kind, path) is None, name
    with zipfile.ZipFile(io.BytesIO(libraries["deflated.npz"])) as archive:
        assert {info.compress_type for info in archive.infolist()} == {zipfile.ZIP_DEFLATED}


def test_mutations_replay_from_their_seed_and_change_the_input(fuzz):
    data = fuzz.photo_seeds()["photo.png"]

    def run(seed):
        rng = np.random.default_rng(seed)
        return [fuzz.mutate(data, rng, [data]) for _ in range(20)]

    first, again = run(4), run(4)
    assert first == again
    assert sum(out != data for out in first) >= 18


def test_png_mutations_keep_every_chunk_checksum_right(fuzz):
    data = fuzz.photo_seeds()["gray.png"]
    rng = np.random.default_rng(8)
    for _ in range(30):
        out = fuzz.mutate_png(data, rng, [data])
        at = 8
        while at + 12 <= len(out):
            length = int.from_bytes(out[at : at + 4], "big")
            body = out[at + 4 : at + 8 + length]
            assert zlib.crc32(body).to_bytes(4, "big") == out[at + 8 + length : at + 12 + length]
            at += 12 + length


def test_the_check_reports_other_exceptions_warnings_and_stderr(fuzz, tmp_path, monkeypatch):
    path = tmp_path / "x.png"
    path.write_bytes(b"x")

    def bug(*args, **kwargs):
        raise TypeError("a bug")

    def warns(*args, **kwargs):
        import warnings

        warnings.warn("overflow", RuntimeWarning, stacklevel=1)

    def prints(*args, **kwargs):
        os.write(2, b"libpng warning: IEND: invalid\n")

    def refuses(*args, **kwargs):
        raise ImageReadError("x.png: not a photo")

    expected = {
        bug: "TypeError at ",
        warns: "RuntimeWarning at ",
        prints: "stderr: libpng warning",
        refuses: None,
    }
    for reader, problem in expected.items():
        monkeypatch.setattr(fuzz, "read_image", reader)
        found = fuzz.check("photo", path)
        assert found == problem if problem is None else found.startswith(problem), found
