"""Folders of photos: walking a folder for the files rockscan reads."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rockscan.core.errors import ParameterError

if TYPE_CHECKING:
    pass

from rockscan.io.photos import IMAGE_SUFFIXES

__all__ = ["PhotoListing", "find_photos"]


@dataclass(frozen=True)
class PhotoListing:
    """The photos under a folder.

    Attributes
    ----------
    photos : tuple of str
        Paths of files with a photo ending (:data:`rockscan.io.IMAGE_SUFFIXES`,
        any case), each joined to the folder as given, in a fixed order: each
        folder's files by name, then its subfolders by name.
    problems : tuple of (str, str)
        Folders that could not be listed, and why.
    n_skipped : int
        Other files seen (no photo ending), skipped.
    skipped_endings : tuple of str
        Their endings (lower case, "" for none), each once, sorted; at most ``SKIPPED_ENDINGS``.
    """

    photos: tuple[str, ...]
    problems: tuple[tuple[str, str], ...] = ()
    n_skipped: int = 0
    skipped_endings: tuple[str, ...] = ()


#: Most endings of skipped files a listing names (a folder may hold thousands of kinds).
SKIPPED_ENDINGS = 8


def find_photos(folder: str | os.PathLike[str]) -> PhotoListing:
    """Walk a folder recursively for photos.

    Symbolic links are followed, and each real folder is visited once, so a
    link loop ends the walk of that branch instead of running forever. Files
    of other kinds are skipped.

    Parameters
    ----------
    folder : path-like

    Returns
    -------
    PhotoListing

    Raises
    ------
    ParameterError
        If ``folder`` is missing or not a folder.
    """
    root = os.path.normpath(os.fspath(folder))
    if not os.path.exists(root):
        raise ParameterError(f"{folder}: folder not found")
    if not os.path.isdir(root):
        raise ParameterError(f"{folder}: is a file, not a folder; use 'rockscan classify' for single photos")
    photos: list[str] = []
    problems: list[tuple[str, str]] = []
    n_skipped = 0
    endings: set[str] = set()
    visited: set[tuple[int, int]] = set()
    stack = [root]
    while stack:
        current = stack.pop()
        try:
            st = os.stat(current)
            identity = (st.st_dev, st.st_ino)
            if identity in visited:
                continue
            visited.add(identity)
            with os.scandir(current) as it:
                entries = sorted(it, key=lambda e: e.name)
        except OSError as exc:
            problems.append((current, f"cannot list folder ({exc.strerror or exc})"))
            continue
        subfolders = []
        for entry in entries:
            try:
                is_dir = entry.is_dir()
            except OSError:  # e.g. a link that points at itself
                is_dir = False
            if is_dir:
                subfolders.append(entry.path)
            elif entry.name.lower().endswith(IMAGE_SUFFIXES):
                photos.append(entry.path)
            else:
                # Said in the summary: a folder of HEIC photos gave an empty report without a word.
                n_skipped += 1
                if len(endings) < SKIPPED_ENDINGS:
                    endings.add(os.path.splitext(entry.name)[1].lower())
        stack.extend(reversed(subfolders))
    return PhotoListing(
        photos=tuple(photos),
        problems=tuple(problems),
        n_skipped=n_skipped,
        skipped_endings=tuple(sorted(endings)),
    )
