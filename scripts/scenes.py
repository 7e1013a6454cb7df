"""A second photo generator for judging segmentation, with exact truth.

Independent of :mod:`rockscan.core.render` (its own code and its own physics), so
that a segmenter tuned on one is judged on the other.

Physics
-------
* **Shape.** A rock is a star-shaped blob: a radius ``R (1 + sum a_k cos(k
  theta + phi_k))`` over harmonics 2 to 7, stretched by an area-preserving
  aspect ratio and turned. A pixel belongs to the rock when its centre lies
  inside that curve; that is the truth, exact at every pixel.
* **Relief.** The rock is a height field on the ground: a superellipsoid dome
  ``H (1 - F**p)**(1/p)`` (``F`` the blob's normalised radius, 0 at the centre
  and 1 on the outline) plus smooth bumps that vanish at the outline.
* **Light.** One directional light of elevation ``e`` and azimuth ``a`` plus
  ambient light. Lambertian shading from the height field's normals: the far
  side turns away from the light and falls into shade. A cast shadow is
  traced by marching from every pixel towards the light over the height
  field (rocks shadow the ground and each other); its edge is softened as a
  penumbra. Specular highlights follow Phong's model (white, clipped by the
  sensor).
* **Surfaces.** Rock skins and grounds are crops of the real photos
  scikit-image ships (gravel, moon, grass, brick, coffee, ...), scaled,
  turned, of set strength, tinted. Ground brightness may ramp across the
  frame (lighter than the rock on one side, darker on the other).
* **Camera.** An illumination gradient, vignetting, Gaussian blur, sensor
  noise, clipping to 8 bits and JPEG compression; some photos gray.

Split
-----
The **development part** uses seeds 0-9999 and texture crops from the top
half of each source photo; the **held-out part** uses seeds 100000 and up and
crops from the bottom half. A seed's part is fixed by its value
(:func:`part_of_seed`), so no held-out photo can be made by accident while
tuning. Each condition draws from its own stream (``(seed, condition id)``).

Conditions
----------
One rock per photo (the truth is label 1; pebbles are ground):

================== ===========================================================
plain              moderate everything: contrast 0.25-0.6, light from above
shaded             light 10-25 deg above the horizon, weak ambient: the far side
                   in deep shade, a long cast shadow
low-contrast       rock and ground differ by 0.10-0.15 in brightness
touching-pebbles   10-40 pebbles like the rock, 3-8 of them touching it
bipolar-ground     the ground ramps across the rock, lighter than it on one side
                   and darker on the other
colour-only        rock and ground of the same luminance, different hue
highlights         glossy rock: Phong highlights, clipped
vignette-blur-jpeg vignetting 30-55%, blur 1.5-3 px, JPEG quality 50
small              rock of 1-3% of the frame
large              rock of 35-60% of the frame
combined           shaded, contrast 0.12-0.25, lighting gradient 25-45%, 10-40
                   pebbles, blur 1.5-3 px, JPEG 50-60, rock of 2-5% of the frame
================== ===========================================================

Several rocks (``--all``; the truth is every rock, labels 1..n):

================== ===========================================================
crowded            2-40 rocks, mostly touching, of similar or different sizes
                   and colours
crop-neighbours    one rock cropped from a crowded scene with a margin of a
                   third of its size; its neighbours intrude at the edges; the
                   truth is the rock the crop is centred on (label 1)
================== ===========================================================

Every generating function takes an ``rng`` and returns a :class:`Scene`; the
same seed always gives the same scene, to the bit.
"""

from __future__ import annotations

import functools
import math
import zlib
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage as ndi

__all__ = [
    "CONDITIONS",
    "CONDITION_KINDS",
    "CROWDED_CONDITIONS",
    "GENERATOR_VERSION",
    "GROUND_SOURCES",
    "PARTS",
    "SINGLE_CONDITIONS",
    "SKIN_SOURCES",
    "SOURCES",
    "Blob",
    "Scene",
    "crowded_scene",
    "make_scene",
    "neighbour_crop",
    "one_rock_photo",
    "part_of_seed",
    "part_seeds",
    "texture_window",
]

#: One-rock conditions, in table order.
SINGLE_CONDITIONS = (
    "plain",
    "shaded",
    "low-contrast",
    "touching-pebbles",
    "bipolar-ground",
    "colour-only",
    "highlights",
    "vignette-blur-jpeg",
    "small",
    "large",
    "combined",
)
#: Conditions with several rocks in the photo.
CROWDED_CONDITIONS = ("crowded", "crop-neighbours")
CONDITIONS = SINGLE_CONDITIONS + CROWDED_CONDITIONS
#: How a condition is judged: ``one`` (the main rock of a photo), ``crop``
#: (the rock a crop is centred on) or ``all`` (every rock).
CONDITION_KINDS = {**{name: "one" for name in SINGLE_CONDITIONS}, "crowded": "all", "crop-neighbours": "crop"}

