"""Peak memory of reading the worst library file of at most 10 MB and the worst photos.

Each case is read in a fresh interpreter, which prints its peak resident set
size (``ru_maxrss``); the table gives it beside that of an interpreter that only
imported rockscan and read a tiny photo and library (the baseline), and the
seconds the read took (wall clock, on whatever else the machine is doing).

Library files (the reader checks sizes before it inflates, rockscan/io/_npzsafe.py):

* ``bomb-declared``: a member of zeros declaring 4 GiB, deflated;
* ``bomb-ratio``: a member of zeros within the budget, deflated a thousandfold;
* ``bomb-at-budget``: a member of random bytes that fills the budget (256 MiB),
  deflated as far as random bytes go (not at all): the most any file makes
  rockscan allocate, and a file of 256 MiB, not 10 MB;
* ``stored-10MB``: a library file of 10 MB as rockscan stores them;
* ``header-745GiB``: an ``.npy`` header claiming 745 GiB.

Photos (read as ``classify`` reads them, reduced for a 1024-pixel work size):

* ``dark16-14000``: an all-dark 16-bit RGBA PNG of 14000 x 14000 (1.5 MB);
* ``rgba-200MP``: an 8-bit RGBA PNG at the 200-million-pixel limit;
* ``jpeg-8000``: an 8000 x 8000 JPEG;
* ``float-tiff-3800``, ``float-tiff-6000``: colour TIFFs of 32-bit float samples,
  3800 x 3800 (165 MiB, read) and 6000 x 6000 (412 MiB, refused from its directory).

Run ``python scripts/bench_memory.py --help``; the photos take a minute to write.
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
import tempfile
import zipfile
import zlib
from pathlib import Path

import numpy as np
from PIL import Image

from rockscan.core.library import Library, ShapeSpec
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import save_library
from rockscan.io._npzsafe import MAX_ARCHIVE_BYTES

_READ = """
import resource, sys, time
from rockscan.core.errors import RockscanError
from rockscan.io import load_library, read_image
import rockscan.core.library, rockscan.core.eigen  # what load_library imports: not part of the read
start = time.perf_counter()
try:
    if sys.argv[1] == "library":
        load_library(sys.argv[2])
    else:
        read_image(sys.argv[2], max_side=1024)
    outcome = "read"
except RockscanError as exc:
    outcome = "refused: " + str(exc).split(": ", 1)[1][:60]
