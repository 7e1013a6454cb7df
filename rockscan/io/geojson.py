"""Triage rows as GeoJSON: a FeatureCollection, one Polygon feature per rock.

Coordinates are photo pixels (x = column, y = row, as the interface's
``outline``), not longitude and latitude: a GIS opens the file as a plain
plane (no CRS), and a georeferenced photo's transform maps it onward. Each
feature's ``properties`` are the rock's row (the classify keys plus ``rank``
and the triage keys) without the outline itself; a row without an outline (an
error row) has a null geometry, as RFC 7946 allows. The collection's
``rockscan_report`` member records how the report was made.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Generator
from typing import Any

from rockscan.io.report import PROVENANCE_KEY, THUMBNAIL_KEY

__all__ = ["feature", "feature_collection_writer", "polygon"]

#: Row keys that are geometry or page material, not feature properties.
_NOT_PROPERTIES = {"outline", THUMBNAIL_KEY}


def polygon(outline: list[list[float]] | None) -> dict[str, Any] | None:
    """A GeoJSON Polygon from an outline (closed implicitly), or None.

    Parameters
    ----------
    outline : list of [x, y], or None
        At least three points.

    Returns
    -------
    dict or None
        ``{"type": "Polygon", "coordinates": [ring]}``: one linear ring, its
        first position repeated at the end (RFC 7946 3.1.6), counter-clockwise
        in its own x, y numbers as the right-hand rule of RFC 7946 asks of a
        writer: the outline runs counter-clockwise on screen, where y points
        up, so with y = row its points are given in reverse.
    """
    if not outline or len(outline) < 3:
        return None
    ring = [[float(x), float(y)] for x, y in reversed(outline)]
    if ring[0] != ring[-1]:
        ring.append(list(ring[0]))
    return {"type": "Polygon", "coordinates": [ring]}


def feature(row: dict[str, Any]) -> dict[str, Any]:
    """A GeoJSON Feature for one report row."""
    return {
        "type": "Feature",
        "geometry": polygon(row.get("outline")),
        "properties": {k: v for k, v in row.items() if k not in _NOT_PROPERTIES},
    }


def feature_collection_writer(
    write: Callable[[bytes], object], *, provenance: dict[str, Any] | None = None
) -> Generator[None, dict[str, Any], None]:
    """Write a FeatureCollection as rows are sent to it (one feature a line).

    Parameters
    ----------
    write : callable
        Takes the file's bytes (UTF-8), piece by piece.
    provenance : dict, optional
        Recorded as the collection's ``rockscan_report`` member.

    Yields
    ------
    None
        Send rows; ``close()`` ends the collection.
    """
    head = {"type": "FeatureCollection", PROVENANCE_KEY: provenance}
    write(json.dumps(head, allow_nan=False)[:-1].encode("utf-8") + b', "features": [\n')
    first = True
    try:
        while True:
            row = yield
            text = json.dumps(feature(row), allow_nan=False)
            write((("" if first else ",\n") + text).encode("utf-8", "surrogateescape"))
            first = False
    except GeneratorExit:
        write(b"\n]}\n")
