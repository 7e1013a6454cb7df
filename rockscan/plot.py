"""Pictures for people: a classified photo, a library's shapes (PNG via matplotlib).

Plotting is an edge of the pipeline: these functions take results and write
files; nothing in the stages imports them.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from rockscan.information import information_face_cartesian
from rockscan.polar import radii_to_xy, rowcol_from_xy

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from rockscan.library import Library
    from rockscan.pipeline import RockResult

__all__ = ["library_outline_rowcol", "plot_classification", "plot_library"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def library_outline_rowcol(library: Library, rock: RockResult) -> NDArray[np.float64]:
    """The matched library shape drawn over a rock: turned by the found angle,
    scaled to the rock's mean radius and centred on its centroid, (row, col)."""
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
) -> None:
    """Draw a classified photo: outline, centroid, matched shape, information face.

    Parameters
    ----------
    pixels : ndarray
        The photo as read.
    rocks : list of RockResult
        From :func:`rockscan.pipeline.classify_image`.
    library : Library
    path : path-like
        PNG file to write.
    title : str, optional
    """
    plt = _pyplot()
    fig, (ax_photo, ax_face) = plt.subplots(1, 2, figsize=(11, 5), gridspec_kw={"width_ratios": [1.6, 1]})
    shown = np.asarray(pixels)
    if shown.dtype == np.uint16:
        shown = (shown / 257).astype(np.uint8)
    ax_photo.imshow(shown, cmap="gray" if shown.ndim == 2 else None)
    for rock in rocks:
        contour = rock.outline.contour_rowcol
        ax_photo.plot(
            contour[:, 1],
            contour[:, 0],
            "-",
            color="#ff3b30",
            lw=1.2,
            label="outline" if rock.index == 0 else None,
        )
        shape = library_outline_rowcol(library, rock)
        ax_photo.plot(
            shape[:, 1],
            shape[:, 0],
            "--",
            color="#34c759",
            lw=1.2,
            label="library shape" if rock.index == 0 else None,
        )
        cx, cy = rock.centroid_xy
        ax_photo.plot(
            [cx], [cy], "+", color="#ffcc00", ms=10, mew=2, label="centroid" if rock.index == 0 else None
        )
        verdict = rock.match.match or f"({rock.match.nearest})"
        ax_photo.annotate(
            f"{verdict}\nMScore {rock.match.mscore:.2f}  {rock.match.angle_deg:.1f}°",
            (cx, cy),
            xytext=(6, 6),
            textcoords="offset points",
            color="white",
            fontsize=8,
            bbox={"boxstyle": "round", "fc": "black", "alpha": 0.55, "lw": 0},
        )
    ax_photo.set_title(title or "rockscan classify", fontsize=10)
    ax_photo.axis("off")
    if rocks:
        ax_photo.legend(loc="lower right", fontsize=7, framealpha=0.7)
        config = library.face_config.with_(grid="cartesian", cartesian_size=160)
        face = information_face_cartesian(rocks[0].radii, config) if config.kind != "radii" else None
        if face is not None:
            image = ax_face.imshow(face, cmap="magma", extent=(-1, 1, -1, 1))
            fig.colorbar(image, ax=ax_face, fraction=0.046, label="bits")
            ax_face.set_title("information face of the main rock", fontsize=10)
        else:
            theta = np.linspace(0, 360, rocks[0].radii.size, endpoint=False)
            ax_face.plot(theta, rocks[0].radii / rocks[0].radii.mean())
            ax_face.set_xlabel("theta (deg)")
            ax_face.set_ylabel("radius / mean")
            ax_face.set_title("radii of the main rock", fontsize=10)
    else:
        ax_face.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_library(library: Library, path: str | os.PathLike[str], *, columns: int = 5) -> None:
    """Draw every shape of a library with its name, symmetry and interest."""
    plt = _pyplot()
    n = len(library)
    rows = (n + columns - 1) // columns
    fig, axes = plt.subplots(rows, columns, figsize=(2.2 * columns, 2.4 * rows), squeeze=False)
    for ax, name, radii, order, interest in zip(
        axes.flat, library.names, library.radii, library.symmetry, library.interest, strict=False
    ):
        xy = radii_to_xy(radii)
        ax.fill(xy[:, 0], xy[:, 1], color="#8e8e93", ec="#1c1c1e", lw=1)
        ax.plot([0], [0], "+", color="#ff3b30")
        sym = "circle" if order == 0 else f"{order}-fold"
        ax.set_title(f"{name}\n{sym}, interest {interest:g}", fontsize=8)
        ax.set_aspect("equal")
        ax.axis("off")
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
