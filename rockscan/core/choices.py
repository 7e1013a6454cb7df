"""Names of the choices the library offers, importable without numpy.

The stages define their behaviour for each name; the command line offers these
names as its option choices, so both always agree.
"""

from __future__ import annotations

#: Face kinds: the paper's variants 1 and 2, and the plain radii baseline.
FACE_KINDS = ("information", "information-shape", "radii")
#: Grids a face may live on.
GRIDS = ("polar", "cartesian")
#: What a match distance measures.
METRICS = ("eigenspace", "face")
#: What ranks library shapes: the sensor-model distance, a face metric, or "auto" (the sensor distance).
RANK_METRICS = ("auto", "sensor", *METRICS)
#: What a novelty score measures (the whole face by default; see rockscan.core.novelty).
NOVELTY_METRICS = ("face", "eigenspace")
#: Matcher presets of the command line: rockscan's default and the paper's exact method.
METHODS = ("default", "paper")
#: Rock polarity of a rendered photo ("random" draws it per photo).
RENDER_POLARITIES = ("random", "light", "dark")
#: Rock polarity settings of the segmentation.
POLARITIES = ("auto", "dark", "light")
#: Outline noise a library tolerates unless told otherwise: the paper's claim of 20%.
DEFAULT_TOLERANCE = 0.2
