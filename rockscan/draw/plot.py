"""Pictures for people: a classified photo, a library's shapes (PNG via matplotlib).

Plotting is an edge of the pipeline: these functions take results and write
files; nothing in the stages imports them. Figures are made with
:class:`matplotlib.figure.Figure` directly, not pyplot, so that plotting leaves
no global state behind (no backend switch, no open figures).
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rockscan.core.errors import ParameterError, WriteError
from rockscan.core.errors import first_line as _first_line
from rockscan.core.information import information_face
from rockscan.core.polar import radii_to_xy, rotate_radii, rowcol_from_xy
from rockscan.io.atomic import write_bytes_atomic

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from numpy.typing import NDArray

    from rockscan.core.library import Library
    from rockscan.core.match import Match, MatchConfig
    from rockscan.run.pipeline import RockResult

__all__ = [
    "DecisionTest",
    "classification_figure",
    "decision_tests",
    "library_outline_rowcol",
    "match_cutoffs",
    "plot_classification",
    "plot_library",
    "save_figure",
]

_OUTLINE = "#ff3b30"
_SHAPE = "#30d158"
_CENTROID = "#ffd60a"
_PASS = "#1e8e3e"
_FAIL = "#d93025"
_CUTOFF = "#d93025"


@dataclass(frozen=True)
class DecisionTest:
    """One of the tests a sample must pass to be interesting.

    Attributes
    ----------
    name : str
        What is tested, for people: ``"distance"``, ``"MScore"``, ``"DFFS"``,
        ``"segmentation"``.
    value : float
    cutoff : float
    passed : bool
    relation : str
        How value and cutoff must compare to pass: ``"<="`` or ``">"``.
    """

    name: str
    value: float
    cutoff: float
    passed: bool
    relation: str

    def describe(self) -> str:
        """E.g. ``'distance 0.31 ≤ 0.80'``, or the comparison that fails."""
        shown = {"<=": "≤", ">": ">", ">=": "≥"}
        failing = {"<=": ">", ">": "≤", ">=": "<"}
        relation = shown[self.relation] if self.passed else failing[self.relation]
        return f"{self.name} {self.value:.3g} {relation} {self.cutoff:.3g}"


def match_cutoffs(match: Match, library: Library, config: MatchConfig | None = None) -> dict[str, float]:
    """The cutoffs a match was judged by, by test name.

    Cutoffs the match carries (``match.cutoff_distance``, ``cutoff_mscore``,
    ``cutoff_residual``, ``cutoff_segmentation``) win; otherwise those of
    ``config`` (default :class:`rockscan.core.match.MatchConfig`) for the library's
    face kind. The one place the plots read cutoffs from.

    Parameters
    ----------
    match : Match
    library : Library
    config : MatchConfig, optional

    Returns
    -------
    cutoffs : dict of str to float
        ``"distance"``, ``"MScore"`` and ``"DFFS"``, and ``"segmentation"`` when
        the match carries a segmentation cutoff.
    """
    from rockscan.core.match import MatchConfig

    config = config or MatchConfig()
    # The distance test is on the sensor distance against the nearest shape's
    # calibrated cutoff (rockscan.core.calibrate); MScore and DFFS decide only when
    # the user sets a cutoff for them.
    cutoffs = {"distance": float(match.cutoff_distance)}
    if config.mscore_cutoff is not None:
        cutoffs["MScore"] = float(config.mscore_cutoff)
    if config.residual_cutoff is not None:
        cutoffs["DFFS"] = float(config.residual_cutoff)
    segmentation = getattr(match, "cutoff_segmentation", None)
    if segmentation is not None:
        cutoffs["segmentation"] = float(segmentation)
    return cutoffs


def decision_tests(
    rock: RockResult, library: Library, config: MatchConfig | None = None
) -> list[DecisionTest]:
    """The tests that decide whether a rock is interesting, each with its value and cutoff.

    Parameters
    ----------
    rock : RockResult
    library : Library
    config : MatchConfig, optional
        The settings the rock was matched with (for the cutoffs, see
        :func:`match_cutoffs`).

    Returns
    -------
    list of DecisionTest
        Distance to the nearest shape (the paper's theta), MScore (gamma), the
        distance from face space (DFFS) and, where a cutoff exists, the
        segmentation score. ``rock.match.interesting`` stays the verdict: these
        say why.
    """
    m = rock.match
    cutoffs = match_cutoffs(m, library, config)
    w = float(m.sensor_distance)
    tests = [DecisionTest("distance", w, cutoffs["distance"], w <= cutoffs["distance"], "<=")]
    if "MScore" in cutoffs:
        tests.append(DecisionTest("MScore", m.mscore, cutoffs["MScore"], m.mscore > cutoffs["MScore"], ">"))
    if "DFFS" in cutoffs:
        tests.append(DecisionTest("DFFS", m.residual, cutoffs["DFFS"], m.residual <= cutoffs["DFFS"], "<="))
    score = rock.to_dict().get("segmentation_score")
    if "segmentation" in cutoffs and score is not None:
        cut = cutoffs["segmentation"]
        tests.append(DecisionTest("segmentation", float(score), cut, float(score) >= cut, ">="))
    return tests


def library_outline_rowcol(library: Library, rock: RockResult) -> NDArray[np.float64]:
    """The matched library shape as drawn over a rock.

    Parameters
    ----------
    library : Library
    rock : RockResult

    Returns
    -------
    outline : (n_angles + 1, 2) ndarray of float
        Closed outline, (row, col) in photo pixels: the nearest library shape
        turned by the found angle, scaled to the rock's mean radius and centred
        on its centroid.
    """
    k = library.index(rock.match.nearest)
    radii = library.radii[k] * float(np.mean(rock.radii))
    xy = radii_to_xy(radii, rock.match.angle_deg)
    return rowcol_from_xy(np.vstack([xy, xy[:1]]), rock.outline.centroid_rowcol)


def plot_classification(
    pixels: NDArray[np.generic],
    rocks: list[RockResult],
    library: Library,
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
    scale: float = 1.0,
    match_config: MatchConfig | None = None,
) -> None:
    """Draw a classified photo to a file; see :func:`classification_figure`.

    Parameters
    ----------
    pixels, rocks, library, title, scale, match_config
        As for :func:`classification_figure`.
    path : path-like
        Image file to write; its suffix picks the format (PNG, PDF, SVG, JPEG).

    Raises
    ------
    ParameterError
        If the file cannot be written or its suffix names no image format.
    """
    figure = classification_figure(
        pixels, rocks, library, title=title, scale=scale, match_config=match_config
    )
    save_figure(figure, path)


def classification_figure(
    pixels: NDArray[np.generic],
    rocks: list[RockResult],
    library: Library,
    *,
    title: str | None = None,
    scale: float = 1.0,
    match_config: MatchConfig | None = None,
) -> Figure:
    """A classified photo: verdict, outlines, centroids, matched shapes, faces, distances.

    Above the panels, the main rock's verdict (interesting or not) and the
    tests that decided it (:func:`decision_tests`: distance cutoff, MScore,
    distance from face space, segmentation where it has a cutoff), the failed
    ones first. Panels, in the order of ``figure.axes``: the whole photo with
    every rock's outline, centroid and verdict; a close view of the main rock
    with the matched library shape drawn over it at the found angle and scale;
    the information face of the main rock on its (theta, r) grid; the matched
    shape's face turned by that angle, on the same colour scale; the colour
    bar; and the distance to every library shape at its best rotation (the
    paper's outWeights) with the distance cutoff. A library of plain radii
    faces shows the two radii curves instead of the faces.

    Parameters
    ----------
    pixels : (rows, cols) or (rows, cols, 3|4) ndarray
        The photo as read (uint8 or uint16), possibly reduced.
    rocks : list of RockResult
        From :func:`rockscan.run.pipeline.classify_image`, main rock first; outlines
        in full-resolution photo pixels.
    library : Library
    title : str, optional
    scale : float
        Full-resolution pixels per pixel of ``pixels`` (the ``scale`` of
        :func:`rockscan.io.read_image`), so that outlines land right on a photo
        read reduced.
    match_config : MatchConfig, optional
        The settings the rocks were matched with, for the cutoffs shown
        (default: the defaults).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    if not (isinstance(scale, (int, float)) and np.isfinite(scale) and scale > 0):
        raise ParameterError(f"scale must be a positive number, got {scale!r}")
    shown = _displayable(pixels)
    # A fixed layout: a layout engine would cost as much as drawing the figure.
    fig = Figure(figsize=(12, 9.6))
    ax_photo = fig.add_axes((0.01, 0.44, 0.48, 0.44))
    ax_zoom = fig.add_axes((0.51, 0.44, 0.48, 0.44))
    ax_face = fig.add_axes((0.07, 0.285, 0.39, 0.105))
    ax_lib = fig.add_axes((0.07, 0.075, 0.39, 0.105))
    ax_bar = fig.add_axes((0.475, 0.075, 0.008, 0.315))
    ax_dist = fig.add_axes((0.665, 0.06, 0.32, 0.32))
    rows, cols = shown.shape[:2]
    # Reduced pixel i covers photo pixels [i*scale, (i+1)*scale): centres at integers.
    extent = (-0.5, cols * scale - 0.5, rows * scale - 0.5, -0.5)
    cmap = "gray" if shown.ndim == 2 else None
    for ax in (ax_photo, ax_zoom):
        ax.imshow(shown, cmap=cmap, extent=extent, interpolation="antialiased")
        ax.set_facecolor("#3a3a3c")
        ax.set_xticks([])
        ax.set_yticks([])
    for rock in rocks:
        _draw_rock(
            ax_photo, rock, library, label=rock.index == 0, shape=len(rocks) == 1, small=len(rocks) > 6
        )
    ax_photo.set_title(title or "rockscan classify", fontsize=10)
    if not rocks:
        for ax in (ax_zoom, ax_face, ax_lib, ax_bar, ax_dist):
            ax.axis("off")
        ax_zoom.text(0.5, 0.5, "no rock found", ha="center", va="center", transform=ax_zoom.transAxes)
        fig.text(0.5, 0.955, "no rock found", ha="center", va="center", fontsize=14, weight="bold")
        return fig
    main = rocks[0]
    _draw_rock(ax_zoom, main, library, label=True, shape=True, annotate=False)
    _zoom_to(ax_zoom, main, library)
    m = main.match
    verdict = m.match if m.match else f"no match (nearest {m.nearest})"
    modulo = f" (mod {360 / m.symmetry:g}°)" if m.symmetry > 1 else ""
    score = main.to_dict().get("segmentation_score")
    segmentation = f", segmentation {score:.2f}" if score is not None else ""
    ax_zoom.set_title(
        f"rock {main.index}: {verdict}\nMScore {m.mscore:.3f}, distance {m.distance:.3g}, "
        f"angle {m.angle_deg:.1f}°{modulo}{segmentation}",
        fontsize=10,
    )
    ax_zoom.legend(loc="lower right", fontsize=7, framealpha=0.75)
    tests = decision_tests(main, library, match_config)
    _draw_verdict(fig, main, tests)
    _draw_faces(fig, ax_face, ax_lib, ax_bar, main, library)
    _draw_distances(ax_dist, main, next(t for t in tests if t.name == "distance"))
    return fig


def _draw_verdict(fig: Any, rock: RockResult, tests: list[DecisionTest]) -> None:
    """The verdict in words and colour across the top, and the tests behind it."""
    m = rock.match
    failed = [t for t in tests if not t.passed]
    if m.interesting:
        headline, color = f"INTERESTING: {m.match}", _PASS
        why = "passes every test: " + ", ".join(t.describe() for t in tests)
    else:
        headline, color = f"NOT INTERESTING: nearest shape '{m.nearest}' rejected", _FAIL
        if failed:
            why = "decided by " + ", ".join(t.describe() for t in failed)
            passed = [t for t in tests if t.passed]
            if passed:
                why += "   (passed: " + ", ".join(t.describe() for t in passed) + ")"
        else:
            why = "rejected by the matcher (" + ", ".join(t.describe() for t in tests) + ")"
    fig.text(0.5, 0.965, headline, ha="center", va="center", fontsize=15, weight="bold", color=color)
    fig.text(0.5, 0.932, why, ha="center", va="center", fontsize=9.5, color="#1c1c1e")


def figure_formats() -> frozenset[str]:
    """File endings (without the dot) :func:`save_figure` can write: matplotlib's
    own, so that a command checks a plot's name before its work."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    return frozenset(FigureCanvasAgg.get_supported_filetypes())


def save_figure(fig: Figure, path: str | os.PathLike[str], *, dpi: int = 100) -> None:
    """Write a figure atomically in the format its suffix names (PNG by default).

    Raises
    ------
    WriteError
        If the folder is missing or the file cannot be written.
    ParameterError
        If matplotlib knows no such format.
    """
    folder = os.path.dirname(os.path.abspath(os.fspath(path)))
    if not os.path.isdir(folder):
        # Fail before drawing: drawing costs most of the time.
        raise WriteError(f"{os.fspath(path)}: cannot write the plot (no folder {folder})")
    suffix = os.path.splitext(os.fspath(path))[1].lower().lstrip(".")
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, dpi=dpi, format=suffix or None)
    except ValueError as exc:
        raise ParameterError(f"{os.fspath(path)}: cannot write the plot ({_first_line(exc)})") from None
    write_bytes_atomic(path, buffer.getvalue(), what="the plot")


def _displayable(pixels: NDArray[np.generic]) -> NDArray[np.uint8]:
    arr = np.asarray(pixels)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (3, 4)) or arr.size == 0:
        raise ParameterError(f"pixels must be a gray, RGB or RGBA photo, got shape {arr.shape}")
    if arr.dtype == np.uint8:
        out = arr
    elif arr.dtype.kind in "ui":
        out = (arr.astype(np.float64) / np.iinfo(arr.dtype).max * 255).round().astype(np.uint8)
    else:
        out = (np.clip(np.nan_to_num(arr.astype(np.float64)), 0, 1) * 255).round().astype(np.uint8)
    # An alpha channel that cuts the rock out would hide the ground: show colour only.
    return out[..., :3] if out.ndim == 3 else out


def _draw_rock(
    ax: Any,
    rock: RockResult,
    library: Library,
    *,
    label: bool,
    shape: bool,
    annotate: bool = True,
    small: bool = False,
) -> None:
    contour = rock.outline.contour_rowcol
    closed = np.vstack([contour, contour[:1]])
    ax.plot(closed[:, 1], closed[:, 0], "-", color=_OUTLINE, lw=1.4, label="outline" if label else None)
    if shape:
        drawn = library_outline_rowcol(library, rock)
        ax.plot(
            drawn[:, 1],
            drawn[:, 0],
            "--",
            color=_SHAPE,
            lw=1.4,
            label=f"library shape '{rock.match.nearest}'" if label else None,
        )
    cx, cy = rock.centroid_xy
    ax.plot([cx], [cy], "+", color=_CENTROID, ms=11, mew=2, label="centroid" if label else None)
    if rock.match.symmetry != 0:
        # The found angle: the library shape's +x axis, turned counter-clockwise on screen.
        reach = 0.6 * float(np.mean(rock.radii))
        angle = np.deg2rad(rock.match.angle_deg)
        ax.plot(
            [cx, cx + reach * np.cos(angle)],
            [cy, cy - reach * np.sin(angle)],
            "-",
            color=_CENTROID,
            lw=1,
            label="angle" if label else None,
        )
    if annotate:
        verdict = rock.match.match or f"({rock.match.nearest})"
        ax.annotate(
            f"{rock.index}" if small else f"{rock.index}: {verdict}\nMScore {rock.match.mscore:.2f}",
            (cx, cy),
            xytext=(5, 5),
            textcoords="offset points",
            color="white",
            fontsize=7,
            bbox={"boxstyle": "round", "fc": "black", "alpha": 0.55, "lw": 0},
        )


def _zoom_to(ax: Any, rock: RockResult, library: Library) -> None:
    points = np.vstack([rock.outline.contour_rowcol, library_outline_rowcol(library, rock)])
    lo, hi = points.min(axis=0), points.max(axis=0)
    half = 0.65 * float(np.max(hi - lo)) + 2.0
    center = (lo + hi) / 2
    ax.set_xlim(center[1] - half, center[1] + half)
    ax.set_ylim(center[0] + half, center[0] - half)


def _draw_faces(fig: Any, ax_face: Any, ax_lib: Any, ax_bar: Any, rock: RockResult, library: Library) -> None:
    config = library.face_config
    k = library.index(rock.match.nearest)
    turned = rotate_radii(library.radii[k], rock.match.angle_deg)
    if config.kind == "radii":
        theta = np.linspace(0.0, 360.0, rock.radii.size, endpoint=False)
        ax_face.plot(theta, rock.radii / rock.radii.mean(), color=_OUTLINE, lw=1.2, label="rock")
        ax_face.plot(theta, turned / turned.mean(), "--", color=_SHAPE, lw=1.2, label=rock.match.nearest)
        ax_face.set_xlabel("theta (deg)", fontsize=8)
        ax_face.set_ylabel("radius / mean", fontsize=8)
        ax_face.legend(fontsize=7)
        ax_face.set_title("radii (the face)", fontsize=9)
        ax_face.set_position((0.07, 0.085, 0.40, 0.30))
        ax_lib.axis("off")
        ax_bar.axis("off")
        return
    if config.grid == "cartesian":
        # The paper's grid map: the face is an image of the plane around the centroid.
        faces = [information_face(rock.radii, config), information_face(turned, config)]
        span = config.ray_length
        extent = (-span, span, -span, span)
        axis_labels = ("x (map units)", "y (map units)")
    else:
        # The face as the matcher sees it: rays along theta, sections along r.
        faces = [information_face(rock.radii, config).T, information_face(turned, config).T]
        extent = (0.0, 360.0, 0.0, float(config.n_sections))
        axis_labels = (
            "theta (degrees, counter-clockwise from +x)",
            f"r (sections of {config.resolution:g})",
        )
    top = max(float(f.max()) for f in faces)
    titles = ["information face of the rock", f"'{rock.match.nearest}' turned by {rock.match.angle_deg:.1f}°"]
    for ax, face, text in zip((ax_face, ax_lib), faces, titles, strict=True):
        image = ax.imshow(
            face,
            cmap="magma",
            vmin=0.0,
            vmax=top,
            extent=extent,
            origin="lower",
            aspect="auto",
            interpolation="nearest",
        )
        ax.set_title(text, fontsize=9)
        ax.set_xlabel(axis_labels[0], fontsize=8)
        ax.set_ylabel(axis_labels[1], fontsize=8)
        ax.tick_params(labelsize=7)
        if config.grid != "cartesian":
            ax.set_xticks(np.arange(0, 361, 45))
    fig.colorbar(image, cax=ax_bar, orientation="vertical", label="H·q (bits)")
    ax_bar.tick_params(labelsize=7)


def _draw_distances(ax: Any, rock: RockResult, test: DecisionTest) -> None:
    m = rock.match
    # The distance test is on the sensor distance (rockscan.core.calibrate): draw that one,
    # so the bars and the cutoff are in the same units.
    sensor = m.sensor_distances is not None
    distances = np.asarray(m.sensor_distances if sensor else m.distances, dtype=float)
    order = np.argsort(distances)[::-1]
    names = [m.names[i] for i in order]
    values = distances[order]
    colors = [(_SHAPE if test.passed else _FAIL) if name == m.nearest else "#8e8e93" for name in names]
    bars = ax.barh(np.arange(len(names)), values, color=colors)
    best = names.index(m.nearest)
    ax.bar_label(bars, labels=[f"{v:.3g}" if i == best else "" for i, v in enumerate(values)], fontsize=7)
    ax.set_yticks(np.arange(len(names)), names, fontsize=7)
    ax.axvline(
        test.cutoff, color=_CUTOFF, lw=1.4, ls="--", label=f"cutoff {test.cutoff:.3g}:\nmatch at or below"
    )
    if not sensor:
        ax.axvline(float(np.mean(values)), color="#1c1c1e", lw=0.8, ls=":", label="mean\n(MScore's base)")
    # Room on the right for the legend, clear of the bars.
    ax.set_xlim(0.0, 1.4 * max(float(values.max()), test.cutoff))
    what = "sensor distance" if sensor else "distance (outWeight)"
    ax.set_xlabel(f"{what} at best rotation", fontsize=8)
    ax.tick_params(axis="x", labelsize=7)
    ax.legend(fontsize=7, loc="center right", framealpha=0.9)
    ax.set_title("distance to every library shape", fontsize=9)


def plot_library(library: Library, path: str | os.PathLike[str], *, columns: int = 5) -> None:
    """Draw every shape of a library with its name, symmetry and interest.

    Parameters
    ----------
    library : Library
    path : path-like
        Image file to write; its suffix picks the format.
    columns : int
        Shapes per row.

    Raises
    ------
    ParameterError
        If the file cannot be written or ``columns`` is not positive.
    """
    if isinstance(columns, bool) or not isinstance(columns, int) or columns < 1:
        raise ParameterError(f"columns must be a positive integer, got {columns!r}")
    from matplotlib.figure import Figure

    n = len(library)
    rows = (n + columns - 1) // columns
    fig = Figure(figsize=(2.2 * columns, 2.4 * rows), layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False)
    for ax, name, radii, order, interest in zip(
        axes.flat, library.names, library.radii, library.symmetry, library.interest, strict=False
    ):
        xy = radii_to_xy(radii)
        ax.fill(xy[:, 0], xy[:, 1], color="#8e8e93", ec="#1c1c1e", lw=1)
        ax.plot([0], [0], "+", color=_OUTLINE)
        sym = "circle" if order == 0 else f"{order}-fold"
        ax.set_title(f"{name}\n{sym}, interest {interest:g}", fontsize=8)
        ax.set_aspect("equal")
        ax.axis("off")
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    save_figure(fig, path)
