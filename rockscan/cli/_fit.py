"""``rockscan library fit`` and ``rockscan library family``: grow a library from examples."""

from __future__ import annotations
