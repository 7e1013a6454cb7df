"""Drawing: figures, thumbnails and the triage contact sheet.

Imports ``rockscan.core`` and ``rockscan.io``; matplotlib is imported only here.
"""
