"""Read-only views of the arrays a shared object holds."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


def freeze_arrays(obj: Any) -> None:
    """Replace every ndarray field of a frozen dataclass by a read-only view of it.

    A library and what it caches (its sensor metric, scan templates,
    prefilters) are shared by every match in a process, and
    ``default_library()`` is one object: one caller's edit of a cached array
    would change every later match. A view costs no copy, and leaves the
    array it was made from as writable as it was.
    """
    for field in dataclasses.fields(obj):
        value = getattr(obj, field.name, None)
        if isinstance(value, np.ndarray) and value.flags.writeable:
            view = value.view()
            view.setflags(write=False)
            object.__setattr__(obj, field.name, view)
