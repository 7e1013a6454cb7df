"""The stages composed: photo -> rocks -> outlines -> radii -> matches.

``classify_image`` takes pixels; ``classify_path`` reads a file first. Neither
prints: the command line formats what they return.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.choices import PX_PER_MM_RANGE
from rockscan.core.errors import ParameterError, RockscanError
from rockscan.core.match import Match, MatchConfig, match_radii
from rockscan.core.outline import Outline, trace_outline
from rockscan.core.polar import contour_radii
from rockscan.core.segment import CONFIDENT_SCORE, Segmentation, SegmentConfig, segment

if TYPE_CHECKING:
    from rockscan.core.information import FaceConfig
    from rockscan.core.library import Library, ShapeSpec

_log = logging.getLogger(__name__)

__all__ = [
    "ClassifyConfig",
    "MeasuredRock",
    "PhotoResult",
    "RockResult",
    "align_radii",
    "classify_image",
    "classify_path",
    "library_from_spec",
    "measure_rocks",
]


@dataclass(frozen=True, eq=False)
class MeasuredRock:
    """One rock of a photo, measured: its outline and its radii.

    Attributes
    ----------
    outline : Outline
        Contour and centroid in photo pixels (full resolution).
    radii : (n_angles,) ndarray of float
        Distances from the centroid to the contour at the matcher's angles
        (:func:`rockscan.core.polar.polar_angles`), pixels.
    """

    outline: Outline
    radii: NDArray[np.float64]


@dataclass(frozen=True)
class ClassifyConfig:
    """Settings for classifying photos: segmentation, matching and scale.

    Parameters
    ----------
    segment : SegmentConfig
    match : MatchConfig
    px_per_mm : float, optional
        Photo pixels per millimetre on the ground (square pixels). When given,
        every rock line also carries its sizes in millimetres (see
        :mod:`rockscan.core.measure` for their definitions).
    """

    segment: SegmentConfig = field(default_factory=SegmentConfig)
    match: MatchConfig = field(default_factory=MatchConfig)
    px_per_mm: float | None = None

    def __post_init__(self) -> None:
        value = self.px_per_mm
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        low, high = PX_PER_MM_RANGE
        if value is not None and not (number and low <= value <= high):
            message = f"px_per_mm must be a positive number of pixels per millimetre, {low:g} to {high:g}"
            raise ParameterError(f"{message}; got {value!r}")


@dataclass(frozen=True, eq=False)
class RockResult:
    """One rock of a photo and its match.

    Attributes
    ----------
    index : int
        0 for the main rock; with all rocks, by decreasing area.
    outline : Outline
        Outline and centroid in photo pixels.
    radii : (n_angles,) ndarray of float
        Radii about the centroid, in photo pixels.
    match : Match
    segmentation_score : float
        How well the photo supports the outline, in [0, 1] (see
        :attr:`rockscan.core.segment.RockMask.score`); below
        :data:`rockscan.core.segment.CONFIDENT_SCORE` the rock is never interesting.
    px_per_mm : float, optional
        Photo pixels per millimetre: the record then carries sizes in mm.
    """

    index: int
    outline: Outline
    radii: NDArray[np.float64]
    match: Match
    segmentation_score: float = 1.0
    px_per_mm: float | None = None

    @property
    def centroid_xy(self) -> tuple[float, float]:
        """Centroid as the interface's (x, y) = (col, row) pixel coordinates."""
        row, col = self.outline.centroid_rowcol
        return (float(col), float(row))

    @property
    def outline_xy(self) -> NDArray[np.float64]:
        """The outline as reported: (x, y) = (col, row) photo pixels, counter-clockwise on
        screen, simplified (:func:`rockscan.core.measure.report_outline_xy`)."""
        from rockscan.core.measure import report_outline_xy

        return report_outline_xy(self.outline.contour_rowcol, min_points=_OUTLINE_MIN_POINTS)

    def to_dict(self) -> dict[str, object]:
        """Interface keys for this rock (without ``path``).

        ``outline`` is :attr:`outline_xy` to 0.01 px; ``area_px`` and ``centroid``
        are those of the traced outline. ``segmentation_score`` is the
        segmenter's calibrated score of the outline. With
        ``px_per_mm``, the sizes of :func:`rockscan.core.measure.outline_sizes` of
        the traced outline (so that ``area_mm2 = area_px / px_per_mm**2``), to six
        significant digits.
        """
        from rockscan.core.measure import outline_sizes

        xy = self.outline_xy
        record: dict[str, object] = {
            **self.match.to_dict(),
            "centroid": [round(self.centroid_xy[0], 3), round(self.centroid_xy[1], 3)],
            "index": self.index,
            "area_px": round(self.outline.area_px, 1),
            "segmentation_score": round(float(np.clip(self.segmentation_score, 0.0, 1.0)), 4),
            "outline": np.round(xy, 2).tolist(),
        }
        if self.px_per_mm is not None:
            sizes = outline_sizes(self.outline.contour_rowcol[:, ::-1], self.px_per_mm)
            # Significant digits, not decimals: at 1e5 px/mm a rock of 9,000 px is
            # 9e-7 mm2, which four decimals made 0.
            record.update({k: float(f"{v:.6g}") for k, v in vars(sizes).items()})
        return record