PARTS = ("dev", "heldout")
#: Changes whenever a seed's scene changes (caches of scenes key on it).
GENERATOR_VERSION = 1
#: Seeds of each part: [first, stop).
PART_SEEDS = {"dev": (0, 10_000), "heldout": (100_000, 2**31)}
#: scikit-image's photos grounds are cut from, and those rock skins are cut from.
GROUND_SOURCES = ("gravel", "moon", "grass", "brick", "coffee", "chelsea")
SKIN_SOURCES = ("gravel", "moon", "grass", "coffee")
SOURCES = GROUND_SOURCES
#: Rec. 601 luma weights (what a camera's gray conversion uses).
LUMA = np.array([0.299, 0.587, 0.114])


@dataclass(frozen=True, eq=False)
class Scene:
    """A photo and its truth.

    Attributes
    ----------
    image : (rows, cols, 3) or (rows, cols) ndarray of uint8
        The photo, RGB or gray.
    labels : (rows, cols) ndarray of int32
        0 for ground (pebbles included), ``i`` for rock ``i``; in one-rock
        photos and crops label 1 is the rock to find.
    condition : str
    seed : int
    part : {"dev", "heldout"}
    kind : {"one", "crop", "all"}
        See :data:`CONDITION_KINDS`.
    info : dict
        What was drawn (contrast, coverage, light, blur, ...), for reports.
    """

    image: NDArray[np.uint8]
    labels: NDArray[np.int32]
    condition: str
    seed: int
    part: str
    kind: str
    info: dict = field(default_factory=dict)

    @property
    def n_rocks(self) -> int:
        """Number of rocks in the truth."""
        return int(self.labels.max())


# --------------------------------------------------------------------------- split


def part_of_seed(seed: int) -> str:
    """The part a seed belongs to: ``dev`` (0-9999) or ``heldout`` (100000+)."""
    for part, (first, stop) in PART_SEEDS.items():
        if first <= seed < stop:
            return part
    raise ValueError(f"seed {seed} is in no part: use 0-9999 (dev) or 100000 and up (heldout)")


def part_seeds(part: str, n: int, offset: int = 0) -> range:
    """``n`` seeds of ``part`` starting ``offset`` seeds into it."""
    if part not in PART_SEEDS:
        raise ValueError(f"part must be one of {', '.join(PARTS)}, got {part!r}")
    first, stop = PART_SEEDS[part]
    if offset < 0 or first + offset + n > stop:
        raise ValueError(f"{part} has only {stop - first} seeds")
    return range(first + offset, first + offset + n)


def condition_rng(condition: str, seed: int) -> np.random.Generator:
    """The random stream of one photo: its own for each (seed, condition)."""
    return np.random.default_rng([seed, zlib.crc32(condition.encode())])


def make_scene(condition: str, seed: int) -> Scene:
    """The photo ``seed`` of ``condition`` (its part follows from the seed).

    Parameters
    ----------
    condition : str
        One of :data:`CONDITIONS`.
    seed : int
        See :func:`part_of_seed`.

    Returns
    -------
    Scene
    """
    if condition not in CONDITIONS:
        raise ValueError(f"condition must be one of {', '.join(CONDITIONS)}, got {condition!r}")
    part = part_of_seed(seed)
    rng = condition_rng(condition, seed)
    if condition == "crowded":
        scene = crowded_scene(rng, part)
    elif condition == "crop-neighbours":
        scene = neighbour_crop(rng, part)
    else:
        scene = one_rock_photo(rng, part, condition)
    return Scene(scene.image, scene.labels, condition, seed, part, CONDITION_KINDS[condition], scene.info)


# --------------------------------------------------------------------------- textures


@functools.cache
def _source(name: str) -> NDArray[np.float32]:
    """A source photo as luminance in [0, 1]."""
    from skimage import data

    image = np.asarray(getattr(data, name)(), dtype=np.float32) / 255.0
    if image.ndim == 3:
        image = image[..., :3] @ LUMA.astype(np.float32)
    return image


def texture_window(rng: np.random.Generator, part: str, source: str) -> tuple[int, int, int, int]:
    """A random crop window (top, bottom, left, right) of a source photo.

    Development crops lie in the top half of the photo, held-out crops in the
    bottom half, so the two parts never share a texture pixel.
    """
    rows, cols = _source(source).shape
    half = rows // 2
    top0, top1 = (0, half) if part == "dev" else (half, rows)
    size_r = int(rng.integers(40, top1 - top0 + 1))
    size_c = int(np.clip(size_r * rng.uniform(0.75, 1.33), 40, cols))
    top = int(rng.integers(top0, top1 - size_r + 1))
    left = int(rng.integers(0, cols - size_c + 1))
    return top, top + size_r, left, left + size_c


def _texture(
    rng: np.random.Generator, part: str, shape: tuple[int, int], strength: float, sources: tuple[str, ...]
) -> NDArray:
    """A texture of mean 1 and relative spread ``strength``, cut, scaled and turned."""
    source = sources[int(rng.integers(len(sources)))]
    top, bottom, left, right = texture_window(rng, part, source)
    crop = _source(source)[top:bottom, left:right]
    crop = np.rot90(crop, int(rng.integers(4)))
    if rng.random() < 0.5:
        crop = crop[:, ::-1]
    # Scale: a crop covers between a quarter of the area and all of it.
    scale = rng.uniform(0.5, 1.0) * max(shape[0] / crop.shape[0], shape[1] / crop.shape[1])
    scale = max(scale, max(shape[0] / crop.shape[0], shape[1] / crop.shape[1]) * 0.999)
    resized = cv2.resize(
        np.ascontiguousarray(crop),
        (math.ceil(crop.shape[1] * scale) + 1, math.ceil(crop.shape[0] * scale) + 1),
        interpolation=cv2.INTER_CUBIC,
    )[: shape[0], : shape[1]]
    spread = float(resized.std()) or 1.0
    return 1.0 + strength * (resized - resized.mean()) / spread


