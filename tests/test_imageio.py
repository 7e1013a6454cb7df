"""Photo input: formats, modes, bit depths, EXIF orientation, reduced decoding, bad files."""

from __future__ import annotations

import io
import logging
import os
import struct
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image, ImageOps

from rockscan.core.errors import ImageReadError, ParameterError
from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import IMAGE_SUFFIXES, read_image
from rockscan.run.pipeline import classify_path

TEARDROP = SuperformulaParams(1, 1, 0.5, 0.5, 0.5)
BLUNT = SuperformulaParams(6, 6, 60, 55, 10)


def _photo(mode: str, depth: int, rows: int = 48, cols: int = 64) -> np.ndarray:
    """A small rendered photo as gray, RGB or RGBA (with a varying alpha), 8 or 16 bits."""
    config = RenderConfig(rows=rows, cols=cols, color=mode != "gray", bit_depth=depth, area_fraction=0.2)
    pixels = render_photo(BLUNT, config, rng=3).pixels
    if mode == "rgba":
        top = np.iinfo(pixels.dtype).max
        alpha = np.linspace(top // 3, top, rows * cols).reshape(rows, cols).astype(pixels.dtype)
        pixels = np.dstack([pixels, alpha])
    return pixels


def _bmp_with_alpha(pixels: np.ndarray) -> bytes:
    """A 32-bit BMP whose fourth channel is alpha (a V4 header with an alpha mask).

    Pillow stores a fourth BMP channel as padding, and OpenCV before 4.9 too."""
    rows, cols, _ = pixels.shape
    header = struct.pack(
        "<IiiHHIIiiII4I",
        108,
        cols,
        rows,
        1,
        32,
        3,
        rows * cols * 4,
        2835,
        2835,
        0,
        0,
        0x00FF0000,
        0x0000FF00,
        0x000000FF,
        0xFF000000,
    )
    header += struct.pack("<I", 0x73524742) + b"\0" * 48  # sRGB: no end points or gamma
    body = np.ascontiguousarray(pixels[::-1][..., [2, 1, 0, 3]]).tobytes()
    offset = 14 + len(header)
    return b"BM" + struct.pack("<IHHI", offset + len(body), 0, 0, offset) + header + body


def _write(path: Path, pixels: np.ndarray, **save: object) -> Path:
    """Write with Pillow, or with OpenCV where Pillow cannot: 16-bit colour; BMP with
    alpha by hand."""
    if path.suffix == ".bmp" and pixels.ndim == 3 and pixels.shape[2] == 4:
        path.write_bytes(_bmp_with_alpha(pixels))
    elif pixels.ndim == 3 and pixels.dtype == np.uint16:
        order = [2, 1, 0] if pixels.shape[2] == 3 else [2, 1, 0, 3]
        assert cv2.imwrite(str(path), np.ascontiguousarray(pixels[..., order]))
    else:
        Image.fromarray(pixels).save(path, **save)
    return path


LOSSLESS = [
    (suffix, mode, depth)
    for suffix in (".png", ".tif", ".bmp")
    for mode in ("gray", "rgb", "rgba")
    for depth in (8, 16)
    if not (suffix == ".bmp" and depth == 16)
]


@pytest.mark.parametrize(("suffix", "mode", "depth"), LOSSLESS)
def test_lossless_formats_read_back_exactly(tmp_path, suffix, mode, depth):
    pixels = _photo(mode, depth)
    image = read_image(_write(tmp_path / f"p{suffix}", pixels))
    assert image.pixels.dtype == pixels.dtype
    assert image.bit_depth == depth
    np.testing.assert_array_equal(image.pixels, pixels)
    assert image.scale == 1.0
    assert image.full_shape == pixels.shape[:2]


@pytest.mark.parametrize("mode", ["gray", "rgb"])
def test_jpeg_reads_as_pillow_decodes_it(tmp_path, mode):
    pixels = _photo(mode, 8)
    path = _write(tmp_path / "p.jpg", pixels, quality=90)
    image = read_image(path)
    np.testing.assert_array_equal(image.pixels, np.asarray(Image.open(path)))
    # Quality 90 with halved chroma keeps a noisy photo within a few levels on average.
    assert np.abs(image.pixels.astype(int) - pixels).mean() < 6.0


def test_suffixes_cover_the_interface_formats():
    # The formats the interface names, and JPEG's other names (.jpe, .jfif: browsers' downloads).
    assert set(IMAGE_SUFFIXES) == {".png", ".jpg", ".jpeg", ".jpe", ".jfif", ".tif", ".tiff", ".bmp"}


def test_palette_and_one_bit_photos_become_rgba_and_gray(tmp_path):
    pixels = _photo("rgb", 8)
    palette = Image.fromarray(pixels).quantize(16)
    palette.info["transparency"] = 0
    palette.save(tmp_path / "p.png")
    image = read_image(tmp_path / "p.png")
    assert image.pixels.shape == (*pixels.shape[:2], 4)
    np.testing.assert_array_equal(image.pixels, np.asarray(Image.open(tmp_path / "p.png").convert("RGBA")))
    Image.fromarray(pixels[..., 0] > 128).save(tmp_path / "b.bmp")
    binary = read_image(tmp_path / "b.bmp").pixels
    assert binary.dtype == np.uint8
    np.testing.assert_array_equal(binary > 0, pixels[..., 0] > 128)


# ---------------------------------------------------------------- TIFFs of wide samples


def _tiff(samples: np.ndarray, *, order: str = "<", orientation: int = 1, size=None) -> bytes:
    """An uncompressed classic TIFF of float32 RGB(A) ``samples`` (rows, cols, 3|4),
    written by hand so that byte order and orientation can be chosen; ``size``
    (rows, cols) puts that size in the directory and no pixels after it."""
    rows, cols, spp = samples.shape if size is None else (*size, 3)
    data = b"" if size is None else None
    if size is None:
        data = samples.astype(order + "f4").tobytes()
    tags = [
        (256, 4, 1, cols),
        (257, 4, 1, rows),
        (258, 3, spp, None),  # 32 bits a sample, stored after the directory
        (259, 3, 1, 1),
        (262, 3, 1, 2),
        (273, 4, 1, None),  # the pixels' offset
        (274, 3, 1, orientation),
        (277, 3, 1, spp),
        (278, 4, 1, rows),
        (279, 4, 1, rows * cols * spp * 4),
        (284, 3, 1, 1),
        (339, 3, spp, None),  # IEEE floating point, stored after the directory
    ]
    directory = 8
    extra = directory + 2 + 12 * len(tags) + 4
    bits_at, format_at, pixels_at = extra, extra + 2 * spp, extra + 4 * spp
    head = (b"II" if order == "<" else b"MM") + struct.pack(order + "HI", 42, directory)
    body = struct.pack(order + "H", len(tags))
    for tag, kind, count, value in tags:
        value = {258: bits_at, 273: pixels_at, 339: format_at}.get(tag, value)
        # Values that do not fit in the entry (a short per sample) are pointed to.
        inline = kind == 3 and count * 2 <= 4
        packed = struct.pack(order + ("H" if inline else "I"), min(value, 2**32 - 1))
        body += struct.pack(order + "HHI", tag, kind, count) + packed.ljust(4, b"\0")
    body += struct.pack(order + "I", 0)
    body += struct.pack(order + "H" * spp, *[32] * spp) + struct.pack(order + "H" * spp, *[3] * spp)
    return head + body + (data or b"")


@pytest.mark.parametrize("order", ["<", ">"])
def test_a_colour_tiff_of_floating_point_samples_reads_as_16_bits_over_its_range(tmp_path, order):
    # Pillow reads gray floating-point TIFFs only; OpenCV decodes colour ones. Values
    # k/255 over [0, 1] become k * 257 exactly, as an 8-bit photo's 16-bit twin.
    # Written uncompressed by hand: OpenCV itself writes float colour as lossy
    # LogLuv in some releases.
    pixels = _photo("rgb", 8)
    pixels[0, 0] = (0, 0, 255)
    pixels[0, 1] = (255, 255, 255)
    (tmp_path / "f.tif").write_bytes(_tiff(pixels.astype(np.float32) / 255, order=order))
    image = read_image(tmp_path / "f.tif")
    assert image.pixels.dtype == np.uint16 and image.bit_depth == 16
    np.testing.assert_array_equal(image.pixels, pixels.astype(np.uint16) * 257)


def test_floating_point_samples_at_float32s_limits_scale_without_overflow(tmp_path):
    samples = np.zeros((20, 30, 3), np.float32)
    samples[0, 0], samples[0, 1] = -3.0e38, 3.0e38
    (tmp_path / "x.tif").write_bytes(_tiff(samples))
    pixels = read_image(tmp_path / "x.tif").pixels
    assert pixels[0, 0].tolist() == [0, 0, 0] and pixels[0, 1].tolist() == [65535] * 3
    assert np.all(pixels[1:] == 32768)


def test_a_colour_tiff_as_opencv_writes_floats_reads(tmp_path):
    # Whatever OpenCV's release writes (uncompressed, or lossy LogLuv at about 1%).
    pixels = _photo("rgb", 8)
    assert cv2.imwrite(str(tmp_path / "f.tif"), pixels[..., ::-1].astype(np.float32) / 255)
    got = read_image(tmp_path / "f.tif").pixels.astype(float)
    want = pixels.astype(float) * 257
    assert got.shape == want.shape
    assert np.corrcoef(got.ravel(), want.ravel())[0, 1] > 0.99


def test_a_colour_tiff_of_32_bit_integers_and_one_with_alpha_read(tmp_path):
    pixels = _photo("rgb", 8)
    pixels[0, :2] = ((0, 0, 0), (255, 255, 255))
    assert cv2.imwrite(str(tmp_path / "i.tif"), pixels[..., ::-1].astype(np.int32) * 1000)
    np.testing.assert_array_equal(read_image(tmp_path / "i.tif").pixels, pixels.astype(np.uint16) * 257)
    alpha = np.linspace(0.0, 1.0, pixels[..., 0].size, dtype=np.float32).reshape(pixels.shape[:2])
    bgra = np.dstack([pixels[..., ::-1].astype(np.float32) / 255, alpha])
    assert cv2.imwrite(str(tmp_path / "a.tif"), bgra)
    image = read_image(tmp_path / "a.tif").pixels
    assert image.shape == (*pixels.shape[:2], 4)
    np.testing.assert_array_equal(image[..., :3], pixels.astype(np.uint16) * 257)
    np.testing.assert_array_equal(image[..., 3], np.round(alpha * 65535).astype(np.uint16))


@pytest.mark.parametrize("orientation", [1, 3, 6, 8])
def test_a_floating_point_colour_tiff_is_turned_upright_by_its_orientation_tag(tmp_path, orientation):
    upright = _photo("rgb", 8, rows=30, cols=52)
    upright[0, :2] = ((0, 0, 0), (255, 255, 255))
    stored = (
        np.asarray(Image.fromarray(upright).transpose(_STORED[orientation])) if orientation != 1 else upright
    )
    (tmp_path / "o.tif").write_bytes(_tiff(stored.astype(np.float32) / 255, orientation=orientation))
    image = read_image(tmp_path / "o.tif")
    np.testing.assert_array_equal(image.pixels, upright.astype(np.uint16) * 257)
    assert image.full_shape == upright.shape[:2]


def test_a_floating_point_colour_tiff_is_reduced_and_classified(tmp_path, default_lib):
    photo = render_photo(TEARDROP, RenderConfig(rows=240, cols=320, color=True, area_fraction=0.2), rng=5)
    path = tmp_path / "f.tif"
    assert cv2.imwrite(str(path), photo.pixels[..., ::-1].astype(np.float32) / 255)
    reduced = read_image(path, max_side=100)
    assert reduced.scale == 3 and reduced.pixels.shape == (80, 106, 3)
    as_png = tmp_path / "f.png"
    Image.fromarray(photo.pixels).save(as_png)
    got, want = classify_path(path, default_lib), classify_path(as_png, default_lib)
    assert got.ok and want.ok, (got.error, want.error)
    # The same photo in 16 bits: the same rock, matched alike.
    (a,), (b,) = got.rocks, want.rocks
    assert a.match.nearest == b.match.nearest
    np.testing.assert_allclose(a.centroid_xy, b.centroid_xy, atol=0.5)
    assert abs((a.match.angle_deg - b.match.angle_deg + 180) % 360 - 180) < 2.0


@pytest.mark.parametrize(
    ("size", "message"),
    [((20000, 20000), "larger than 200,000,000 pixels"), ((9000, 9000), "too large to decode")],
)
def test_a_floating_point_colour_tiff_too_large_is_refused_before_decoding(tmp_path, size, message):
    # The directory alone says how large the photo is: no pixels follow it.
    path = tmp_path / "big.tif"
    path.write_bytes(_tiff(np.zeros((1, 1, 3)), size=size))
    with pytest.raises(ImageReadError, match=message) as info:
        read_image(path)
    assert "\n" not in str(info.value)


def test_the_size_of_a_big_tiff_is_read_from_its_directory(tmp_path):
    from rockscan.io.photos import _tiff_header

    # Big TIFF: version 43, 8-byte offsets and counts, entries of 20 bytes.
    head = b"II" + struct.pack("<HHHQ", 43, 8, 0, 16) + struct.pack("<Q", 3)
    entries = b"".join(
        struct.pack("<HHQ", tag, kind, 1) + value
        for tag, kind, value in [
            (256, 4, struct.pack("<I", 30).ljust(8, b"\0")),
            (257, 16, struct.pack("<Q", 20)),
            (274, 3, struct.pack("<H", 6).ljust(8, b"\0")),
        ]
    )
    (tmp_path / "b.tif").write_bytes(head + entries + struct.pack("<Q", 0))
    header = _tiff_header(tmp_path / "b.tif")
    assert (header.rows, header.cols, header.orientation) == (20, 30, 6)
    assert header.orientation_at == 16 + 8 + 2 * 20 + 12
    assert header.order == "<"
    (tmp_path / "no.tif").write_bytes(b"II" + struct.pack("<H", 44) + bytes(12))
    assert _tiff_header(tmp_path / "no.tif") is None


@pytest.mark.parametrize("samples", [2, 5])
def test_a_floating_point_tiff_of_odd_samples_is_one_clear_error(tmp_path, samples):
    path = tmp_path / "odd.tif"
    path.write_bytes(_tiff(np.full((20, 30, samples), 0.5, np.float32)))
    with pytest.raises(ImageReadError) as info:
        read_image(path)
    assert str(info.value).startswith(f"{path}: ") and "\n" not in str(info.value)


def test_a_floating_point_colour_tiff_with_nan_is_refused(tmp_path):
    samples = np.full((20, 30, 3), 0.5, np.float32)
    samples[3, 4, 1] = np.nan
    (tmp_path / "n.tif").write_bytes(_tiff(samples))
    with pytest.raises(ImageReadError, match="non-finite"):
        read_image(tmp_path / "n.tif")


# ---------------------------------------------------------------- EXIF orientation

# Pillow's transpose for each EXIF orientation (stored -> upright), and its inverse.
_UPRIGHT = {
    2: Image.Transpose.FLIP_LEFT_RIGHT,
    3: Image.Transpose.ROTATE_180,
    4: Image.Transpose.FLIP_TOP_BOTTOM,
    5: Image.Transpose.TRANSPOSE,
    6: Image.Transpose.ROTATE_270,
    7: Image.Transpose.TRANSVERSE,
    8: Image.Transpose.ROTATE_90,
}
_STORED = {**_UPRIGHT, 6: Image.Transpose.ROTATE_90, 8: Image.Transpose.ROTATE_270}


def _save_oriented(path: Path, upright: np.ndarray, orientation: int, fmt: str) -> None:
    """Store a photo so that a viewer honouring EXIF shows ``upright``."""
    im = Image.fromarray(upright)
    if orientation != 1:
        im = im.transpose(_STORED[orientation])
    exif = Image.Exif()
    exif[0x0112] = orientation
    im.save(path, format=fmt, exif=exif)


@pytest.mark.parametrize("orientation", range(1, 9))
@pytest.mark.parametrize(("fmt", "suffix"), [("PNG", ".png"), ("JPEG", ".jpg"), ("TIFF", ".tif")])
def test_orientation_agrees_with_pillow_exif_transpose(tmp_path, orientation, fmt, suffix):
    upright = _photo("rgb", 8, rows=30, cols=52)
    path = tmp_path / f"o{orientation}{suffix}"
    _save_oriented(path, upright, orientation, fmt)
    expected = np.asarray(ImageOps.exif_transpose(Image.open(path)))
    image = read_image(path)
    np.testing.assert_array_equal(image.pixels, expected)
    assert image.full_shape == (30, 52)
    if fmt != "JPEG":
        np.testing.assert_array_equal(image.pixels, upright)


@pytest.fixture(scope="module")
def teardrop_photo():
    return render_photo(TEARDROP, RenderConfig(rows=240, cols=320, angle_deg=35.0), rng=11, name="teardrop")


@pytest.mark.parametrize("orientation", range(1, 9))
def test_orientation_keeps_centroid_and_angle(tmp_path, teardrop_photo, default_lib, orientation):
    path = tmp_path / "rock.png"
    _save_oriented(path, teardrop_photo.pixels, orientation, "PNG")
    result = classify_path(path, default_lib)
    assert result.ok, result.error
    rock = result.rocks[0]
    truth = teardrop_photo.truth
    assert rock.match.nearest == "teardrop"
    np.testing.assert_allclose(rock.centroid_xy, truth["centroid_xy"], atol=1.0)
    assert abs((rock.match.angle_deg - truth["angle_deg"] + 180) % 360 - 180) < 1.5


# ---------------------------------------------------------------- large photos


@pytest.fixture(scope="module")
def big_photos(tmp_path_factory):
    """A 480x640 render enlarged 5 times (2400x3200) as TIFF, JPEG and 16-bit gray PNG."""
    folder = tmp_path_factory.mktemp("big")
    photo = render_photo(BLUNT, RenderConfig(angle_deg=20.0, area_fraction=0.1), rng=2)
    big = Image.fromarray(photo.pixels).resize((3200, 2400), Image.Resampling.BILINEAR)
    big.save(folder / "big.tif")
    big.save(folder / "big.jpg", quality=92)
    gray16 = (np.asarray(big.convert("L")).astype(np.uint16) * 257).astype(np.uint16)
    Image.fromarray(gray16).save(folder / "big16.png", compress_level=1)
    # Pillow's resize puts output pixel centre j at input (j + 0.5)/5 - 0.5.
    centroid = [(v + 0.5) * 5 - 0.5 for v in photo.truth["centroid_xy"]]
    return folder, np.asarray(big), centroid, photo.truth["angle_deg"]


@pytest.mark.parametrize("name", ["big.tif", "big.jpg", "big16.png"])
def test_large_photos_decode_reduced_by_an_exact_factor(big_photos, name):
    folder, full, _, _ = big_photos
    image = read_image(folder / name, max_side=512)
    k = int(image.scale)
    assert image.scale == k and k in (4, 5, 6)
    assert image.full_shape == (2400, 3200)
    assert image.pixels.shape[:2] == (2400 // k, 3200 // k) or name == "big.jpg"
    # Reduced pixel i is the mean of full pixels [i*k, (i+1)*k): compare with a block mean.
    rows, cols = image.pixels.shape[:2]
    reference = full[: rows * k, : cols * k].reshape(rows, k, cols, k, 3).mean(axis=(1, 3))
    got = image.pixels.astype(float)
    if got.ndim == 2:
        reference = reference @ [0.299, 0.587, 0.114]
        got = got / 257
    assert np.abs(got - reference).mean() < (2.0 if name == "big.jpg" else 1.0)


@pytest.mark.parametrize("name", ["big.tif", "big.jpg", "big16.png"])
def test_large_photos_classify_in_full_resolution_pixels(big_photos, default_lib, name):
    folder, _, centroid, angle = big_photos
    result = classify_path(folder / name, default_lib)
    assert result.ok, result.error
    rock = result.rocks[0]
    assert rock.match.nearest == "three-faced-blunt"
    # One working pixel is 3200/512 = 6.25 photo pixels; the centroid is good to a fraction of it.
    np.testing.assert_allclose(rock.centroid_xy, centroid, atol=2.5)
    assert abs((rock.match.angle_deg - angle + 60) % 120 - 60) < 1.5


@pytest.mark.parametrize("dark", [False, True])
def test_large_sixteen_bit_colour_keeps_its_bits_only_when_dark(tmp_path, dark):
    """Reduced 16-bit colour comes from 8 bits when the photo uses its range (OpenCV
    would need 12 bytes a pixel), from all 16 when the 8 bits would crush it."""
    pixels = _photo("rgb", 16, rows=400, cols=600)
    if dark:
        pixels = pixels // 64  # at most 1023: 8 bits would keep 4 levels
    path = _write(tmp_path / "deep.png", pixels)
    image = read_image(path, max_side=128)
    assert image.scale == 4.0 and image.bit_depth == 16
    assert image.pixels.dtype == (np.uint16 if dark else np.uint8)
    blocks = pixels.reshape(100, 4, 150, 4, 3).astype(float)
    expected = blocks.mean(axis=(1, 3)) if dark else (blocks // 256).mean(axis=(1, 3))
    assert np.abs(image.pixels - expected).max() <= 1.0


def test_eight_thousand_pixel_jpeg_classifies_in_bounded_memory(tmp_path):
    """Peak memory of classifying an 8000x8000 JPEG, over that of a 1000x1000 one."""
    photo = render_photo(BLUNT, RenderConfig(rows=1000, cols=1000, area_fraction=0.1), rng=5)
    small = tmp_path / "small.jpg"
    Image.fromarray(photo.pixels).save(small, quality=90)
    big = tmp_path / "big.jpg"
    Image.fromarray(photo.pixels).resize((8000, 8000), Image.Resampling.BILINEAR).save(big, quality=90)
    script = textwrap.dedent(
        """
        import resource, sys
        from rockscan.io import default_library
        from rockscan.run.pipeline import classify_path
        lib = default_library()
        result = classify_path(sys.argv[1], lib)
        assert result.ok, result.error
        print(result.rocks[0].match.nearest, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
        """
    )

    def peak_mb(path: Path) -> tuple[str, float]:
        out = subprocess.run(
            [sys.executable, "-c", script, str(path)], capture_output=True, text=True, check=True
        ).stdout.split()
        return out[0], int(out[1]) / 1024

    name_small, peak_small = peak_mb(small)
    name_big, peak_big = peak_mb(big)
    assert name_small == name_big == "three-faced-blunt"
    # The full photo would be 192 MB of pixels (256 MB inside Pillow); decoded at 1/8
    # it is 3 MB, so the big photo must cost no more than a few tens of MB extra.
    assert peak_big - peak_small < 60, (peak_small, peak_big)


# ---------------------------------------------------------------- bad files


def _encoded(fmt: str, **save: object) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(_photo("rgb", 8)).save(buf, format=fmt, **save)
    return buf.getvalue()


BAD_FILES = {
    "missing": (None, "file not found"),
    "folder": ("folder", "is a folder"),
    "empty": (b"", "file is empty"),
    "text": (b"a list of rocks, not a photo\n", "not a supported image"),
    "png-cut": ("PNG", "truncated or corrupt"),
    "jpeg-cut": ("JPEG", "truncated or corrupt"),
    "gif": ("GIF", "GIF images are not supported"),
}


def make_bad_file(folder: Path, kind: str) -> Path:
    """Write one kind of bad photo file into ``folder``; returns its path."""
    content, _ = BAD_FILES[kind]
    path = folder / f"{kind}.png"
    if content is None:
        return path
    if content == "folder":
        path.mkdir()
    elif content == "GIF":
        path.write_bytes(_encoded("GIF"))
    elif isinstance(content, str):
        data = _encoded(content)
        path.write_bytes(data[: len(data) // 2])
    else:
        path.write_bytes(content)
    return path


@pytest.mark.parametrize("kind", sorted(BAD_FILES))
def test_bad_files_raise_one_clear_image_read_error(tmp_path, kind):
    path = make_bad_file(tmp_path, kind)
    with pytest.raises(ImageReadError, match=BAD_FILES[kind][1]) as info:
        read_image(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    assert message.count(str(path)) == 1
    assert isinstance(info.value, OSError)


def test_unreadable_file_says_permission_denied(tmp_path, monkeypatch):
    path = _write(tmp_path / "p.png", _photo("rgb", 8))
    real_open = open

    def guarded_open(file, *args, **kwargs):
        if os.fspath(file) == str(path):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr("builtins.open", guarded_open)
    with pytest.raises(ImageReadError, match="permission denied"):
        read_image(path)


def test_max_side_must_be_positive(tmp_path):
    path = _write(tmp_path / "p.png", _photo("gray", 8))
    with pytest.raises(ParameterError, match="max_side"):
        read_image(path, max_side=0)


@pytest.fixture(scope="module")
def encoded_files():
    pixels = _photo("rgb", 8)
    out = {}
    for fmt in ("PNG", "JPEG", "TIFF", "BMP"):
        buf = io.BytesIO()
        Image.fromarray(pixels).save(buf, format=fmt)
        out[fmt] = buf.getvalue()
    return out


@settings(max_examples=40)
@given(
    fmt=st.sampled_from(["PNG", "JPEG", "TIFF", "BMP"]),
    cut=st.floats(0.0, 1.0),
    flips=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(1, 255)), max_size=4),
)
def test_damaged_files_never_raise_anything_but_image_read_error(
    tmp_path_factory, encoded_files, fmt, cut, flips
):
    data = bytearray(encoded_files[fmt])
    for where, xor in flips:
        data[min(int(where * len(data)), len(data) - 1)] ^= xor
    data = data[: max(1, int(cut * len(data)))] if cut < 1.0 else data
    path = tmp_path_factory.mktemp("fuzz") / "damaged.img"
    path.write_bytes(bytes(data))
    try:
        image = read_image(path)
    except ImageReadError as exc:
        assert "\n" not in str(exc)
    else:
        assert image.pixels.ndim in (2, 3) and image.pixels.size > 0


def test_decoder_warnings_do_not_escape(tmp_path):
    """A photo whose EXIF block is broken is read with orientation 1, silently."""
    pixels = _photo("rgb", 8)
    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, format="JPEG", exif=b"Exif\x00\x00MM\x00*\x00\x00\x00\x08\xff\xff")
    path = tmp_path / "broken-exif.jpg"
    path.write_bytes(buf.getvalue())
    image = read_image(path)
    assert image.pixels.shape == pixels.shape


def test_a_tiff_of_several_pages_reads_its_first_and_says_so(tmp_path, caplog):
    first, second = np.full((20, 30), 40, np.uint8), np.full((20, 30), 200, np.uint8)
    path = tmp_path / "stack.tif"
    Image.fromarray(first).save(path, save_all=True, append_images=[Image.fromarray(second)])
    # The command line's own handler stops records at the "rockscan" logger (a test
    # of it may have run in this process first): listen at the module's logger.
    logger = logging.getLogger("rockscan.io.photos")
    logger.addHandler(caplog.handler)
    try:
        with caplog.at_level("WARNING", logger="rockscan.io.photos"):
            image = read_image(path)
    finally:
        logger.removeHandler(caplog.handler)
    np.testing.assert_array_equal(image.pixels, first)
    # Classified without a word before, as if the file held one photo.
    assert "a TIFF of 2 pages; reading its first" in caplog.text


def test_an_empty_path_and_a_fractional_size_say_what_is_wrong():
    # Path("") is the current folder: ".: is a folder" named no mistake of the caller's.
    with pytest.raises(ImageReadError, match="an empty path"):
        read_image("")
    with pytest.raises(ParameterError, match="whole number of pixels"):
        read_image(__file__, max_side=2.5)


# ------------------------------------------------ TIFF sample layouts Pillow and OpenCV misread


def test_a_16_bit_colour_tiff_stored_plane_by_plane_reads_as_the_interleaved_one(tmp_path):
    import tifffile

    # Pillow kept 8 bits of each plane and OpenCV misread it: noise, classified as a rock.
    rgb = (_photo("rgb", 8).astype(np.uint16) * 257) ^ 0x0055
    tifffile.imwrite(tmp_path / "chunky.tif", rgb, photometric="rgb")
    tifffile.imwrite(
        tmp_path / "planar.tif", np.moveaxis(rgb, 2, 0), photometric="rgb", planarconfig="separate"
    )
    planar = read_image(tmp_path / "planar.tif")
    np.testing.assert_array_equal(planar.pixels, read_image(tmp_path / "chunky.tif").pixels)
    np.testing.assert_array_equal(planar.pixels, rgb)
    assert planar.bit_depth == 16


def test_a_float_colour_tiff_stored_plane_by_plane_reads_as_the_interleaved_one(tmp_path):
    import tifffile

    # OpenCV returned memory it never filled: another answer on every run.
    rgb = _photo("rgb", 8)
    samples = rgb.astype(np.float32) / 255
    tifffile.imwrite(
        tmp_path / "planar.tif", np.moveaxis(samples, 2, 0), photometric="rgb", planarconfig="separate"
    )
    (tmp_path / "chunky.tif").write_bytes(_tiff(samples))
    want = read_image(tmp_path / "chunky.tif").pixels
    for _ in range(3):
        np.testing.assert_array_equal(read_image(tmp_path / "planar.tif").pixels, want)


@pytest.mark.parametrize(
    ("dtype", "low", "high"),
    [(np.uint32, 0, 2**32 - 1), (np.int8, -128, 127), (np.float16, -0.5, 2.0)],
)
def test_gray_tiffs_of_wide_unsigned_signed_bytes_and_half_floats_scale_over_their_range(
    tmp_path, dtype, low, high
):
    import tifffile

    # Pillow read unsigned 32-bit samples as signed (those above 2**31 wrapped) and
    # signed bytes as unsigned; neither reader took half floats.
    gray = _photo("gray", 8).astype(np.float64) / 255
    values = (low + gray * (high - low)).astype(dtype)
    values.flat[:2] = (low, high)
    tifffile.imwrite(tmp_path / "g.tif", values, photometric="minisblack")
    pixels = read_image(tmp_path / "g.tif").pixels.astype(np.float64)
    want = (values.astype(np.float64) - low) / (high - low) * 65535
    assert pixels.flat[0] == 0 and pixels.flat[1] == 65535
    # float32 holds 24 bits of a 32-bit sample: a step of at most one in 16 bits.
    assert np.abs(pixels - want).max() <= 1.0


def test_a_tiff_whose_first_page_is_a_preview_reads_its_full_resolution_page(tmp_path, caplog):
    import tifffile

    rgb = _photo("rgb", 8)
    with tifffile.TiffWriter(tmp_path / "preview-first.tif") as tif:
        tif.write(rgb[::4, ::4].copy(), photometric="rgb", subfiletype=1)
        tif.write(rgb, photometric="rgb")
    logger = logging.getLogger("rockscan.io.photos")
    logger.addHandler(caplog.handler)
    try:
        with caplog.at_level("WARNING", logger="rockscan.io.photos"):
            image = read_image(tmp_path / "preview-first.tif")
    finally:
        logger.removeHandler(caplog.handler)
    # The preview gave the centroid and the outline in its own, quarter-size pixels.
    np.testing.assert_array_equal(image.pixels, rgb)
    assert image.full_shape == rgb.shape[:2]
    assert "a TIFF of 2 pages; reading page 2, its first at full resolution" in caplog.text


def test_a_corrupt_png_or_jpeg_is_named_as_what_it_is(tmp_path):
    buf = io.BytesIO()
    Image.fromarray(_photo("rgb", 8)).save(buf, format="PNG")
    data = bytearray(buf.getvalue())
    data[29] ^= 0xFF  # the header chunk's checksum
    (tmp_path / "bad.png").write_bytes(bytes(data))
    (tmp_path / "bad.jpg").write_bytes(b"\xff\xd8\xff\xe0" + b"\0" * 40)
    (tmp_path / "text.png").write_bytes(b"not a photo")
    # "not a supported image (PNG, JPEG, TIFF or BMP)" told the user to convert a PNG to PNG.
    with pytest.raises(ImageReadError, match=r"bad.png: a PNG file that cannot be decoded \(corrupt\)$"):
        read_image(tmp_path / "bad.png")
    with pytest.raises(ImageReadError, match=r"bad.jpg: a JPEG file that cannot be decoded"):
        read_image(tmp_path / "bad.jpg")
    with pytest.raises(ImageReadError, match=r"text.png: not a supported image"):
        read_image(tmp_path / "text.png")


def test_a_tiff_whose_compression_needs_imagecodecs_says_so(tmp_path, monkeypatch):
    import importlib.util

    import tifffile

    if importlib.util.find_spec("imagecodecs") is not None:
        # Where imagecodecs is installed the file below decodes (as garbage): tifffile
        # is made to answer as it does without it.
        def without_codec(self, *args, **kwargs):
            raise KeyError("<COMPRESSION.LZW: 5> requires the 'imagecodecs' package")

        monkeypatch.setattr(tifffile.TiffPage, "asarray", without_codec)
    path = tmp_path / "lzw.tif"
    rgb = _photo("rgb", 8).astype(np.uint16) * 257
    tifffile.imwrite(path, np.moveaxis(rgb, 2, 0), photometric="rgb", planarconfig="separate")
    with tifffile.TiffFile(path) as tif:
        at = tif.pages[0].tags["Compression"].valueoffset
    data = bytearray(path.read_bytes())
    data[at : at + 2] = struct.pack("<H", 5)  # LZW, as scientific software writes it
    path.write_bytes(bytes(data))
    # "image is truncated or corrupt" blamed a whole file for a codec tifffile lacks.
    with pytest.raises(ImageReadError, match=r"compression needs the imagecodecs package \(pip install"):
        read_image(path)


def test_tiffs_read_by_tifffile_give_light_not_ink(tmp_path):
    import tifffile

    # tifffile gives what the file stores: a plane-by-plane 16-bit CMYK TIFF came
    # back as RGBA (black taken for alpha), a gray one with 0 as white came back negative.
    rgb = (_photo("rgb", 8).astype(np.uint16) * 257).astype(np.float64) / 65535
    black = 1.0 - rgb.max(axis=2, keepdims=True)
    inks = (1.0 - rgb - black) / np.maximum(1.0 - black, 1e-9)
    cmyk = np.rint(np.concatenate([inks, black], axis=2) * 65535).astype(np.uint16)
    tifffile.imwrite(
        tmp_path / "c.tif", np.moveaxis(cmyk, 2, 0), photometric="separated", planarconfig="separate"
    )
    got = read_image(tmp_path / "c.tif").pixels.astype(np.float64)
    assert got.shape == rgb.shape
    assert np.abs(got - rgb * 65535).max() <= 1.0
    gray = _photo("gray", 8).astype(np.uint32)
    gray.flat[:2] = (0, 255)
    tifffile.imwrite(tmp_path / "w.tif", (255 - gray) * 16843009, photometric="miniswhite")
    np.testing.assert_array_equal(read_image(tmp_path / "w.tif").pixels, gray.astype(np.uint16) * 257)
