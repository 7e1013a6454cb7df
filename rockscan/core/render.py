"""Synthetic rock photos with known ground truth.

A rock is a Superformula outline (or any radii), turned, scaled and placed on a
ground, then photographed: rock and ground texture, pebbles on the ground, a
lighting gradient, a soft shadow, pixel noise, blur and JPEG compression, and
the paper's outline noise (Fig. 11: each radius times ``1 + e``, ``e`` normal).

Tests, benchmarks and ``rockscan render`` all draw their photos here.
"""

from __future__ import annotations

import io as _io
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core.errors import ParameterError
from rockscan.core.polar import polar_angles, polygon_centroid_xy, resample_radii, symmetry_order
from rockscan.core.superformula import SuperformulaParams, degenerate_rays, shape_radii

__all__ = [
    "RenderConfig",
    "RenderedPhoto",
    "numbered_stem",
    "random_superformula",
    "render_numbered",
    "render_photo",
    "render_scene",
]


#: Most pixels of a rendered photo (about 1 GB of memory while drawing).
MAX_RENDER_PIXELS = 16_000_000


#: Most pebbles a photo may scatter, the longest drawn outline, the largest texture,
#: noise or outline-noise amplitude (brightness runs 0 to 1) and the widest blur (pixels).
MAX_PEBBLES = 10_000
MAX_OUTLINE_POINTS = 1_000_000
MAX_AMPLITUDE = 100.0
MAX_BLUR = 100.0


