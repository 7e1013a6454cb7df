"""One photo of a triage: classified, its thumbnails drawn, never raising for a bad photo.

This is the unit of work a triage hands to a worker, in this process, a pool
or a Dask cluster (:mod:`rockscan.run.backends`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rockscan.core.errors import RockscanError, internal_error
from rockscan.run.pipeline import ClassifyConfig, RockResult, classify_path

if TYPE_CHECKING:
    from rockscan.core.library import Library

from rockscan.draw.thumbnails import thumbnail_data_uris

__all__ = ["PhotoOutcome", "photo_outcome"]


@dataclass(frozen=True, eq=False)
class PhotoOutcome:
    """One photo classified, as a worker returns it.

    Attributes
    ----------
    record : dict
        The interface's JSON object for the main rock (``rockscan classify --json``),
        or ``{"path": ..., "error": ...}``.
    radii : (n_angles,) ndarray of float or None
        The rock's radii (for novelty); None for an error.
    thumbnail : str or None
        A data URI of a small picture of the photo with outline and matched shape drawn, when asked for.
    more : tuple of PhotoOutcome
        The photo's other rocks, with ``all_rocks`` (index 1, 2, ...).
    """

    record: dict[str, Any]
    radii: NDArray[np.float64] | None = None
    thumbnail: str | None = None
    more: tuple[PhotoOutcome, ...] = ()

    def rocks(self) -> tuple[PhotoOutcome, ...]:
        """This outcome and those of the photo's other rocks, by index."""
        return (self, *self.more)


def photo_outcome(
    path: str,
    library: Library,
    config: ClassifyConfig | None = None,
    thumbnail_size: int = 0,
    all_rocks: bool = False,
) -> PhotoOutcome:
    """Classify one photo for triage; never raises for a bad photo.

    Parameters
    ----------
    path : str
    library : Library
    config : ClassifyConfig, optional
    thumbnail_size : int
        Make a thumbnail with this longer side (0: none).
    all_rocks : bool
        Every rock of the photo, not only the main one.

    Returns
    -------
    PhotoOutcome
        A photo rockscan cannot use gives the error record ``classify`` gives.
        An unexpected failure (a bug) gives an error record that says so,
        so that one photo never stops a batch.
    """
    try:
        result = classify_path(path, library, config, all_rocks=all_rocks)
        if not result.ok:
            return PhotoOutcome(record=result.records()[0])
        thumbs = _thumbnails_or_none(path, result.rocks, library, thumbnail_size)
        outcomes = [
            PhotoOutcome(record=record, radii=rock.radii, thumbnail=thumb)
            for record, rock, thumb in zip(result.records(), result.rocks, thumbs, strict=True)
        ]
        return dataclasses.replace(outcomes[0], more=tuple(outcomes[1:]))
    except Exception as exc:  # one photo must never stop a batch of millions
        return PhotoOutcome(record={"path": path, "error": internal_error(exc)})


def _thumbnails_or_none(
    path: str, rocks: tuple[RockResult, ...], library: Library, size: int
) -> list[str | None]:
    if not size:
        return [None] * len(rocks)
    try:
        return thumbnail_data_uris(path, rocks, library, size)
    except RockscanError:
        return [None] * len(rocks)
