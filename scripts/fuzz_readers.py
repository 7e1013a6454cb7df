"""Fuzz the photo and library readers: every input decodes or raises a RockscanError.

Seeds are made here: rendered photos written as PNG (8 and 16 bits, gray, RGB,
RGBA), JPEG, TIFF (raw, LZW, deflate) and BMP, and small library files (as
saved, and deflated). A seeded mutator flips bits, writes boundary integers,
cuts, repeats, inserts and splices bytes, and also edits the insides that a
checksum would otherwise guard: PNG chunks (their CRCs made right again), TIFF
directory entries, and the
``.npy`` headers and metadata of library archives (re-zipped). Each input is read
with :func:`rockscan.io.read_image` (as ``classify`` reads a photo) or
:func:`rockscan.io.load_library`. A finding is any other exception, a Python
warning, or text a decoder wrote to the process's stderr.

tests/test_fuzz.py runs a few hundred inputs of one fixed seed; this script runs
for a given time and prints what it found, grouped::

    nice python scripts/fuzz_readers.py --minutes 5 --save fuzz-findings
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import tempfile
import time
import traceback
import warnings
import zipfile
import zlib
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from rockscan.core.errors import RockscanError
from rockscan.core.information import FaceConfig
from rockscan.core.library import Library, ShapeSpec
from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import load_library, read_image, save_library
from rockscan.io.library import RecalibratedWarning

#: Byte values and integers at the edges where parsers break.
_BYTES = (0x00, 0x01, 0x7F, 0x80, 0xFE, 0xFF)
_INTS = (0, 1, 2, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF)
#: The work size classify decodes photos for (twice SegmentConfig.work_size).
MAX_SIDE = 1024


@dataclass(frozen=True)
class Finding:
    """One input that broke a reader: which seed, and what happened."""

    kind: str
    seed: str
    problem: str
    data: bytes


def photo_seeds() -> dict[str, bytes]:
    """Small photos in every format and layout the reader takes."""
    params = SuperformulaParams(5, 5, 2, 7, 7)
    photo = render_photo(params, RenderConfig(rows=24, cols=32, area_fraction=0.3), rng=[9, 0])
    rgb = photo.pixels if photo.pixels.ndim == 3 else np.dstack([photo.pixels] * 3)
    gray = rgb.mean(axis=2).astype(np.uint8)
    seeds = {f"photo{suffix}": photo.encode(suffix) for suffix in (".png", ".jpg", ".tif", ".bmp")}
    images = {
        "gray.png": Image.fromarray(gray),
        "rgba.png": Image.fromarray(np.dstack([rgb, np.full(gray.shape, 200, np.uint8)])),
        "gray16.png": Image.fromarray(gray.astype(np.uint16) * 257),
        "palette.png": Image.fromarray(rgb).quantize(8),
        "lzw.tif": Image.fromarray(rgb),
        "deflate.tif": Image.fromarray(gray),
        "gray.bmp": Image.fromarray(gray),
        "progressive.jpg": Image.fromarray(rgb),
    }
    options = {"lzw.tif": {"compression": "tiff_lzw"}, "deflate.tif": {"compression": "tiff_adobe_deflate"}}
    options["progressive.jpg"] = {"progressive": True, "quality": 80}
    for name, image in images.items():
        buffer = io.BytesIO()
        image.save(buffer, format=_format(name), **options.get(name, {}))
        seeds[name] = buffer.getvalue()
    seeds["rgb16.png"] = _png16(rgb)
    # Colour TIFFs of floating-point samples, which Pillow cannot read and OpenCV decodes.
    bgr = rgb[..., ::-1].astype(np.float32) / 255.0
    seeds["float.tif"] = _tiff(bgr)
    seeds["float-rgba.tif"] = _tiff(np.dstack([bgr, np.full(gray.shape, 0.8, np.float32)]))
    return seeds


def _tiff(samples: np.ndarray) -> bytes:
    """A TIFF of ``samples`` (BGR order) as OpenCV writes it."""
    import cv2

    ok, data = cv2.imencode(".tiff", samples)
    assert ok
    return data.tobytes()


def library_seeds() -> dict[str, bytes]:
    """Small library files: as saved, and with every member deflated."""
    shapes = [
        ShapeSpec("circle", SuperformulaParams(4, 4, 2, 2, 2)),
        ShapeSpec("star", SuperformulaParams(5, 5, 2, 7, 7)),
        ShapeSpec("square-ish", SuperformulaParams(4, 4, 12, 15, 15), interest=2.0),
    ]
    library = Library.from_shapes(shapes, face_config=FaceConfig(n_angles=16, resolution=0.25))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "small.npz"
        save_library(library, path)
        stored = path.read_bytes()
    return {"library.npz": stored, "deflated.npz": _rezip(_members(stored), zipfile.ZIP_DEFLATED)}


def _format(name: str) -> str:
    return {"png": "PNG", "tif": "TIFF", "bmp": "BMP", "jpg": "JPEG"}[name.rsplit(".", 1)[1]]


def _png16(rgb: np.ndarray) -> bytes:
    import cv2

    ok, data = cv2.imencode(".png", (rgb[..., ::-1].astype(np.uint16) * 257))
    assert ok
    return data.tobytes()


def _members(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def _rezip(members: dict[str, bytes], method: int) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=method) as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    return buffer.getvalue()


def mutate(data: bytes, rng: np.random.Generator, others: list[bytes]) -> bytes:
    """One to four random byte-level edits of ``data``."""
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 5))):
        if not out:
            out = bytearray(rng.bytes(8))
        at = int(rng.integers(0, len(out)))
        op = int(rng.integers(0, 8))
        if op == 0:
            out[at] ^= 1 << int(rng.integers(0, 8))
        elif op == 1:
            out[at] = _BYTES[int(rng.integers(0, len(_BYTES)))]
        elif op == 2:
            width = int(rng.choice([2, 4]))
            value = _INTS[int(rng.integers(0, len(_INTS)))] & ((1 << (8 * width)) - 1)
            order = "big" if rng.random() < 0.5 else "little"
            out[at : at + width] = value.to_bytes(width, order)
        elif op == 3:
            del out[at : at + int(rng.integers(1, 64))]
        elif op == 4:
            span = bytes(out[at : at + int(rng.integers(1, 64))])
            out[at:at] = span * int(rng.integers(1, 4))
        elif op == 5:
            out[at:at] = rng.bytes(int(rng.integers(1, 32)))
        elif op == 6:
            out = out[: max(1, at)]
        else:
            other = others[int(rng.integers(0, len(others)))]
            cut = int(rng.integers(0, len(other)))
            out = out[:at] + other[cut : cut + int(rng.integers(1, 512))] + out[at:]
    return bytes(out)


def mutate_png(data: bytes, rng: np.random.Generator, others: list[bytes]) -> bytes:
    """Edit one chunk's body and make every chunk's CRC right again, so decoders read on."""
    chunks = list(_png_chunks(data))
    if not chunks:
        return mutate(data, rng, others)
    i = int(rng.integers(0, len(chunks)))
    kind, body = chunks[i]
    chunks[i] = (kind, mutate(body, rng, others) if body else rng.bytes(4))
    out = bytearray(data[:8])
    for kind, body in chunks:
        out += len(body).to_bytes(4, "big") + kind + body
        out += zlib.crc32(kind + body).to_bytes(4, "big")
    return bytes(out)


def mutate_tiff(data: bytes, rng: np.random.Generator, others: list[bytes]) -> bytes:
    """Overwrite the tag, type, count or value of entries of the first directory."""
    order = "little" if data[:2] == b"II" else "big"
    start = int.from_bytes(data[4:8], order)
    if start + 2 > len(data):
        return mutate(data, rng, others)
    entries = int.from_bytes(data[start : start + 2], order)
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 4))):
        entry = start + 2 + 12 * int(rng.integers(0, max(1, entries)))
        field, width = [(0, 2), (2, 2), (4, 4), (8, 4)][int(rng.integers(0, 4))]
        value = _INTS[int(rng.integers(0, len(_INTS)))] if rng.random() < 0.7 else int(rng.integers(0, 20))
        if entry + field + width <= len(out):
            out[entry + field : entry + field + width] = (value & ((1 << (8 * width)) - 1)).to_bytes(
                width, order
            )
    return bytes(out)


def _png_chunks(data: bytes) -> Iterator[tuple[bytes, bytes]]:
    at = 8
    while at + 12 <= len(data):
        length = int.from_bytes(data[at : at + 4], "big")
        yield data[at + 4 : at + 8], data[at + 8 : at + 8 + length]
        at += 12 + length


def mutate_npz(data: bytes, rng: np.random.Generator, others: list[bytes]) -> bytes:
    """Edit one member's header or the metadata, then zip it again (CRCs right)."""
    members = _members(data)
    name = list(members)[int(rng.integers(0, len(members)))]
    content = members[name]
    if name == "metadata.npy" or rng.random() < 0.5:
        # Within the first 200 bytes: the .npy header, or the metadata JSON.
        head = min(len(content), 200 if name != "metadata.npy" else len(content))
        content = mutate(content[:head], rng, others) + content[head:]
    else:
        content = mutate(content, rng, others)
    members[name] = content
    method = zipfile.ZIP_DEFLATED if rng.random() < 0.3 else zipfile.ZIP_STORED
    return _rezip(members, method)


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[bytes]]:
    """What C code writes to file descriptor 2 meanwhile (Python's stderr included)."""
    found: list[bytes] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield found
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            found.append(sink.read())


