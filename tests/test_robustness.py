"""Inputs that used to break a run: each gets one clear line, and the batch goes on.

Thin photos, unreadable photos, decoders' own messages, huge exponents, render
sizes and family counts past their budgets, 16-bit photos past the decode
budget, and a reader that goes away (``| head``). Library files: see
test_io_library.py; fuzzing: test_fuzz.py.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tracemalloc
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from rockscan.cli import BROKEN_PIPE_STATUS, main
from rockscan.core.errors import ImageReadError, ParameterError
from rockscan.core.render import MAX_RENDER_PIXELS, RenderConfig, render_photo
from rockscan.core.superformula import SuperformulaParams, shape_radii
from rockscan.io import photos as _imageio
from rockscan.io import read_image

BLUNT = SuperformulaParams(6, 6, 60, 55, 10)


def _rendered(path: Path, rows: int = 120, cols: int = 160, seed: int = 0) -> Path:
    photo = render_photo(BLUNT, RenderConfig(rows=rows, cols=cols, area_fraction=0.2), rng=seed)
    path.write_bytes(photo.encode(path.suffix))
    return path


def _thin(path: Path, cols: int, rows: int) -> Path:
    pixels = (np.random.default_rng(cols).random((rows, cols, 3)) * 255).astype(np.uint8)
    Image.fromarray(pixels).save(path)
    return path


# ---------------------------------------------------------------- thin photos


@pytest.mark.parametrize("suffix", [".jpg", ".png", ".bmp", ".tif"])
@pytest.mark.parametrize(("cols", "rows"), [(3000, 1), (5000, 2), (1, 3000)])
def test_a_thin_photo_reads_at_its_own_size(tmp_path, suffix, cols, rows):
    image = read_image(_thin(tmp_path / f"thin{suffix}", cols, rows), max_side=1024)
    assert image.full_shape == (rows, cols)
    assert min(image.pixels.shape[:2]) == min(rows, cols)  # never reduced to nothing


def test_thin_photos_are_refused_as_too_small_and_the_batch_goes_on(tmp_path):
    thin = [_thin(tmp_path / f"thin{s}", 3000, 1) for s in (".jpg", ".png", ".bmp", ".tif")]
    thin.append(_thin(tmp_path / "thin2.jpg", 5000, 2))
    good = _rendered(tmp_path / "good.png")
    result = CliRunner().invoke(main, ["classify", "--json", *map(str, thin), str(good)])
    assert result.exit_code == 1
    records = [json.loads(line) for line in result.stdout.splitlines()]
    assert [r["path"] for r in records] == [*map(str, thin), str(good)]
    for record in records[:-1]:
        assert "at least 8x8 pixels" in record["error"] and "corrupt" not in record["error"]
    assert records[-1]["nearest"] == "three-faced-blunt"


# ---------------------------------------------------------------- unreadable photos


def test_an_unreadable_photo_is_one_error_line_and_the_batch_goes_on(tmp_path, monkeypatch):
    locked, good = _rendered(tmp_path / "locked.png"), _rendered(tmp_path / "good.png", seed=1)
    real_open = open

    def guarded_open(file, *args, **kwargs):
        if os.fspath(file) == str(locked):
            raise PermissionError(13, "Permission denied", str(locked))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr("builtins.open", guarded_open)
    result = CliRunner().invoke(main, ["classify", "--json", str(locked), str(good)])
    assert result.exit_code == 1
    first, second = (json.loads(line) for line in result.stdout.splitlines())
    assert first == {"path": str(locked), "error": f"{locked}: cannot read (permission denied)"}
    assert second["nearest"] == "three-faced-blunt"


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files of mode 000")
def test_a_photo_of_mode_000_is_one_error_line(tmp_path):
    locked = _rendered(tmp_path / "locked.png")
    locked.chmod(0)
    result = CliRunner().invoke(main, ["classify", str(locked)])
    assert result.exit_code == 1
    assert "cannot read (permission denied)" in result.stdout


# ---------------------------------------------------------------- decoders' own messages


def _png_with_bad_iend(pixels: np.ndarray) -> bytes:
    ok, data = cv2.imencode(".png", pixels)
    assert ok
    data = data.tobytes()
    end = data.rindex(b"IEND")
    return data[: end + 4] + b"junk" + data[end + 8 :]  # an IEND with a body and a wrong CRC


def _tiff_with_a_broken_strip(compression: str) -> bytes:
    """A compressed TIFF with one byte of its strip flipped (libtiff complains)."""
    buffer = io.BytesIO()
    pixels = (np.random.default_rng(0).random((40, 50)) * 255).astype(np.uint8)
    Image.fromarray(pixels).save(buffer, format="TIFF", compression=compression)
    data = bytearray(buffer.getvalue())
    with Image.open(io.BytesIO(bytes(data))) as im:
        offset, size = im.tag_v2[273][0], im.tag_v2[279][0]
    data[offset + size // 2] ^= 0xFF
    return bytes(data)


def _broken_files(folder: Path) -> list[Path]:
    deep = np.full((60, 80, 3), 900, np.uint16)  # dark: OpenCV decodes its 16 bits
    (folder / "iend.png").write_bytes(_png_with_bad_iend(deep))
    (folder / "zip.tif").write_bytes(_tiff_with_a_broken_strip("tiff_adobe_deflate"))
    (folder / "lzw.tif").write_bytes(_tiff_with_a_broken_strip("tiff_lzw"))
    return [folder / "iend.png", folder / "zip.tif", folder / "lzw.tif"]


def test_decoders_print_nothing_about_a_broken_file(tmp_path, capfd):
    for path in _broken_files(tmp_path):
        try:
            read_image(path, max_side=16)
        except ImageReadError:
            pass
    captured = capfd.readouterr()
    assert captured.err == "" and captured.out == ""


def test_a_classify_run_on_broken_files_writes_only_its_error_lines(tmp_path):
    broken = [str(p) for p in _broken_files(tmp_path)]
    code = "import sys; from rockscan.cli import main; sys.exit(main())"
    out = subprocess.run(
        [sys.executable, "-c", code, "classify", "--json", *broken], capture_output=True, text=True
    )
    records = [json.loads(line) for line in out.stdout.splitlines()]
    assert [r["path"] for r in records] == broken
    # Each error row is also one line on stderr, and nothing else is (no decoder noise).
    lines = out.stderr.splitlines()
    assert len(lines) == len(records)
    for line, r in zip(lines, records, strict=True):
        assert line.startswith(f"rockscan: error: {r['path']}: ") and line.endswith(r["error"])
    assert all("truncated or corrupt" in r["error"] for r in records[1:])


def test_huge_exponents_are_refused_without_numpy_warnings():
    # pyproject turns warnings into errors: a RuntimeWarning would fail here.
    for params in [(4, 4, 1e-300, 1e300, 1e300), (4, 4, 1e300, 1e300, 1e300), (1e300, 1e300, 2, 2, 2)]:
        try:
            shape_radii(SuperformulaParams(*params), 360)
        except ParameterError as exc:
            assert "unbounded or degenerate" in str(exc)


# ---------------------------------------------------------------- budgets before the work


def test_render_sizes_past_the_budget_are_refused_before_drawing(tmp_path):
    tracemalloc.start()
    try:
        result = CliRunner().invoke(main, ["render", "-o", str(tmp_path), "--size", "100000x100000"])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert result.exit_code == 2
    assert f"over the {MAX_RENDER_PIXELS:,} rockscan draws" in result.output
    assert peak < 50 * 2**20
    assert list(tmp_path.iterdir()) == []


def test_family_counts_past_the_budget_are_refused_before_the_values_are_made(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text('[[shape]]\nname = "egg"\nm1 = 1\nm2 = 1\nn1 = 0.5\nn2 = 0.5\nn3 = 0.5\n')
    tracemalloc.start()
    try:
        args = [
            "library",
            "family",
            str(spec),
            "egg",
            "--vary",
            "n1=0.8:1.2:10000000000",
            "-o",
            str(tmp_path / "f.toml"),
        ]
        result = CliRunner().invoke(main, args)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert result.exit_code == 2
    assert "COUNT must be at most 1001" in result.output
    assert peak < 50 * 2**20


def _dark_png16(path: Path, rows: int, cols: int) -> Path:
    """An all-dark 16-bit RGBA PNG written a row at a time (it deflates to almost nothing)."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        return len(body).to_bytes(4, "big") + kind + body + zlib.crc32(kind + body).to_bytes(4, "big")

    header = rows.to_bytes(4, "big")
    ihdr = cols.to_bytes(4, "big") + header + bytes([16, 6, 0, 0, 0])
    compressor = zlib.compressobj(9)
    row = b"\0" + (np.array([20, 20, 20, 900], ">u2").tobytes() * cols)
    body = b"".join(compressor.compress(row) for _ in range(rows)) + compressor.flush()
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", body) + chunk(b"IEND", b""))
    return path