def _tint(rng: np.random.Generator, saturation: float) -> NDArray:
    """An RGB multiplier of luma 1 and the given saturation, random hue."""
    hue = rng.uniform(0, 2 * np.pi)
    return _hue_tint(hue, saturation)


def _hue_tint(hue: float, saturation: float) -> NDArray:
    # Two directions orthogonal to gray, then back to luma 1.
    u = np.array([1.0, -1.0, 0.0]) / math.sqrt(2)
    v = np.array([1.0, 1.0, -2.0]) / math.sqrt(6)
    tint = 1.0 + saturation * (math.cos(hue) * u + math.sin(hue) * v)
    tint = np.clip(tint, 0.05, None)
    return tint / float(tint @ LUMA)


# --------------------------------------------------------------------------- shapes


@dataclass(frozen=True)
class Blob:
    """A star-shaped outline: ``F(p) <= 1`` inside.

    Attributes
    ----------
    center_rowcol : (float, float)
    radius : float
        Base radius ``R``, in pixels.
    amplitudes, phases : tuple of float
        Harmonics 2, 3, ... of the radius.
    aspect : float
        Area-preserving stretch (>= 1) along ``angle``.
    angle : float
        Direction of the stretch, radians.
    """

    center_rowcol: tuple[float, float]
    radius: float
    amplitudes: tuple[float, ...] = ()
    phases: tuple[float, ...] = ()
    aspect: float = 1.0
    angle: float = 0.0

    @property
    def area(self) -> float:
        """Exact area of the outline: ``pi R^2 (1 + sum a_k^2 / 2)``."""
        return math.pi * self.radius**2 * (1.0 + 0.5 * sum(a * a for a in self.amplitudes))

    @property
    def extent(self) -> float:
        """A radius that encloses the whole outline."""
        return self.radius * (1.0 + sum(abs(a) for a in self.amplitudes)) * math.sqrt(self.aspect) + 1.0

    def radius_at(self, theta: NDArray) -> NDArray:
        """Radius of the unstretched outline at angles ``theta``."""
        r = np.ones_like(theta)
        for k, (a, phi) in enumerate(zip(self.amplitudes, self.phases, strict=True), start=2):
            r = r + a * np.cos(k * theta + phi)
        return self.radius * r

    def field(self, rows: NDArray, cols: NDArray) -> NDArray:
        """``F`` at pixel centres: distance from the centre over the outline's radius."""
        dr = rows - self.center_rowcol[0]
        dc = cols - self.center_rowcol[1]
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        along = (dc * ca + dr * sa) / math.sqrt(self.aspect)
        across = (-dc * sa + dr * ca) * math.sqrt(self.aspect)
        return np.hypot(along, across) / self.radius_at(np.arctan2(across, along))

    def boundary(self, n: int = 2000) -> NDArray:
        """``n`` points of the outline, (row, col)."""
        theta = np.linspace(0, 2 * np.pi, n, endpoint=False)
        r = self.radius_at(theta)
        along, across = r * np.cos(theta) * math.sqrt(self.aspect), r * np.sin(theta) / math.sqrt(self.aspect)
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        dc = along * ca - across * sa
        dr = along * sa + across * ca
        return np.column_stack([dr + self.center_rowcol[0], dc + self.center_rowcol[1]])

    def box(self, shape: tuple[int, int], pad: int = 2) -> tuple[slice, slice]:
        """Rows and columns of the frame the blob can reach."""
        e = self.extent + pad
        r0 = max(0, int(self.center_rowcol[0] - e))
        r1 = min(shape[0], int(self.center_rowcol[0] + e) + 2)
        c0 = max(0, int(self.center_rowcol[1] - e))
        c1 = min(shape[1], int(self.center_rowcol[1] + e) + 2)
        return slice(r0, r1), slice(c0, c1)

    def mask(self, shape: tuple[int, int]) -> NDArray[np.bool_]:
        """Pixels whose centres lie inside the outline (the truth)."""
        out = np.zeros(shape, dtype=bool)
        rs, cs = self.box(shape)
        out[rs, cs] = self.box_mask(shape)
        return out

    def box_mask(self, shape: tuple[int, int]) -> NDArray[np.bool_]:
        """The truth within :meth:`box`."""
        rs, cs = self.box(shape)
        rr, cc = np.mgrid[rs, cs]
        return self.field(rr.astype(float), cc.astype(float)) <= 1.0