def check(kind: str, path: Path) -> str | None:
    """None if ``path`` reads or fails with a RockscanError; else what went wrong."""
    with _captured_stderr() as noise, warnings.catch_warnings():
        warnings.simplefilter("error")
        # The message rockscan gives by design for a library of an earlier
        # calibration (a fuzzed version field makes one) is no finding.
        warnings.simplefilter("ignore", RecalibratedWarning)
        try:
            if kind == "photo":
                read_image(path, max_side=MAX_SIDE)
            else:
                load_library(path)
            problem = None
        except RockscanError:
            problem = None
        except Exception as exc:
            frame = traceback.extract_tb(exc.__traceback__)[-1]
            where = f"{Path(frame.filename).name}:{frame.lineno}"
            problem = f"{type(exc).__name__} at {where}: {str(exc).splitlines()[0] if str(exc) else ''}"
    if problem is None and noise and noise[0].strip():
        problem = f"stderr: {noise[0].decode(errors='replace').strip().splitlines()[0]}"
    return problem


def fuzz(
    *, count: int | None = None, seconds: float | None = None, seed: int = 0, folder: Path | None = None
) -> tuple[int, list[Finding]]:
    """Read mutated seeds until ``count`` inputs or ``seconds`` have passed.

    Returns
    -------
    tried : int
    findings : list of Finding
    """
    rng = np.random.default_rng(seed)
    seeds = {"photo": photo_seeds(), "library": library_seeds()}
    pool = [data for group in seeds.values() for data in group.values()]
    findings: list[Finding] = []
    deadline = None if seconds is None else time.monotonic() + seconds
    tried = 0
    with tempfile.TemporaryDirectory() as tmp:
        while (count is None or tried < count) and (deadline is None or time.monotonic() < deadline):
            kind = "photo" if rng.random() < 0.6 else "library"
            names = sorted(seeds[kind])
            name = names[int(rng.integers(0, len(names)))]
            data = seeds[kind][name]
            if kind == "library" and rng.random() < 0.6:
                data = mutate_npz(data, rng, pool)
            elif name.endswith(".png") and rng.random() < 0.5:
                data = mutate_png(data, rng, pool)
            elif name.endswith(".tif") and rng.random() < 0.5:
                data = mutate_tiff(data, rng, pool)
            else:
                data = mutate(data, rng, pool)
            path = Path(tmp) / f"input{Path(name).suffix}"
            path.write_bytes(data)
            problem = check(kind, path)
            tried += 1
            if problem is not None:
                findings.append(Finding(kind, name, problem, data))
                if folder is not None:
                    folder.mkdir(parents=True, exist_ok=True)
                    (folder / f"{len(findings):04d}-{name}").write_bytes(data)
    return tried, findings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=5.0, help="how long to run (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--save", type=Path, default=None, help="folder for the inputs that broke a reader")
    args = parser.parse_args()
    tried, findings = fuzz(seconds=args.minutes * 60, seed=args.seed, folder=args.save)
    print(f"inputs read: {tried:,}; findings: {len(findings):,}")
    for problem, n in Counter(f"{f.kind}: {f.problem}" for f in findings).most_common():
        print(f"{n:6d}  {problem}")
    sys.exit(1 if findings else 0)


if __name__ == "__main__":
    main()
