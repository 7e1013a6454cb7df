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
#: What ranks library shapes: the sensor-model distance, a face metric, or "auto" (the
#: eigenspace distance for a clean outline, the sensor distance for a noisy one).
RANK_METRICS = ("auto", "sensor", *METRICS)
#: What a novelty score measures (the whole face by default; see rockscan.core.novelty).
NOVELTY_METRICS = ("face", "eigenspace")
#: Matcher presets of the command line: rockscan's default and the paper's exact method.
METHODS = ("default", "paper")
#: Rock polarity of a rendered photo ("random" draws it per photo).
RENDER_POLARITIES = ("random", "light", "dark")
#: Rock polarity settings of the segmentation.
POLARITIES = ("auto", "dark", "light")
#: Photo pixels per millimetre a size may be given in: a pixel of a kilometre to one of a
#: nanometre. Beyond them an area in square millimetres overflows to inf (or underflows to 0).
PX_PER_MM_RANGE = (1e-6, 1e6)
#: Outline noise a library tolerates unless told otherwise: the paper's claim of 20%.
DEFAULT_TOLERANCE = 0.2
#: Most rays a library's faces may have: a tenth of a degree (a face of 3,600 rays of 50
#: sections is 1.4 MB; a library past its loader's budget per array could not be read).
MAX_FACE_ANGLES = 3600
#: Largest side of the paper's Cartesian grid map (4096 x 4096 cells are 128 MiB of floats).
MAX_CARTESIAN = 4096