#: Fewest vertices of a reported outline (the interface's minimum).
_OUTLINE_MIN_POINTS = 64


@dataclass(frozen=True, eq=False)
class PhotoResult:
    """Everything found in one photo, or why nothing could be."""

    path: str
    rocks: tuple[RockResult, ...] = ()
    error: str | None = None
    segmentation: Segmentation | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        return self.error is None

    def records(self) -> list[dict[str, object]]:
        """The interface's JSON objects: one per rock, or one error object."""
        if self.error is not None:
            return [{"path": self.path, "error": self.error}]
        return [{"path": self.path, **rock.to_dict()} for rock in self.rocks]


@one_blas_thread
def measure_rocks(
    pixels: NDArray[np.generic],
    n_angles: int,
    config: SegmentConfig | None = None,
    *,
    all_rocks: bool = False,
    scale: float = 1.0,
) -> tuple[Segmentation, list[MeasuredRock]]:
    """Segment a photo and measure each rock's outline and radii.

    Parameters
    ----------
    pixels : ndarray
        The photo (see :func:`rockscan.core.segment.segment`).
    n_angles : int
        Number of rays for the radii.
    config : SegmentConfig, optional
    all_rocks : bool
        Every rock, not only the main one.
    scale : float
        Full-resolution pixels per pixel of ``pixels`` (for photos decoded at
        reduced size), so outlines come back in full-resolution pixels.

    Returns
    -------
    segmentation : Segmentation
    rocks : list of MeasuredRock
        One per rock of ``segmentation.rocks``, in the same order.
    """
    seg = segment(pixels, config, all_rocks=all_rocks)
    # One map covers both reductions: a working pixel spans seg.scale_rowcol * scale
    # photo pixels whether the photo was decoded at full or reduced size.
    pixel_scale = np.asarray(seg.scale_rowcol) * scale
    rocks = []
    for rock in seg.rocks:
        outline = trace_outline(rock.coverage, scale=pixel_scale, origin_rowcol=rock.origin_rowcol)
        radii = contour_radii(outline.contour_rowcol, outline.centroid_rowcol, n_angles)
        rocks.append(MeasuredRock(outline, radii))
    return seg, rocks


@one_blas_thread
def classify_image(
    pixels: NDArray[np.generic],
    library: Library,
    config: ClassifyConfig | None = None,
    *,
    all_rocks: bool = False,
    scale: float = 1.0,
) -> list[RockResult]:
    """Find the rock(s) in a photo and match each against a library.

    Parameters
    ----------
    pixels : ndarray
        Gray, RGB or RGBA photo.
    library : Library
    config : ClassifyConfig, optional
    all_rocks : bool
        Classify every rock (``--all``), not only the main one.
    scale : float
        See :func:`measure_rocks`.

    Returns
    -------
    list of RockResult
        The main rock first.

    Raises
    ------
    NoRockFoundError
        If no rock stands out from the ground.
    TypeError
        If ``library`` is not a :class:`Library` (a name such as ``"default"``).
    """
    from rockscan.core.match import require_library

    config = config or ClassifyConfig()
    n_angles = require_library(library).face_config.n_angles
    seg, rocks = measure_rocks(pixels, n_angles, config.segment, all_rocks=all_rocks, scale=scale)
    results = []
    for i, (measured, rock) in enumerate(zip(rocks, seg.rocks, strict=True)):
        outline, radii = measured.outline, measured.radii
        match = match_radii(radii, library, config.match)
        if rock.score < CONFIDENT_SCORE and match.interesting:
            # A shape read from an outline the photo does not support is no finding.
            match = dataclasses.replace(match, interesting=False, match=None)
        results.append(
            RockResult(i, outline, radii, match, segmentation_score=rock.score, px_per_mm=config.px_per_mm)
        )
    return results


