"""``rockscan triage``: rank a folder of photos by interest."""

from __future__ import annotations
