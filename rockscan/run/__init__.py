"""Running the stages on photos and folders: the pipeline and triage.

Composes ``rockscan.core``, ``rockscan.io`` and ``rockscan.draw``.
"""