def random_blob(
    rng: np.random.Generator,
    center_rowcol: tuple[float, float],
    area: float,
    irregularity: float,
    max_aspect: float,
) -> Blob:
    """A random blob of exactly ``area`` pixels (of the continuous outline)."""
    n = 6
    amplitudes = irregularity * rng.normal(size=n) / np.arange(2, 2 + n) ** 1.3
    # Keep the radius positive and the outline smooth enough to be a rock.
    total = np.abs(amplitudes).sum()
    if total > 0.45:
        amplitudes *= 0.45 / total
    phases = rng.uniform(0, 2 * np.pi, n)
    base = Blob(center_rowcol, 1.0, tuple(amplitudes), tuple(phases))
    radius = math.sqrt(area / base.area)
    return Blob(
        center_rowcol,
        radius,
        tuple(float(a) for a in amplitudes),
        tuple(float(p) for p in phases),
        float(rng.uniform(1.0, max_aspect)),
        float(rng.uniform(0, np.pi)),
    )


# --------------------------------------------------------------------------- objects and rendering


@dataclass(frozen=True)
class _Object:
    """A rock or a pebble: shape, relief and surface."""

    blob: Blob
    label: int  # 0 for a pebble (ground), i for rock i
    height: float  # dome height, pixels
    exponent: float  # superellipsoid exponent (2 a dome, more a flat top)
    bumps: float  # relief amplitude as a fraction of the height
    color: tuple[float, float, float]  # mean RGB reflectance
    texture: float  # relative spread of the skin
    specular: float = 0.0
    shininess: float = 20.0


@dataclass(frozen=True)
class _Light:
    elevation: float  # radians above the horizon
    azimuth: float  # radians, direction the light comes from (0 = from +col)
    ambient: float  # share of the ground's light that is not direct


@dataclass(frozen=True)
class _Camera:
    gradient: float = 0.0  # relative illumination change across the frame
    vignette: float = 0.0  # relative darkening at the corners
    blur: float = 0.5  # Gaussian sigma, pixels
    noise: float = 1.0  # sensor noise, gray levels
    jpeg: int = 90  # quality
    gray: bool = False


def _draw_camera(
    rng: np.random.Generator,
    *,
    gradient: tuple[float, float] = (0.0, 0.12),
    vignette: tuple[float, float] = (0.0, 0.15),
    blur: tuple[float, float] = (0.3, 1.2),
    noise: tuple[float, float] = (0.5, 2.0),
    jpeg: tuple[int, int] = (75, 95),
    gray_chance: float = 0.3,
) -> _Camera:
    """A camera drawn from ranges (the defaults: an ordinary photo)."""
    return _Camera(
        float(rng.uniform(*gradient)),
        float(rng.uniform(*vignette)),
        float(rng.uniform(*blur)),
        float(rng.uniform(*noise)),
        int(rng.integers(jpeg[0], jpeg[1] + 1)),
        bool(rng.random() < gray_chance),
    )


