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
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.errors import ParameterError
from rockscan.polar import polar_angles, polygon_centroid_xy
from rockscan.superformula import SuperformulaParams

__all__ = ["RenderConfig", "RenderedPhoto", "random_superformula", "render_photo", "render_scene"]


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
        random, wholly inside the frame.
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
        if int(self.rows) < 16 or int(self.cols) < 16:
            raise ParameterError("rows and cols must be at least 16")
        if not 0.0005 <= self.area_fraction <= 0.8:
            raise ParameterError("area_fraction must be between 0.0005 and 0.8")
        for name in (
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
            if not (math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} must be a non-negative number")
        if self.shadow > 1 or self.gradient >= 2:
            raise ParameterError("shadow must be at most 1 and gradient below 2")
        if self.jpeg_quality is not None and not 1 <= int(self.jpeg_quality) <= 100:
            raise ParameterError("jpeg_quality must be between 1 and 100")
        if self.bit_depth not in (8, 16):
            raise ParameterError("bit_depth must be 8 or 16")
        if self.bit_depth == 16 and self.jpeg_quality is not None:
            raise ParameterError("JPEG photos are 8 bits; use bit_depth=8 with jpeg_quality")
        if int(self.outline_points) < 8:
            raise ParameterError("outline_points must be at least 8")

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
        JSON-able ground truth: shape, params, angle_deg, scale_px (mean radius
        of the outline in pixels), center_xy (the shape's origin),
        centroid_xy (the rock's area centroid), rock_lighter, rocks (for
        scenes), and every render setting.
    """

    pixels: NDArray[np.generic]
    truth: dict[str, object]
    _raw: NDArray[np.generic] = field(repr=False)
    jpeg_quality: int | None = None

    def encode(self, suffix: str = ".png") -> bytes:
        """The photo as file bytes (``.png``, ``.jpg``, ``.tif`` or ``.bmp``).

        A JPEG is compressed from the uncompressed render at ``jpeg_quality``,
        so it decodes to exactly :attr:`pixels`; other formats store
        :attr:`pixels` losslessly.
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
    """A random closed, rock-like Superformula shape (m1 = m2, a = b = 1)."""
    rng = np.random.default_rng(rng)
    from rockscan.library import shape_radii

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

    Each rock takes ``config.area_fraction / len(shapes)`` of the frame.
    """
    config = config or RenderConfig()
    rng = np.random.default_rng(rng)
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
        if isinstance(shape, SuperformulaParams):
            radii = shape.radii(theta)
            params: dict[str, float] | None = shape.as_dict()
        else:
            given = np.asarray(shape, dtype=np.float64)
            if given.ndim != 1 or given.size < 8:
                raise ParameterError("shape radii must be a 1-D array of at least 8 values")
            radii = _periodic_resample(given, n_points)
            params = None
        if not np.all(np.isfinite(radii)) or np.any(radii <= 0):
            raise ParameterError("the shape's outline is unbounded or degenerate; it cannot be drawn")
        if cfg.outline_noise > 0:
            radii = radii * np.maximum(1.0 + rng.normal(0.0, cfg.outline_noise, radii.size), 0.05)
        unit_area = 0.5 * float(np.mean(radii**2)) * 2.0 * math.pi
        scale = math.sqrt(area_fraction * cfg.rows * cfg.cols / unit_area)
        angle = float(rng.uniform(0.0, 360.0)) if angle_deg is None else float(angle_deg)
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
            for _ in range(200):
                cx, cy = float(rng.uniform(lo_x, hi_x)), float(rng.uniform(lo_y, hi_y))
                mask = _polygon_mask(cx + x, cy - y, cfg.rows, cfg.cols)
                if not avoid or not np.any(_dilate(mask > 0.01, int(scale * 0.15) + 3) & self.taken):
                    break
            else:
                raise ParameterError("could not place the rocks without overlap; lower area_fraction")
        else:
            cx, cy = map(float, center_xy)
            mask = _polygon_mask(cx + x, cy - y, cfg.rows, cfg.cols)
        self.coverage = np.maximum(self.coverage, mask)
        self.taken |= mask > 0.01
        centroid = polygon_centroid_xy(np.column_stack([x, y]))
        mean_radius = float(np.mean(scale * radii))
        return {
            "shape": name,
            "params": params,
            "angle_deg": angle % 360.0,
            "scale_px": mean_radius,
            "center_xy": [cx, cy],
            "centroid_xy": [cx + float(centroid[0]), cy - float(centroid[1])],
            "area_px": float(mask.sum()),
            "area_fraction": float(mask.sum()) / (cfg.rows * cfg.cols),
            "rock_lighter": self.lighter,
        }

    def finish(self) -> tuple[NDArray[np.generic], NDArray[np.generic]]:
        cfg, rng = self.config, self.rng
        rows, cols = cfg.rows, cfg.cols
        channels = 3 if cfg.color else 1
        ground_level = rng.uniform(0.35, 0.6)
        rock_level = ground_level + cfg.contrast if self.lighter else ground_level - cfg.contrast
        rock_level = float(np.clip(rock_level, 0.03, 0.97))
        ground_tint = 1.0 + rng.uniform(-0.08, 0.08, channels)
        rock_tint = 1.0 + rng.uniform(-0.15, 0.15, channels)
        ground = ground_level + cfg.ground_texture * _texture(rows, cols, rng)
        if cfg.pebbles:
            ground = self._pebbles(ground)
        rock = rock_level + cfg.rock_texture * _texture(rows, cols, rng, scales=(2, 6))
        if cfg.shadow > 0:
            ground = ground * (1.0 - cfg.shadow * self._shadow())
        alpha = self.coverage[..., None]
        image = ground[..., None] * ground_tint * (1 - alpha) + rock[..., None] * rock_tint * alpha
        if cfg.gradient > 0:
            direction = rng.uniform(0.0, 2.0 * math.pi)
            rr, cc = np.mgrid[0:rows, 0:cols]
            ramp = (cc - cols / 2) * math.cos(direction) + (rr - rows / 2) * math.sin(direction)
            ramp = ramp / max(np.abs(ramp).max(), 1.0)
            image = image * (1.0 + 0.5 * cfg.gradient * ramp)[..., None]
        if cfg.blur > 0:
            import cv2

            image = cv2.GaussianBlur(image.astype(np.float32), (0, 0), cfg.blur).reshape(image.shape)
        if cfg.noise > 0:
            image = image + rng.normal(0.0, cfg.noise, image.shape)
        image = np.clip(image, 0.0, 1.0)
        top = 65535 if cfg.bit_depth == 16 else 255
        raw = np.round(image * top).astype(np.uint16 if cfg.bit_depth == 16 else np.uint8)
        raw = raw[..., 0] if channels == 1 else raw
        if cfg.jpeg_quality is None:
            return raw, raw
        return _jpeg_decode(_jpeg_bytes(raw, cfg.jpeg_quality)), raw

    def _pebbles(self, ground: NDArray[np.float64]) -> NDArray[np.float64]:
        import cv2

        cfg, rng = self.config, self.rng
        out = ground.copy()
        size = math.sqrt(cfg.rows * cfg.cols)
        for _ in range(cfg.pebbles):
            center = (int(rng.uniform(0, cfg.cols)), int(rng.uniform(0, cfg.rows)))
            axes = (
                max(1, int(rng.uniform(0.003, 0.012) * size)),
                max(1, int(rng.uniform(0.003, 0.012) * size)),
            )
            level = float(np.clip(ground.mean() + rng.normal(0.0, cfg.contrast * 0.5), 0.02, 0.98))
            peb = np.zeros_like(out, dtype=np.uint8)
            cv2.ellipse(peb, center, axes, float(rng.uniform(0, 180)), 0, 360, 1, -1, cv2.LINE_AA)
            out = np.where(peb > 0, level, out)
        return out

    def _shadow(self) -> NDArray[np.float64]:
        import cv2

        ys, _xs = np.nonzero(self.coverage > 0.5)
        if ys.size == 0:
            return np.zeros_like(self.coverage, dtype=np.float64)
        radius = math.sqrt(ys.size / math.pi)
        direction = self.rng.uniform(0.0, 2.0 * math.pi)
        shift = (0.15 * radius * math.cos(direction), 0.15 * radius * math.sin(direction))
        matrix = np.float32([[1, 0, shift[0]], [0, 1, shift[1]]])
        moved = cv2.warpAffine(self.coverage, matrix, (self.config.cols, self.config.rows))
        soft = cv2.GaussianBlur(moved, (0, 0), max(1.0, 0.12 * radius))
        return soft.astype(np.float64)


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
) -> NDArray[np.float64]:
    """Smooth random texture of unit standard deviation, summed over scales.

    Each scale is drawn at a grid a few samples per blur width and enlarged, so
    coarse texture costs no more than fine.
    """
    import cv2

    out = np.zeros((rows, cols), np.float32)
    for s in scales:
        step = max(1, s // 2)
        small = (max(2, -(-rows // step)), max(2, -(-cols // step)))
        field_ = rng.normal(0.0, 1.0, small).astype(np.float32)
        smooth = cv2.GaussianBlur(field_, (0, 0), s / step) if s / step >= 0.5 else field_
        big = cv2.resize(smooth, (cols, rows), interpolation=cv2.INTER_CUBIC)
        out += big / max(float(big.std()), 1e-9)
    return (out / max(float(out.std()), 1e-9)).astype(np.float64)


def _dilate(mask: NDArray[np.bool_], radius: int) -> NDArray[np.bool_]:
    import cv2

    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    return cv2.dilate(mask.astype(np.uint8), kernel) > 0


def _periodic_resample(values: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    position = np.arange(n) * values.size / n
    lo = np.floor(position).astype(np.int64)
    frac = position - lo
    return values[lo % values.size] * (1 - frac) + values[(lo + 1) % values.size] * frac


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