def classify_path(
    path: str | os.PathLike[str],
    library: Library,
    config: ClassifyConfig | None = None,
    *,
    all_rocks: bool = False,
) -> PhotoResult:
    """Read a photo and classify it; a bad photo gives an error result, never an exception.

    Parameters
    ----------
    path : path-like
        A PNG, JPEG, TIFF or BMP photo (see :func:`rockscan.io.read_image`).
        Photos larger than twice the segmentation's ``work_size`` are decoded
        at reduced size; outlines and centroids still come back in the full
        photo's pixels.
    library : Library
    config : ClassifyConfig, optional
    all_rocks : bool
        Classify every rock, not only the main one.

    Returns
    -------
    PhotoResult
        With the rocks, or with ``error`` set to a one-line message.

    Notes
    -----
    Only :class:`rockscan.core.errors.RockscanError` becomes an error result: anything
    else is a bug and propagates, as does the ``TypeError`` of a ``library`` that is
    not a :class:`Library`.
    """
    from rockscan.core.match import require_library
    from rockscan.io import read_image

    require_library(library)  # before the photo is read: a wrong argument is no bad photo
    config = config or ClassifyConfig()
    start = time.perf_counter()
    try:
        image = read_image(path, max_side=2 * config.segment.work_size)
        rocks = classify_image(image.pixels, library, config, all_rocks=all_rocks, scale=image.scale)
    except RockscanError as exc:
        return PhotoResult(path=str(path), error=str(exc))
    _log.debug(
        "%s: %d rock(s) in %.2f s (decoded at 1/%g size)",
        path,
        len(rocks),
        time.perf_counter() - start,
        image.scale,
    )
    return PhotoResult(path=str(path), rocks=tuple(rocks))


def library_from_spec(
    shapes: list[ShapeSpec],
    *,
    face_config: FaceConfig | None = None,
    segment_config: SegmentConfig | None = None,
    n_components: int | None = None,
    tolerance: float | None = None,
) -> Library:
    """Build a library from spec shapes, reading the example photos of shapes
    given by ``images`` instead of parameters.

    Parameters
    ----------
    shapes : list of ShapeSpec
        Superformula shapes, or shapes given by example photos.
    face_config : FaceConfig, optional
    segment_config : SegmentConfig, optional
        How the example photos are segmented.
    n_components : int, optional
        Keep at most this many eigenfaces (default: all non-zero).
    tolerance : float, optional
        Outline noise the cutoffs are calibrated for (default 0.2); the
        spread between a shape's example photos counts in its cutoff.

    Returns
    -------
    Library

    Notes
    -----
    A shape given by examples gets the mean of their faces, after turning each
    example to the first one's orientation (the rotation that best aligns
    their radii), so that the examples reinforce rather than blur each other.
    Its radii (for drawing) are the mean of the aligned examples' radii.

    Raises
    ------
    SpecError
        If an example photo cannot be read or shows no rock.
    """
    from rockscan.core.errors import SpecError
    from rockscan.core.information import FaceConfig, information_face
    from rockscan.core.library import Library
    from rockscan.core.superformula import shape_radii
    from rockscan.io import read_image

    config = face_config or FaceConfig()
    if all(shape.params is not None for shape in shapes):
        # No photos to read: the library's own build, chunked for large specs.
        return Library.from_shapes(
            shapes,
            face_config=config,
            n_components=n_components,
            **({} if tolerance is None else {"tolerance": tolerance}),
        )
    n = config.n_angles
    names, radii, faces, params, interest, sources = [], [], [], [], [], []
    for shape in shapes:
        if shape.params is not None:
            try:
                r = shape_radii(shape.params, n)
            except RockscanError as exc:
                raise SpecError(f"shape {shape.name!r}: {exc}") from None
            examples = r[None, :]
        else:
            measured = []
            for image_path in shape.images:
                try:
                    image = read_image(image_path, max_side=2 * (segment_config or SegmentConfig()).work_size)
                    _, rocks = measure_rocks(image.pixels, n, segment_config, scale=image.scale)
                except RockscanError as exc:
                    raise SpecError(f"shape {shape.name!r}: example {image_path}: {exc}") from None
                r = rocks[0].radii
                measured.append(r / r.mean())
            examples = align_radii(np.array(measured))
        names.append(shape.name)
        radii.append(examples.mean(axis=0))
        faces.append(information_face(examples, config).mean(axis=0))
        params.append(shape.params)
        interest.append(shape.interest)
        sources.append(examples if shape.params is None else None)
    return Library.from_radii(
        names,
        np.array(radii),
        face_config=config,
        params=params,
        interest=interest,
        faces=np.array(faces),
        n_components=n_components,
        examples=sources,
        **({} if tolerance is None else {"tolerance": tolerance}),
    )


def align_radii(radii: NDArray[np.float64]) -> NDArray[np.float64]:
    """Turn each row of radii to the orientation of the first.

    Parameters
    ----------
    radii : (n_rows, n_angles) array_like of float
        Radii at :func:`rockscan.core.polar.polar_angles`, one outline per row.

    Returns
    -------
    turned : (n_rows, n_angles) ndarray of float
        Each row shifted by the whole number of rays that best aligns it with
        the first row (largest circular cross-correlation of the
        mean-normalised radii); the first row unchanged.
    """
    radii = np.asarray(radii, dtype=np.float64)
    normalized = radii / radii.mean(axis=1, keepdims=True) - 1.0
    spectra = np.fft.rfft(normalized, axis=1)
    corr = np.fft.irfft(np.conj(spectra[:1]) * spectra, n=radii.shape[1], axis=1)
    shifts = np.argmax(corr, axis=1)
    return np.stack([np.roll(row, -int(s)) for row, s in zip(radii, shifts, strict=True)])