def _paint(
    rng: np.random.Generator, part: str, shape: tuple[int, int], objects: list[_Object]
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """Height, reflectance, specular maps and truth of objects painted bottom first."""
    height = np.zeros(shape, np.float64)
    albedo_scale = np.zeros((*shape, 3), np.float64)  # filled by the caller's ground
    cover = np.zeros(shape, np.float64)
    spec = np.zeros((2, *shape), np.float64)
    labels = np.zeros(shape, np.int32)
    for obj in objects:
        rs, cs = obj.blob.box(shape)
        if rs.stop <= rs.start or cs.stop <= cs.start:
            continue
        rr, cc = np.mgrid[rs, cs].astype(np.float64)
        f = obj.blob.field(rr, cc)
        inside = f <= 1.0
        # Coverage of a pixel by the rock: its signed distance to the outline
        # (first order: (1 - F) / |grad F|) through a one-pixel ramp.
        gr, gc = np.gradient(f)
        grad = np.hypot(gr, gc) + 1e-9
        cov = np.clip(0.5 + (1.0 - f) / grad, 0.0, 1.0)
        fc = np.clip(f, 0.0, 1.0)
        dome = (1.0 - fc**obj.exponent) ** (1.0 / obj.exponent)
        relief = ndi.gaussian_filter(rng.normal(size=f.shape), max(1.0, obj.blob.radius / 6))
        relief /= relief.std() + 1e-12
        h = obj.height * (dome + obj.bumps * relief * (1.0 - fc**2)) * (f < 1.0)
        h = np.maximum(h, 0.0)
        skin = _texture(rng, part, f.shape, obj.texture, SKIN_SOURCES)
        color = np.asarray(obj.color)[None, None, :] * skin[..., None]
        c3 = cov[..., None]
        albedo_scale[rs, cs] = c3 * color + (1.0 - c3) * albedo_scale[rs, cs]
        cover[rs, cs] = np.maximum(cover[rs, cs], cov)
        height[rs, cs] = np.where(cov > 0, cov * h + (1.0 - cov) * height[rs, cs], height[rs, cs])
        spec[0, rs, cs] = np.where(cov > 0.5, obj.specular, spec[0, rs, cs])
        spec[1, rs, cs] = np.where(cov > 0.5, obj.shininess, spec[1, rs, cs])
        labels[rs, cs] = np.where(inside, obj.label, labels[rs, cs])
    return height, albedo_scale, cover, spec, labels


def _shadow(height: NDArray, light: _Light) -> NDArray:
    """Share of direct light blocked at each pixel, by marching towards the light."""
    top = float(height.max())
    if top <= 0:
        return np.zeros_like(height)
    slope = math.tan(light.elevation)
    steps = min(math.ceil(top / slope) + 1, 700)
    stride = 1 if steps <= 150 else 2
    # Direction towards the light, (row, col) per unit ground distance.
    dr, dc = math.sin(light.azimuth), math.cos(light.azimuth)
    rows, cols = height.shape
    excess = np.full(height.shape, -np.inf)
    for s in range(stride, steps + 1, stride):
        orow, ocol = round(s * dr), round(s * dc)
        shifted = np.zeros_like(height)
        # shifted[p] = height[p + offset]
        r0, r1 = max(0, -orow), min(rows, rows - orow)
        c0, c1 = max(0, -ocol), min(cols, cols - ocol)
        if r1 <= r0 or c1 <= c0:
            break
        shifted[r0:r1, c0:c1] = height[r0 + orow : r1 + orow, c0 + ocol : c1 + ocol]
        np.maximum(excess, shifted - s * slope, out=excess)
    blocked = np.clip((excess - height) / 1.5, 0.0, 1.0)
    # Penumbra: the sun is not a point.
    return ndi.gaussian_filter(blocked, 1.0 + 0.01 * steps)


def _shade(height: NDArray, albedo: NDArray, spec: NDArray, light: _Light) -> NDArray:
    """Radiance: Lambert with a cast shadow, plus Phong highlights; the lit ground is its albedo."""
    gr, gc = np.gradient(height)
    norm = np.sqrt(gr**2 + gc**2 + 1.0)
    # Normal (row, col, up) of the surface z = height(row, col).
    n_r, n_c, n_z = -gr / norm, -gc / norm, 1.0 / norm
    l_r = math.cos(light.elevation) * math.sin(light.azimuth)
    l_c = math.cos(light.elevation) * math.cos(light.azimuth)
    l_z = math.sin(light.elevation)
    lambert = np.clip(n_r * l_r + n_c * l_c + n_z * l_z, 0.0, None)
    lit = 1.0 - _shadow(height, light)
    ground = light.ambient + (1.0 - light.ambient) * l_z
    irradiance = (light.ambient + (1.0 - light.ambient) * lambert * lit) / ground
    out = albedo * irradiance[..., None]
    if np.any(spec[0] > 0):
        # Mirror direction's vertical part: the camera looks straight down.
        dot = n_r * l_r + n_c * l_c + n_z * l_z
        r_z = 2.0 * dot * n_z - l_z
        highlight = spec[0] * np.clip(r_z, 0.0, None) ** spec[1] * lit
        out = out + highlight[..., None]
    return out


def _camera(rng: np.random.Generator, radiance: NDArray, camera: _Camera) -> NDArray[np.uint8]:
    rows, cols = radiance.shape[:2]
    rr, cc = np.mgrid[0:rows, 0:cols].astype(np.float64)
    if camera.gradient > 0:
        a = rng.uniform(0, 2 * np.pi)
        t = ((rr - rows / 2) * math.sin(a) + (cc - cols / 2) * math.cos(a)) / math.hypot(rows, cols)
        radiance = radiance * (1.0 + camera.gradient * t)[..., None]
    if camera.vignette > 0:
        d2 = ((rr - rows / 2) ** 2 + (cc - cols / 2) ** 2) / ((rows / 2) ** 2 + (cols / 2) ** 2)
        radiance = radiance * (1.0 - camera.vignette * d2)[..., None]
    value = radiance * 255.0
    if camera.blur > 0:
        value = cv2.GaussianBlur(value.astype(np.float32), (0, 0), camera.blur)
    value = value + rng.normal(0.0, camera.noise, value.shape)
    if camera.gray:
        value = value @ LUMA
    image = np.clip(np.round(value), 0, 255).astype(np.uint8)
    if camera.jpeg < 100:
        bgr = image if image.ndim == 2 else image[..., ::-1]
        ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(bgr), [cv2.IMWRITE_JPEG_QUALITY, camera.jpeg])
        assert ok
        decoded = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
        image = decoded if image.ndim == 2 else decoded[..., ::-1]
    return np.ascontiguousarray(image)


def _ground(
    rng: np.random.Generator, part: str, shape: tuple[int, int], color: NDArray, texture: float
) -> NDArray:
    skin = _texture(rng, part, shape, texture, GROUND_SOURCES)
    return np.asarray(color)[None, None, :] * skin[..., None]


def _render(
    rng: np.random.Generator,
    part: str,
    shape: tuple[int, int],
    ground: NDArray,
    objects: list[_Object],
    light: _Light,
    camera: _Camera,
) -> tuple[NDArray[np.uint8], NDArray[np.int32]]:
    height, albedo, cover, spec, labels = _paint(rng, part, shape, objects)
    albedo = albedo + (1.0 - cover[..., None]) * ground
    radiance = _shade(height, albedo, spec, light)
    return _camera(rng, radiance, camera), labels


# --------------------------------------------------------------------------- one rock