def test_a_sixteen_bit_photo_past_the_decode_budget_is_read_at_eight_bits(tmp_path, monkeypatch):
    path = _dark_png16(tmp_path / "dark.png", 300, 400)
    assert read_image(path, max_side=64).pixels.dtype == np.uint16  # within the budget: 16 bits
    monkeypatch.setattr(_imageio, "MAX_DEEP_BYTES", 300 * 400 * 16 - 1)

    def whole_frame(*args):
        raise AssertionError("decoded the whole 16-bit frame")

    monkeypatch.setattr(_imageio, "_decode_deep", whole_frame)
    image = read_image(path, max_side=64)
    assert image.pixels.dtype == np.uint8 and image.bit_depth == 16 and image.scale == 6.0


# ---------------------------------------------------------------- a reader that goes away


def test_a_closed_pipe_ends_classify_quietly_with_the_sigpipe_status(tmp_path):
    photos = [str(_rendered(tmp_path / f"p{i}.png", 64, 80, seed=i)) for i in range(12)]
    code = "import sys; from rockscan.cli import main; sys.exit(main())"
    proc = subprocess.Popen(
        [sys.executable, "-c", code, "classify", *photos], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    assert proc.stdout.readline().startswith(b"photo")  # the header, then the reader leaves
    proc.stdout.close()
    with proc.stderr:
        stderr = proc.stderr.read()
    assert proc.wait() == BROKEN_PIPE_STATUS == 141
    assert stderr == b""