@dataclass(frozen=True)
class RenderConfig:
    """How a synthetic rock photo looks.

    Parameters
    ----------
    rows, cols : int
        Photo size in pixels.
    area_fraction : float
        Rock area as a fraction of the frame (0.02 to 0.6 in the interface).
    angle_deg : float or None
        Rotation of the rock, counter-clockwise; None draws it uniformly.
    center_xy : (float, float) or None
        Where the shape's origin lies, (x=col, y=row); None places the rock at
        random, wholly inside the frame. A rock placed partly outside is
        drawn clipped (its truth says so); one wholly outside is refused.
    rock_lighter : bool or None
        Rock lighter than the ground; None draws it.
    contrast : float
        Difference of mean brightness between rock and ground (0..1 scale).
    rock_texture, ground_texture : float
        Amplitude (0..1 scale) of smooth random texture on rock and ground.
    pebbles : int
        Number of small pebbles scattered on the ground.
    gradient : float
        Strength of a linear lighting gradient across the frame: brightness is
        multiplied by ``1 +- gradient/2`` from one side to the other.
    shadow : float
        Darkness of a soft shadow cast beside the rock (0: none, 1: black).
    noise : float
        Standard deviation of Gaussian pixel noise (0..1 scale).
    blur : float
        Standard deviation of a Gaussian blur, in pixels.
    jpeg_quality : int or None
        Compress as JPEG at this quality (None: lossless).
    outline_noise : float
        Standard deviation of ``e`` in the paper's radial noise ``r * (1 + e)``.
    outline_points : int
        Number of outline vertices the outline noise is drawn at.
    color : bool
        RGB photo (True) or gray.
    bit_depth : {8, 16}
    """

    rows: int = 480
    cols: int = 640
    area_fraction: float = 0.12
    angle_deg: float | None = None
    center_xy: tuple[float, float] | None = None
    rock_lighter: bool | None = None
    contrast: float = 0.35
    rock_texture: float = 0.04
    ground_texture: float = 0.04
    pebbles: int = 0
    gradient: float = 0.2
    shadow: float = 0.0
    noise: float = 0.02
    blur: float = 0.8
    jpeg_quality: int | None = None
    outline_noise: float = 0.0
    outline_points: int = 360
    color: bool = True
    bit_depth: int = 8

    def __post_init__(self) -> None:
        for name in ("rows", "cols", "pebbles", "outline_points", "bit_depth"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ParameterError(f"{name} must be an integer, got {value!r}")
        if self.rows < 16 or self.cols < 16:
            raise ParameterError("rows and cols must be at least 16")
        if self.rows * self.cols > MAX_RENDER_PIXELS:
            # Drawing takes some 60 bytes a pixel: refuse before allocating any.
            raise ParameterError(
                f"a photo of {self.rows} x {self.cols} pixels is over the {MAX_RENDER_PIXELS:,} "
                "rockscan draws (e.g. 4000 x 4000)"
            )
        if not 0 <= self.pebbles <= MAX_PEBBLES:
            # Each is drawn on its own: a million took a quarter of a minute a photo.
            raise ParameterError(f"pebbles must be from 0 to {MAX_PEBBLES:,}, got {self.pebbles}")
        if self.outline_points > MAX_OUTLINE_POINTS:
            raise ParameterError(
                f"outline_points must be at most {MAX_OUTLINE_POINTS:,}, got {self.outline_points}"
            )
        for name in (
            "area_fraction",
            "contrast",
            "rock_texture",
            "ground_texture",
            "gradient",
            "shadow",
            "noise",
            "blur",
            "outline_noise",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ParameterError(f"{name} must be a number, got {value!r}")
            if not (math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} must be a non-negative number, got {value!r}")
        if not 0.0005 <= self.area_fraction <= 0.8:
            raise ParameterError(
                "area_fraction must be between 0.0005 and 0.8 (the rock's share of the frame)"
            )
        if self.shadow > 1 or self.gradient >= 2:
            raise ParameterError("shadow must be at most 1 and gradient below 2")
        for name in ("rock_texture", "ground_texture", "noise", "outline_noise"):
            # Brightness runs 0 to 1; far past it the drawing overflows its floats.
            if getattr(self, name) > MAX_AMPLITUDE:
                raise ParameterError(f"{name} must be at most {MAX_AMPLITUDE:g}, got {getattr(self, name)!r}")
        if self.blur > MAX_BLUR:
            raise ParameterError(f"blur must be at most {MAX_BLUR:g} pixels, got {self.blur!r}")
        if self.contrast > 1:
            # Brightness runs 0 to 1: a larger difference would only clip the rock to white or black.
            raise ParameterError(
                f"contrast must be from 0 to 1 (the brightness difference), got {self.contrast}"
            )
        if self.jpeg_quality is not None and (
            isinstance(self.jpeg_quality, bool)
            or not isinstance(self.jpeg_quality, (int, np.integer))
            or not 1 <= self.jpeg_quality <= 100
        ):
            raise ParameterError("jpeg_quality must be between 1 and 100")
        if self.bit_depth not in (8, 16):
            raise ParameterError("bit_depth must be 8 or 16")
        if self.bit_depth == 16 and self.jpeg_quality is not None:
            raise ParameterError("JPEG photos are 8 bits; use bit_depth=8 with jpeg_quality")
        if self.outline_points < 8:
            raise ParameterError("outline_points must be at least 8")
        if self.angle_deg is not None and not (
            isinstance(self.angle_deg, (int, float, np.number))
            and not isinstance(self.angle_deg, bool)
            and math.isfinite(self.angle_deg)
        ):
            raise ParameterError(f"angle_deg must be a finite number or None, got {self.angle_deg!r}")
        if self.center_xy is not None:
            try:
                x, y = (float(v) for v in self.center_xy)
            except (TypeError, ValueError):
                raise ParameterError(f"center_xy must be (x, y) or None, got {self.center_xy!r}") from None
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ParameterError(f"center_xy must be finite, got {self.center_xy!r}")

    def with_(self, **changes: object) -> RenderConfig:
        """A copy with some settings changed."""
        return replace(self, **changes)


@dataclass(frozen=True, eq=False)
class RenderedPhoto:
    """A synthetic photo and its ground truth.

    Attributes
    ----------
    pixels : ndarray of uint8 or uint16
        The photo as a reader sees it (after JPEG compression, if any).
    truth : dict
        JSON-able ground truth. Per rock: ``shape`` (name), ``params``,
        ``angle_deg`` (counter-clockwise, the interface's convention),
        ``scale_px`` (mean radius of the outline about its origin, pixels),
        ``center_xy`` (the shape's origin), ``centroid_xy`` (the rock's area
        centroid, (col, row)), ``area_px``, ``area_fraction``, ``clipped``
        (part of the rock lies outside the frame; area and centroid are then
        those of the part inside), ``rock_lighter`` and ``symmetry`` (order
        of rotational symmetry of the noise-free outline; 0 for a circle).
        :func:`render_photo` puts the
        rock's keys at the top level; both functions list the rocks under
        ``rocks`` and every render setting under ``render``.
    """

    pixels: NDArray[np.generic]
    truth: dict[str, object]
    _raw: NDArray[np.generic] = field(repr=False)
    jpeg_quality: int | None = None

    def encode(self, suffix: str = ".png") -> bytes:
        """The photo as file bytes (``.png``, ``.jpg``, ``.tif`` or ``.bmp``).

        Other formats store :attr:`pixels` losslessly. A JPEG is compressed
        from the uncompressed render at ``jpeg_quality``, so it decodes to
        exactly :attr:`pixels` when the photo was rendered with a
        ``jpeg_quality``; without one it is compressed at quality 95.

        Raises
        ------
        ParameterError
            For other suffixes, and for 16-bit photos as JPEG or BMP (8-bit formats).
        """

        suffix = suffix.lower()
        if suffix in (".jpg", ".jpeg"):
            if self.pixels.dtype != np.uint8:
                raise ParameterError("JPEG photos are 8 bits; render with bit_depth=8")
            return _jpeg_bytes(self._raw, self.jpeg_quality or 95)
        formats = {".png": "PNG", ".tif": "TIFF", ".tiff": "TIFF", ".bmp": "BMP"}
        if suffix not in formats:
            raise ParameterError(f"cannot write {suffix!r} photos; use .png, .jpg, .tif or .bmp")
        if self.pixels.dtype == np.uint16 and (self.pixels.ndim == 3 or suffix == ".bmp"):
            if suffix == ".bmp":
                raise ParameterError("BMP photos are 8 bits; render with bit_depth=8")
            import cv2

            # Pillow cannot write 16-bit colour; OpenCV can (it stores BGR order).
            ok, data = cv2.imencode(suffix, np.ascontiguousarray(self.pixels[..., ::-1]))
            if not ok:
                raise ParameterError(f"cannot encode a 16-bit colour photo as {suffix}")
            return data.tobytes()
        buf = _io.BytesIO()
        _pil_image(self.pixels).save(buf, format=formats[suffix])
        return buf.getvalue()


def random_superformula(rng: np.random.Generator | int | None = None) -> SuperformulaParams:
    """A random closed, rock-like Superformula shape (m1 = m2, a = b = 1).

    Parameters
    ----------
    rng : numpy.random.Generator, int or None
        Source of randomness.

    Returns
    -------
    SuperformulaParams
        m from 1 to 8; n1, n2 log-uniform in [0.3, 20]; n3 = n2 in 60% of
        draws, else drawn alike; only bounded outlines whose longest radius is
        under 3.5 times the shortest (a rock, not a needle).
    """
    rng = np.random.default_rng(rng)
    for _ in range(1000):
        m = float(rng.choice([1, 2, 3, 4, 5, 6, 7, 8]))
        n1 = float(np.exp(rng.uniform(np.log(0.3), np.log(20))))
        n2 = float(np.exp(rng.uniform(np.log(0.3), np.log(20))))
        n3 = n2 if rng.random() < 0.6 else float(np.exp(rng.uniform(np.log(0.3), np.log(20))))
        params = SuperformulaParams(m, m, n1, n2, n3)
        try:
            radii = shape_radii(params, 360)
        except ParameterError:
            continue
        if radii.max() / radii.min() < 3.5:
            return params
    raise ParameterError("could not draw a rock-like Superformula shape")


def render_photo(
    shape: SuperformulaParams | ArrayLike,
    config: RenderConfig | None = None,
    *,
    rng: np.random.Generator | int | None = None,
    name: str | None = None,
) -> RenderedPhoto:
    """Draw one rock on a ground.

    Parameters
    ----------
    shape : SuperformulaParams or (n,) array_like of float
        The rock's outline: Superformula parameters, or radii at equal angles
        about its origin.
    config : RenderConfig, optional
    rng : numpy.random.Generator, int or None
        Source of every random choice.
    name : str, optional
        Shape name recorded in the truth.

    Returns
    -------
    RenderedPhoto
    """
    config = config or RenderConfig()
    rng = np.random.default_rng(rng)
    scene = _Scene(config, rng)
    rock = scene.add_rock(
        shape,
        area_fraction=config.area_fraction,
        angle_deg=config.angle_deg,
        center_xy=config.center_xy,
        name=name,
    )
    photo = scene.finish()
    truth = {**rock, "rocks": [rock], **_settings(config)}
    return RenderedPhoto(pixels=photo[0], truth=truth, _raw=photo[1], jpeg_quality=config.jpeg_quality)


def render_scene(
    shapes: list[SuperformulaParams | ArrayLike],
    config: RenderConfig | None = None,
    *,
    rng: np.random.Generator | int | None = None,
    names: list[str] | None = None,
) -> RenderedPhoto:
    """Draw several rocks that do not overlap; ``truth["rocks"]`` lists them.

    Parameters
    ----------
    shapes : list of SuperformulaParams or (n,) array_like of float
        One outline per rock (see :func:`render_photo`). An empty list draws
        the bare ground: a photo with no rock.
    config : RenderConfig, optional
        ``angle_deg`` turns every rock alike; ``center_xy`` is ignored (rocks
        are placed at random, apart from each other).
    rng : numpy.random.Generator, int or None
    names : list of str, optional
        One name per shape, recorded in the truth.

    Returns
    -------
    RenderedPhoto
        Each rock takes ``config.area_fraction / len(shapes)`` of the frame.

    Raises
    ------
    ParameterError
        If the rocks cannot be placed without overlap, or ``names`` does not
        match ``shapes``.
    """
    config = config or RenderConfig()
    rng = np.random.default_rng(rng)
    if names is not None and len(names) != len(shapes):
        raise ParameterError(f"names must give one name per shape ({len(shapes)}), got {len(names)}")
    scene = _Scene(config, rng)
    rocks = []
    for i, shape in enumerate(shapes):
        rocks.append(
            scene.add_rock(
                shape,
                area_fraction=config.area_fraction / len(shapes),
                angle_deg=config.angle_deg,
                center_xy=None,
                name=names[i] if names else None,
                avoid=True,
            )
        )
    photo = scene.finish()
    return RenderedPhoto(
        pixels=photo[0],
        truth={"rocks": rocks, **_settings(config)},
        _raw=photo[1],
        jpeg_quality=config.jpeg_quality,
    )


def render_numbered(
    shapes: Sequence[tuple[str, SuperformulaParams]],
    config: RenderConfig | None = None,
    *,
    seed: int,
    index: int,
    rocks: int = 1,
) -> tuple[str, RenderedPhoto]:
    """Photo ``index`` of a numbered set: the same (seed, index) draws the same photo,
    whatever else the set holds and in whatever order it is drawn.

    Parameters
    ----------
    shapes : sequence of (name, SuperformulaParams)
    config : RenderConfig, optional
    seed : int
        The set's seed.
    index : int
        The photo's number in the set, from 0.
    rocks : int
        One rock: shape ``index mod len(shapes)``. More: that many shapes
        drawn at random from ``shapes``, in one scene.

    Returns
    -------
    stem : str
        ``NNNN-NAME`` for one rock, ``NNNN-scene`` for a scene.
    photo : RenderedPhoto
        Drawn with ``rng = numpy.random.default_rng([seed, index])``.
    """
    if not shapes:
        raise ParameterError("give at least one shape to draw")
    if rocks < 1:
        raise ParameterError(f"rocks must be at least 1, got {rocks}")
    rng = np.random.default_rng([seed, index])
    stem = numbered_stem([name for name, _ in shapes], index, rocks)
    if rocks == 1:
        name, params = shapes[index % len(shapes)]
        return stem, render_photo(params, config, rng=rng, name=name)
    chosen = [shapes[int(j)] for j in rng.integers(0, len(shapes), rocks)]
    photo = render_scene([p for _, p in chosen], config, rng=rng, names=[n for n, _ in chosen])
    return stem, photo


def numbered_stem(names: Sequence[str], index: int, rocks: int = 1) -> str:
    """The file stem of photo ``index`` of :func:`render_numbered`: ``NNNN-SHAPE``,
    or ``NNNN-scene`` for several rocks."""
    return f"{index:04d}-{names[index % len(names)] if rocks == 1 else 'scene'}"


class _Scene:
    """Builds a photo: coverage mask of rocks, then ground, lighting and camera."""

    def __init__(self, config: RenderConfig, rng: np.random.Generator) -> None:
        self.config = config
        self.rng = rng
        self.coverage = np.zeros((config.rows, config.cols), np.float32)
        self.taken = np.zeros((config.rows, config.cols), bool)
        self.lighter = bool(rng.random() < 0.5) if config.rock_lighter is None else bool(config.rock_lighter)

    def add_rock(
        self,
        shape: SuperformulaParams | ArrayLike,
        *,
        area_fraction: float,
        angle_deg: float | None,
        center_xy: tuple[float, float] | None,
        name: str | None,
        avoid: bool = False,
    ) -> dict[str, object]:
        cfg, rng = self.config, self.rng
        n_points = cfg.outline_points if cfg.outline_noise > 0 else max(cfg.outline_points, 2048)
        theta = polar_angles(n_points)
        radii, params = _drawn_radii(shape, n_points)
        if np.any(degenerate_rays(radii)):
            raise ParameterError(
                "the shape's outline is unbounded or degenerate; choose parameters whose curve is closed"
            )
        symmetry = symmetry_order(radii)
        if cfg.outline_noise > 0:
            radii = radii * np.maximum(1.0 + rng.normal(0.0, cfg.outline_noise, radii.size), 0.05)
        unit_area = 0.5 * float(np.mean(radii**2)) * 2.0 * math.pi
        scale = math.sqrt(area_fraction * cfg.rows * cfg.cols / unit_area)
        # Turned into [0, 360) first: the radians of 1e20 degrees swamp every ray's own angle.
        angle = float(rng.uniform(0.0, 360.0)) if angle_deg is None else float(angle_deg) % 360.0
        x = scale * radii * np.cos(theta + math.radians(angle))
        y = scale * radii * np.sin(theta + math.radians(angle))
        margin = 2.0 + 3.0 * cfg.blur
        # A long rock at a large area fraction may not fit the frame at all:
        # shrink it until it does (the truth records the area it got).
        fit = min(
            (cfg.cols - 2 * margin) / max(np.ptp(x), 1e-9), (cfg.rows - 2 * margin) / max(np.ptp(y), 1e-9)
        )
        if fit < 1.0:
            scale, x, y = scale * fit * 0.98, x * fit * 0.98, y * fit * 0.98
        lo_x, hi_x = -x.min() + margin, cfg.cols - x.max() - margin
        lo_y, hi_y = y.max() + margin, cfg.rows - (-y.min()) - margin
        if center_xy is None:
            if lo_x > hi_x or lo_y > hi_y:
                raise ParameterError("the rock does not fit in the frame; lower area_fraction")
            # The rock with a gap around it, drawn once in a window of its own;
            # each try only shifts the window over the rocks already placed.
            gap = int(scale * 0.15) + 3
            left, top = math.floor(x.min()) - gap - 1, math.floor(-y.max()) - gap - 1
            height, width = math.ceil(-y.min()) - top + gap + 2, math.ceil(x.max()) - left + gap + 2
            keep_out = _dilate(_polygon_mask(x - left, -y - top, height, width) > 0.01, gap)
            for _ in range(200):
                cx, cy = float(rng.uniform(lo_x, hi_x)), float(rng.uniform(lo_y, hi_y))
                if not avoid or not _overlaps(self.taken, keep_out, round(cy) + top, round(cx) + left):
                    break
            else:
                raise ParameterError("could not place the rocks without overlap; lower area_fraction")
            mask = _polygon_mask(cx + x, cy - y, cfg.rows, cfg.cols)
        else:
            cx, cy = map(float, center_xy)
            mask = _polygon_mask(cx + x, cy - y, cfg.rows, cfg.cols)
        area = float(mask.sum())
        if area < 1.0:
            raise ParameterError(f"a rock centred at {center_xy} lies outside the frame; place it inside")
        self.coverage = np.maximum(self.coverage, mask)
        self.taken |= mask > 0.01
        # Pixel j covers [j - 0.5, j + 0.5), so the frame spans -0.5 to size - 0.5.
        low, high = min(cx + x.min(), cy - y.max()), max(cx + x.max() - cfg.cols, cy - y.min() - cfg.rows)
        clipped = bool(low < -0.5 or high > -0.5)
        if clipped:
            # The truth is what the photo shows: a segmenter can only find the
            # part inside the frame, so its centroid is that part's.
            rows_at, cols_at = np.indices(mask.shape)
            centre = (float((mask * cols_at).sum()) / area, float((mask * rows_at).sum()) / area)
        else:
            centroid = polygon_centroid_xy(np.column_stack([x, y]))
            centre = (cx + float(centroid[0]), cy - float(centroid[1]))
        mean_radius = float(np.mean(scale * radii))
        return {
            "shape": name,
            "params": params,
            "angle_deg": angle % 360.0,
            "scale_px": mean_radius,
            "center_xy": [cx, cy],
            "centroid_xy": list(centre),
            "area_px": area,
            "area_fraction": area / (cfg.rows * cfg.cols),
            "clipped": clipped,
            "rock_lighter": self.lighter,
            "symmetry": symmetry,
        }

    def finish(self) -> tuple[NDArray[np.generic], NDArray[np.generic]]:
        cfg, rng = self.config, self.rng
        rows, cols = cfg.rows, cfg.cols
        channels = 3 if cfg.color else 1
        ground_level = rng.uniform(0.35, 0.6)
        rock_level = ground_level + cfg.contrast if self.lighter else ground_level - cfg.contrast
        rock_level = float(np.clip(rock_level, 0.03, 0.97))
        ground_tint = (1.0 + rng.uniform(-0.08, 0.08, channels)).astype(np.float32)
        rock_tint = (1.0 + rng.uniform(-0.15, 0.15, channels)).astype(np.float32)
        ground = np.float32(ground_level) + np.float32(cfg.ground_texture) * _texture(rows, cols, rng)
        if cfg.pebbles:
            ground = self._pebbles(ground)
        if cfg.shadow > 0:
            ground *= 1.0 - np.float32(cfg.shadow) * self._shadow()
        image = ground[..., None] * ground_tint
        covered = np.flatnonzero(self.coverage.any(axis=1)), np.flatnonzero(self.coverage.any(axis=0))
        if covered[0].size:
            # Rock texture and blending only where rocks are: a fraction of the frame.
            box = np.s_[covered[0][0] : covered[0][-1] + 1, covered[1][0] : covered[1][-1] + 1]
            alpha = self.coverage[box][..., None]
            height, width = alpha.shape[:2]
            texture = _texture(height, width, rng, scales=(2, 6))
            rock = np.float32(rock_level) + np.float32(cfg.rock_texture) * texture
            image[box] += alpha * (rock[..., None] * rock_tint - image[box])
        if cfg.gradient > 0:
            direction = rng.uniform(0.0, 2.0 * math.pi)
            dx, dy = math.cos(direction), math.sin(direction)
            # The ramp is the sum of a column and a row term; its largest value
            # lies at a corner.
            col_term = ((np.arange(cols) - cols / 2) * dx).astype(np.float32)
            row_term = ((np.arange(rows) - rows / 2) * dy).astype(np.float32)
            peak = max(abs(cols / 2 * dx) + abs(rows / 2 * dy), 1.0)
            light = 1.0 + np.float32(0.5 * cfg.gradient / peak) * (row_term[:, None] + col_term[None, :])
            image *= light[..., None]
        if cfg.blur > 0:
            import cv2

            image = cv2.GaussianBlur(image, (0, 0), cfg.blur).reshape(image.shape)
        if cfg.noise > 0:
            image += np.float32(cfg.noise) * rng.standard_normal(image.shape, dtype=np.float32)
        top = 65535 if cfg.bit_depth == 16 else 255
        image = np.clip(image, 0.0, 1.0, out=image)
        image *= np.float32(top)
        raw = np.rint(image, out=image).astype(np.uint16 if cfg.bit_depth == 16 else np.uint8)
        raw = raw[..., 0] if channels == 1 else raw
        if cfg.jpeg_quality is None:
            return raw, raw
        return _jpeg_decode(_jpeg_bytes(raw, cfg.jpeg_quality)), raw

    def _pebbles(self, ground: NDArray[np.float32]) -> NDArray[np.float32]:
        import cv2

        cfg, rng = self.config, self.rng
        out = ground.copy()
        size = math.sqrt(cfg.rows * cfg.cols)
        mean = float(ground.mean())
        for _ in range(cfg.pebbles):
            center = (int(rng.uniform(0, cfg.cols)), int(rng.uniform(0, cfg.rows)))
            axes = (
                max(1, int(rng.uniform(0.003, 0.012) * size)),
                max(1, int(rng.uniform(0.003, 0.012) * size)),
            )
            level = float(np.clip(mean + rng.normal(0.0, cfg.contrast * 0.5), 0.02, 0.98))
            angle = float(rng.uniform(0, 180))
            cv2.ellipse(out, center, axes, angle, 0, 360, level, -1, cv2.LINE_8)
        return out

    def _shadow(self) -> NDArray[np.float32]:
        import cv2

        area = float(self.coverage.sum())
        if area < 1.0:
            return np.zeros_like(self.coverage)
        radius = math.sqrt(area / math.pi)
        direction = self.rng.uniform(0.0, 2.0 * math.pi)
        shift = (0.15 * radius * math.cos(direction), 0.15 * radius * math.sin(direction))
        matrix = np.float32([[1, 0, shift[0]], [0, 1, shift[1]]])
        moved = cv2.warpAffine(self.coverage, matrix, (self.config.cols, self.config.rows))
        return cv2.GaussianBlur(moved, (0, 0), max(1.0, 0.12 * radius))


def _drawn_radii(
    shape: SuperformulaParams | ArrayLike, n_points: int
) -> tuple[NDArray[np.float64], dict[str, float] | None]:
    """The shape's radii at ``n_points`` equal angles, and its parameters (None for radii)."""
    if isinstance(shape, SuperformulaParams):
        return shape.radii(polar_angles(n_points)), shape.as_dict()
    if isinstance(shape, (str, bytes)):
        raise TypeError(
            f"shape must be SuperformulaParams or radii, not the name {shape!r}; "
            "read_spec(path) gives a spec's shapes"
        )
    try:
        given = np.asarray(shape, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError("shape radii must be numbers") from None
    if given.ndim != 1 or given.size < 8:
        raise ParameterError("shape radii must be a 1-D array of at least 8 values")
    return resample_radii(given, n_points), None


def _polygon_mask(
    x: NDArray[np.float64], row: NDArray[np.float64], rows: int, cols: int
) -> NDArray[np.float32]:
    """Anti-aliased coverage of a polygon given in pixel (x=col, row) coordinates."""
    import cv2

    factor = 4
    x0, x1 = max(math.floor(x.min()) - 2, 0), min(math.ceil(x.max()) + 3, cols)
    y0, y1 = max(math.floor(row.min()) - 2, 0), min(math.ceil(row.max()) + 3, rows)
    out = np.zeros((rows, cols), np.float32)
    if x1 <= x0 or y1 <= y0:
        return out
    shift = 4
    # Pixel (i, j) covers [j-0.5, j+0.5); supersample its centre grid.
    px = ((x - x0 + 0.5) * factor - 0.5) * (1 << shift)
    py = ((row - y0 + 0.5) * factor - 0.5) * (1 << shift)
    big = np.zeros(((y1 - y0) * factor, (x1 - x0) * factor), np.uint8)
    pts = np.round(np.column_stack([px, py])).astype(np.int32)
    cv2.fillPoly(big, [pts], 255, lineType=cv2.LINE_8, shift=shift)
    small = cv2.resize(big, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    out[y0:y1, x0:x1] = small.astype(np.float32) / 255.0
    return out


def _texture(
    rows: int, cols: int, rng: np.random.Generator, scales: tuple[int, ...] = (2, 8, 32)
) -> NDArray[np.float32]:
    """Smooth random texture of unit standard deviation, summed over scales.

    Scale ``s`` (pixels) is white noise on a grid of one sample per ``s``
    pixels, blurred by one sample and enlarged by cubic interpolation: a smooth
    field of correlation length ``s`` at the cost of ``rows*cols/s**2`` draws.
    """
    import cv2

    out = np.zeros((rows, cols), np.float32)
    for s in scales:
        # A small frame cannot hold a coarse scale: keep at least 4 samples a side,
        # or the few samples left would add an offset, not a texture.
        step = max(1, min(s, min(rows, cols) // 4))
        small = (max(2, -(-rows // step)), max(2, -(-cols // step)))
        field_ = rng.standard_normal(small, dtype=np.float32)
        smooth = cv2.GaussianBlur(field_, (0, 0), 1.0)
        big = cv2.resize(smooth, (cols, rows), interpolation=cv2.INTER_CUBIC)
        big -= big.mean()
        out += big / max(float(big.std()), 1e-6)
    out /= max(float(out.std()), 1e-6)
    return out


def _overlaps(taken: NDArray[np.bool_], window: NDArray[np.bool_], top: int, left: int) -> bool:
    """Whether ``window``, placed with its corner at (top, left), meets ``taken``."""
    rows, cols = taken.shape
    r0, c0 = max(top, 0), max(left, 0)
    r1, c1 = min(top + window.shape[0], rows), min(left + window.shape[1], cols)
    if r1 <= r0 or c1 <= c0:
        return False
    return bool(np.any(taken[r0:r1, c0:c1] & window[r0 - top : r1 - top, c0 - left : c1 - left]))


def _dilate(mask: NDArray[np.bool_], radius: int) -> NDArray[np.bool_]:
    import cv2

    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    return cv2.dilate(mask.astype(np.uint8), kernel) > 0


def _pil_image(pixels: NDArray[np.generic]) -> object:
    from PIL import Image

    if pixels.dtype == np.uint16:
        return Image.fromarray(pixels.astype(np.uint16))
    return Image.fromarray(pixels)


def _jpeg_bytes(pixels: NDArray[np.generic], quality: int) -> bytes:
    from PIL import Image

    buf = _io.BytesIO()
    Image.fromarray(np.asarray(pixels, dtype=np.uint8)).save(buf, format="JPEG", quality=int(quality))
    return buf.getvalue()


def _jpeg_decode(data: bytes) -> NDArray[np.uint8]:
    from PIL import Image

    with Image.open(_io.BytesIO(data)) as im:
        return np.asarray(im).copy()


def _settings(config: RenderConfig) -> dict[str, object]:
    out = asdict(config)
    out.pop("angle_deg", None)
    out.pop("center_xy", None)
    return {"render": out}