_FRAMES = ((360, 480), (384, 512), (480, 640), (512, 512), (400, 400))


def _place(rng: np.random.Generator, shape: tuple[int, int], blob: Blob, margin: float) -> Blob | None:
    """The blob moved to a random place where it lies wholly inside the frame."""
    e = blob.extent + margin
    if 2 * e >= min(shape):
        return None
    center = (float(rng.uniform(e, shape[0] - e)), float(rng.uniform(e, shape[1] - e)))
    return Blob(center, blob.radius, blob.amplitudes, blob.phases, blob.aspect, blob.angle)


def _touching(rng: np.random.Generator, anchor: Blob, blob: Blob, overlap: float) -> Blob:
    """The blob moved to touch ``anchor`` from a random side (``overlap`` of its radius inside)."""
    theta = rng.uniform(0, 2 * np.pi)
    direction = np.array([math.sin(theta), math.cos(theta)])
    pts = blob.boundary(180) - np.asarray(blob.center_rowcol)

    def apart(dist: float) -> bool:
        c = np.asarray(anchor.center_rowcol) + dist * direction
        return bool(anchor.field(pts[:, 0] + c[0], pts[:, 1] + c[1]).min() > 1.0)

    # Out from the anchor's centre until the outlines no longer meet, then
    # bisect to where they just touch.
    near, far = 0.0, anchor.extent + blob.extent
    while not apart(far):  # pragma: no cover - the extents enclose both outlines
        far *= 1.5
    for _ in range(12):
        mid = 0.5 * (near + far)
        near, far = (near, mid) if apart(mid) else (mid, far)
    dist = far
    dist -= overlap * blob.radius
    c = np.asarray(anchor.center_rowcol) + dist * direction
    return Blob(
        (float(c[0]), float(c[1])), blob.radius, blob.amplitudes, blob.phases, blob.aspect, blob.angle
    )


def _level_pair(rng: np.random.Generator, contrast: float) -> tuple[float, float]:
    """Ground and rock reflectance (luma) ``contrast`` apart, relative to the brighter."""
    ground = rng.uniform(0.3, 0.65)
    if rng.random() < 0.5:
        rock = ground * (1.0 + contrast)
    else:
        rock = ground * (1.0 - contrast)
    if rock > 0.85:
        ground, rock = ground * 0.85 / rock, 0.85
    return ground, rock