seconds = time.perf_counter() - start
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, seconds, outcome, sep="\\t")
"""


def _npy_header(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    text = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape!r}, }}".encode()
    text += b" " * (-(len(text) + 11) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + len(text).to_bytes(2, "little") + text


def _zeros_member(archive: zipfile.ZipFile, name: str, shape: tuple[int, ...]) -> None:
    """A deflated .npy member of zeros, written in pieces (never whole in memory)."""
    info = zipfile.ZipInfo(name)
    info.compress_type = zipfile.ZIP_DEFLATED
    with archive.open(info, "w", force_zip64=True) as member:
        member.write(_npy_header(shape))
        left = int(np.prod(shape)) * 8
        block = bytes(1 << 20)
        while left:
            member.write(block[: min(left, len(block))])
            left -= min(left, len(block))


def _small_members(folder: Path) -> dict[str, bytes]:
    shapes = [
        ShapeSpec("a", SuperformulaParams(4, 4, 2, 2, 2)),
        ShapeSpec("b", SuperformulaParams(5, 5, 2, 7, 7)),
    ]
    path = folder / "small.npz"
    save_library(Library.from_shapes(shapes), path)
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def library_cases(folder: Path) -> dict[str, Path]:
    members = _small_members(folder)
    cases = {}
    path = folder / "bomb-declared.npz"
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            if name != "components.npy":
                archive.writestr(name, content)
        _zeros_member(archive, "components.npy", (2**15, 2**14))  # 4 GiB
    cases["bomb-declared"] = path
    path = folder / "bomb-ratio.npz"
    rows = (MAX_ARCHIVE_BYTES - 2**20) // (18000 * 8)
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            if name != "components.npy":
                archive.writestr(name, content)
        _zeros_member(archive, "components.npy", (rows, 18000))
    cases["bomb-ratio"] = path
    for name, rows in (("bomb-at-budget", (MAX_ARCHIVE_BYTES - 2**20) // (18000 * 8)), ("stored-10MB", 72)):
        path = folder / f"{name}.npz"
        noise = np.random.default_rng(1).random((rows, 18000))
        with zipfile.ZipFile(path, "w") as archive:
            for member, content in members.items():
                if member != "components.npy":
                    archive.writestr(member, content)
            archive.writestr("components.npy", _npy_header(noise.shape) + noise.tobytes())
        cases[name] = path
    path = folder / "header-745GiB.npz"
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content if name != "mean.npy" else _npy_header((100000, 1000000)))
    cases["header-745GiB"] = path
    return cases


def _png(path: Path, rows: int, cols: int, sample: bytes, bit_depth: int) -> Path:
    """An RGBA PNG of one repeated pixel, written a row at a time."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        return len(body).to_bytes(4, "big") + kind + body + zlib.crc32(kind + body).to_bytes(4, "big")

    ihdr = cols.to_bytes(4, "big") + rows.to_bytes(4, "big") + bytes([bit_depth, 6, 0, 0, 0])
    compressor = zlib.compressobj(1)
    row = b"\0" + sample * cols
    with open(path, "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr))
        pieces = []
        for _ in range(rows):
            pieces.append(compressor.compress(row))
        pieces.append(compressor.flush())
        fh.write(chunk(b"IDAT", b"".join(pieces)) + chunk(b"IEND", b""))
    return path


def photo_cases(folder: Path) -> dict[str, Path]:
    dark = np.array([20, 20, 20, 900], ">u2").tobytes()
    cases = {"dark16-14000": _png(folder / "dark16.png", 14000, 14000, dark, 16)}
    cases["rgba-200MP"] = _png(folder / "rgba.png", 12500, 16000, bytes([90, 120, 60, 255]), 8)
    rng = np.random.default_rng(0)
    small = (rng.random((500, 500, 3)) * 255).astype(np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(small).resize((8000, 8000)).save(buffer, format="JPEG", quality=90)
    (folder / "big.jpg").write_bytes(buffer.getvalue())
    cases["jpeg-8000"] = folder / "big.jpg"
    # Colour TIFFs of float samples, which OpenCV decodes: one within the budget, one beyond.
    import cv2

    for name, side in (("float-tiff-3800", 3800), ("float-tiff-6000", 6000)):
        samples = np.full((side, side, 3), 0.8, np.float32)
        cv2.circle(samples, (side // 2, side // 2), side // 4, (0.2, 0.25, 0.3), -1)
        path = folder / f"{name}.tif"
        cv2.imwrite(str(path), samples)
        del samples
        cases[name] = path
    return cases


def measure(kind: str, path: Path) -> tuple[float, float, str]:
    out = subprocess.run(
        [sys.executable, "-c", _READ, kind, str(path)], capture_output=True, text=True, check=True
    )
    rss, seconds, outcome = out.stdout.strip().split("\t")
    return int(rss) / 1024, float(seconds), outcome


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-photos", action="store_true", help="library files only (fast)")
    parser.add_argument("--make", type=Path, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.make is not None:
        # Writing the cases takes memory; a process that did would pass its high-water
        # mark on to the readers it starts, so the files are made in a process of their own.
        cases = library_cases(args.make) | ({} if args.no_photos else photo_cases(args.make))
        tiny = args.make / "tiny.png"
        Image.fromarray(np.zeros((16, 16), np.uint8)).save(tiny)
        print("\n".join(f"{name}\t{path}" for name, path in cases.items()))
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        command = [
            sys.executable,
            __file__,
            "--make",
            str(folder),
            *(["--no-photos"] if args.no_photos else []),
        ]
        made = subprocess.run(command, capture_output=True, text=True, check=True).stdout.split("\n")
        cases = dict(line.split("\t") for line in made if line)
        base = measure("photo", folder / "tiny.png")[0]
        print(f"baseline (interpreter, rockscan imported, a tiny photo read): {base:.0f} MB")
        print(f"{'case':<16} {'file MB':>8} {'peak MB':>8} {'over base':>9} {'seconds':>8}  outcome")
        for name, path in cases.items():
            kind = "library" if path.endswith(".npz") else "photo"
            peak, seconds, outcome = measure(kind, Path(path))
            size = Path(path).stat().st_size / 2**20
            print(f"{name:<16} {size:>8.2f} {peak:>8.0f} {peak - base:>9.0f} {seconds:>8.2f}  {outcome}")


if __name__ == "__main__":
    main()