def one_rock_photo(rng: np.random.Generator, part: str, condition: str = "plain") -> Scene:
    """A photo of one rock under ``condition`` (see the module's table).

    Parameters
    ----------
    rng : numpy.random.Generator
    part : {"dev", "heldout"}
        Which half of the source photos textures are cut from.
    condition : str
        One of :data:`SINGLE_CONDITIONS`.

    Returns
    -------
    Scene
        Label 1 is the rock; pebbles are ground.
    """
    if condition not in SINGLE_CONDITIONS:
        raise ValueError(f"condition must be one of {', '.join(SINGLE_CONDITIONS)}, got {condition!r}")
    c = condition
    shape = _FRAMES[int(rng.integers(len(_FRAMES)))]
    if c == "large":
        shape = (512, 512) if rng.random() < 0.5 else (448, 448)
    frame = shape[0] * shape[1]

    coverage = {"small": (0.01, 0.03), "large": (0.35, 0.60), "combined": (0.02, 0.05)}.get(c, (0.04, 0.30))
    contrast = {"low-contrast": (0.10, 0.15), "combined": (0.12, 0.25), "bipolar-ground": (0.0, 0.0)}.get(
        c, (0.25, 0.6)
    )
    contrast_v = float(rng.uniform(*contrast))
    ground_level, rock_level = _level_pair(rng, contrast_v)
    ground_tint = _tint(rng, rng.uniform(0.0, 0.25))
    rock_tint = _tint(rng, rng.uniform(0.0, 0.25))
    if c == "colour-only":
        hue = rng.uniform(0, 2 * np.pi)
        ground_tint = _hue_tint(hue, rng.uniform(0.1, 0.35))
        rock_tint = _hue_tint(
            hue + rng.uniform(0.6, 1.0) * np.pi * rng.choice([-1, 1]), rng.uniform(0.3, 0.6)
        )
        rock_level = ground_level = rng.uniform(0.35, 0.6)
    ground_texture = (
        rng.uniform(0.03, 0.10) if c in ("low-contrast", "colour-only") else rng.uniform(0.04, 0.18)
    )
    rock_texture = rng.uniform(0.03, 0.10) if c in ("low-contrast", "colour-only") else rng.uniform(0.05, 0.2)

    if c in ("shaded", "combined"):
        light = _Light(np.radians(rng.uniform(10, 25)), rng.uniform(0, 2 * np.pi), rng.uniform(0.12, 0.3))
    elif c == "colour-only":
        light = _Light(np.radians(rng.uniform(65, 88)), rng.uniform(0, 2 * np.pi), rng.uniform(0.5, 0.7))
    else:
        light = _Light(np.radians(rng.uniform(40, 80)), rng.uniform(0, 2 * np.pi), rng.uniform(0.3, 0.6))

    gray_chance = 0.0 if c == "colour-only" else 0.3
    if c == "vignette-blur-jpeg":
        camera = _draw_camera(rng, vignette=(0.3, 0.55), blur=(1.5, 3.0), noise=(1, 3), jpeg=(50, 50))
    elif c == "combined":
        camera = _draw_camera(
            rng, gradient=(0.25, 0.45), vignette=(0, 0.3), blur=(1.5, 3.0), noise=(1, 3), jpeg=(50, 60)
        )
    else:
        camera = _draw_camera(rng, gray_chance=gray_chance)

    # The rock: a blob that fits the frame, with a margin for the blur.
    area = rng.uniform(*coverage) * frame
    irregularity = rng.uniform(0.05, 0.12) if c == "large" else rng.uniform(0.1, 0.5)
    blob = None
    while blob is None:
        blob = _place(
            rng, shape, random_blob(rng, (0, 0), area, irregularity, 1.25 if c == "large" else 1.8), 4
        )
        area *= 0.97
    height_ratio = rng.uniform(0.25, 0.7)
    rock = _Object(
        blob,
        1,
        height_ratio * math.sqrt(blob.area / math.pi),
        float(rng.uniform(2.0, 4.0)),
        float(rng.uniform(0.03, 0.12)),
        tuple(rock_level * rock_tint),
        rock_texture,
        specular=float(rng.uniform(0.3, 0.9)) if c == "highlights" else 0.0,
        shininess=float(rng.uniform(8, 40)),
    )

    # Pebbles: like the rock or like the ground, below it in the painting order.
    n_pebbles = (
        int(rng.integers(10, 41)) if c in ("touching-pebbles", "combined") else int(rng.integers(0, 7))
    )
    n_touch = int(rng.integers(3, 9)) if c in ("touching-pebbles", "combined") else 0
    rock_r = math.sqrt(blob.area / math.pi)
    pebbles = []
    for i in range(n_pebbles):
        p_area = math.pi * (rock_r * rng.uniform(0.06, 0.22)) ** 2
        p_area = max(p_area, math.pi * 2.5**2)
        p = random_blob(rng, (0, 0), p_area, rng.uniform(0.05, 0.4), 1.6)
        p = _touching(rng, blob, p, rng.uniform(0.1, 0.5)) if i < n_touch else _place(rng, shape, p, 2)
        if p is None:
            continue
        mix = rng.uniform(0.3, 1.2)
        level = ground_level + mix * (rock_level - ground_level) if c != "colour-only" else ground_level
        tint = rock_tint if rng.random() < 0.5 else ground_tint
        pebbles.append(
            _Object(
                p,
                0,
                rng.uniform(0.3, 0.7) * p.radius,
                2.0,
                0.05,
                tuple(level * tint),
                rng.uniform(0.05, 0.2),
            )
        )

    ground = _ground(rng, part, shape, ground_level * ground_tint, ground_texture)
    if c == "bipolar-ground":
        # Lighter than the rock on one side, darker on the other: a ramp across the rock.
        a = rng.uniform(0, 2 * np.pi)
        swing = rng.uniform(0.25, 0.45)
        rr, cc = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
        t = ((rr - blob.center_rowcol[0]) * math.sin(a) + (cc - blob.center_rowcol[1]) * math.cos(a)) / rock_r
        ground = ground * (1.0 + swing * np.clip(t, -1.0, 1.0))[..., None]
        contrast_v = swing
    image, labels = _render(rng, part, shape, ground, [*pebbles, rock], light, camera)
    info = {
        "contrast": 0.0 if c == "colour-only" else round(contrast_v, 4),
        "coverage": round(float((labels == 1).mean()), 4),
        "elevation_deg": round(math.degrees(light.elevation), 1),
        "blur": round(camera.blur, 2),
        "jpeg": camera.jpeg,
        "pebbles": len(pebbles),
        "gray": camera.gray,
    }
    return Scene(image, labels, condition, -1, part, "one", info)


# --------------------------------------------------------------------------- several rocks


def _crowd(
    rng: np.random.Generator,
    part: str,
    shape: tuple[int, int],
    n_rocks: int,
    radius_range: tuple[float, float] | None = None,
    touch: float = 0.85,
) -> tuple[NDArray[np.uint8], NDArray[np.int32], dict]:
    """Many rocks, mostly touching; every rock fully inside the frame."""
    frame = shape[0] * shape[1]
    similar_size = rng.random() < 0.5
    similar_color = rng.random() < 0.5
    if similar_size:
        scales = rng.uniform(0.85, 1.15, n_rocks)
    else:
        scales = np.exp(rng.uniform(np.log(0.55), np.log(1.8), n_rocks))
    if radius_range is None:
        cover = rng.uniform(0.15, 0.45) if n_rocks > 3 else rng.uniform(0.05, 0.3)
        base = math.sqrt(cover * frame / (math.pi * float((scales**2).sum())))
    else:
        base = rng.uniform(*radius_range)
    base = max(base, 6.0 / float(scales.min()))
    polarity = 1.0 if rng.random() < 0.5 else -1.0
    ground_level = rng.uniform(0.35, 0.6)
    ground_tint = _tint(rng, rng.uniform(0.0, 0.25))
    shared_tint = _tint(rng, rng.uniform(0.0, 0.3))
    shared_contrast = rng.uniform(0.25, 0.6)
    light = _Light(np.radians(rng.uniform(40, 80)), rng.uniform(0, 2 * np.pi), rng.uniform(0.3, 0.6))
    camera = _draw_camera(rng)
    occupied = np.zeros(shape, bool)
    objects: list[_Object] = []
    blobs: list[Blob] = []
    for i in range(n_rocks):
        area = math.pi * (base * scales[i]) ** 2
        for _ in range(60):
            blob = random_blob(rng, (0, 0), area, rng.uniform(0.1, 0.4), 1.5)
            if blobs and rng.random() < touch:
                blob = _touching(rng, blobs[int(rng.integers(len(blobs)))], blob, rng.uniform(0.0, 0.06))
                e = blob.extent - 1.0
                r, c = blob.center_rowcol
                if not (e + 3 <= r <= shape[0] - e - 3 and e + 3 <= c <= shape[1] - e - 3):
                    continue
            else:
                blob = _place(rng, shape, blob, 3)
                if blob is None:
                    area *= 0.9
                    continue
            box = blob.box(shape)
            m = blob.box_mask(shape)
            if (m & occupied[box]).sum() <= 0.03 * m.sum():
                break
        else:
            continue
        occupied[box] |= m
        blobs.append(blob)
        if similar_color:
            level = ground_level * (1.0 + polarity * shared_contrast * rng.uniform(0.93, 1.07))
            tint = shared_tint
        else:
            level = ground_level * (1.0 + polarity * rng.uniform(0.2, 0.7))
            tint = _tint(rng, rng.uniform(0.0, 0.35))
        objects.append(
            _Object(
                blob,
                len(blobs),
                rng.uniform(0.25, 0.6) * math.sqrt(blob.area / math.pi),
                float(rng.uniform(2.0, 4.0)),
                float(rng.uniform(0.03, 0.1)),
                tuple(min(level, 0.9) * tint),
                rng.uniform(0.05, 0.18),
            )
        )
    ground = _ground(rng, part, shape, ground_level * ground_tint, rng.uniform(0.03, 0.15))
    image, labels = _render(rng, part, shape, ground, objects, light, camera)
    # A rock hidden under later ones loses its label there; keep the labels 1..n dense.
    present = np.unique(labels[labels > 0])
    remap = np.zeros(labels.max() + 1, np.int32)
    remap[present] = np.arange(1, len(present) + 1)
    labels = remap[labels]
    info = {
        "n_rocks": len(present),
        "similar_size": similar_size,
        "similar_color": similar_color,
        "polarity": "light" if polarity > 0 else "dark",
        "coverage": round(float((labels > 0).mean()), 4),
    }
    return image, labels, info


def crowded_scene(rng: np.random.Generator, part: str) -> Scene:
    """2-40 rocks, mostly touching, of similar or different sizes and colours.

    Returns
    -------
    Scene
        Labels 1..n, every rock whole inside the frame (bar the few percent a
        touching neighbour may cover).
    """
    shape = ((480, 640), (512, 512), (600, 800))[int(rng.integers(3))]
    n_rocks = int(rng.integers(2, 41))
    image, labels, info = _crowd(rng, part, shape, n_rocks)
    return Scene(image, labels, "crowded", -1, part, "all", info)


def neighbour_crop(rng: np.random.Generator, part: str) -> Scene:
    """One rock cut from a crowded scene with a margin of a third of its size.

    The crop is centred on the rock; neighbours that touch it or lie near
    intrude at the edges. The truth is that rock alone (label 1).
    """
    shape = (480, 640)
    for _ in range(20):
        image, labels, info = _crowd(rng, part, shape, int(rng.integers(8, 25)), (25.0, 55.0), touch=0.9)
        objects = ndi.find_objects(labels)
        order = rng.permutation(len(objects))
        for k in order:
            sl = objects[k]
            if sl is None:
                continue
            mask = labels == k + 1
            r0, r1, c0, c1 = sl[0].start, sl[0].stop, sl[1].start, sl[1].stop
            diameter = max(r1 - r0, c1 - c0)
            rc, cc = 0.5 * (r0 + r1 - 1), 0.5 * (c0 + c1 - 1)
            half = diameter / 2 + diameter / 3
            top, bottom = round(rc - half), round(rc + half) + 1
            left, right = round(cc - half), round(cc + half) + 1
            if top < 0 or left < 0 or bottom > shape[0] or right > shape[1]:
                continue
            crop_labels = labels[top:bottom, left:right]
            neighbours = np.unique(crop_labels[(crop_labels > 0) & (crop_labels != k + 1)])
            if len(neighbours) == 0:
                continue
            truth = mask[top:bottom, left:right].astype(np.int32)
            info = {**info, "diameter": int(diameter), "neighbours": len(neighbours)}
            return Scene(
                image[top:bottom, left:right].copy(), truth, "crop-neighbours", -1, part, "crop", info
            )
    raise RuntimeError(
        "no crop with neighbours found"
    )  # pragma: no cover - 20 crowded scenes always have one
