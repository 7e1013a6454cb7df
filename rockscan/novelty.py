"""Novelty (paper Section V): how far a sample is from every shape seen so far.

The paper proposes a second library, "created during the mission of observed
shapes", against which each new sample is compared; the distance to the
nearest of them quantifies its novelty. rockscan builds it from the same
parts as the library of interest: an :class:`ObservedShapes` holds a
:class:`rockscan.library.Library` (and so an :class:`rockscan.eigen.EigenBasis`)
of the known shapes, is saved with :func:`rockscan.io.save_library`, and grows
by one shape each time a sample lies farther than a threshold from all of them.

Choices (documented in docs/triage.md, "Novelty"):

* **Seed.** A new observed library starts from the library of interest's
  shapes: Section V compares a sample "both to that library and a library
  created during the mission", and a rock that one of the library's shapes
  already describes is not new. It also gives the observed library the two
  shapes a library needs from the start.
* **Distance.** The novelty score is the distance between the sample's face
  and the nearest known shape's face, each at its best rotation:
  ``sqrt(eps**2 + dffs**2)``, the eigenspace distance ``eps`` plus the distance
  from face space (``metric="face"``). The eigenspace distance alone is blind to
  whatever the known shapes do not span, and that part is exactly what makes
  a shape new; ``metric="eigenspace"`` gives the paper's ``eps`` alone.
* **Threshold.** By default half the median distance from each library shape
  to its nearest other library shape (:func:`default_threshold`): a sample is
  new when it lies farther from everything known than the library's own
  shapes lie, halfway, from each other.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from rockscan._choices import NOVELTY_METRICS
from rockscan.errors import LibraryError, ParameterError
from rockscan.information import information_face
from rockscan.library import Library
from rockscan.match import MatchConfig, match_radii, rotation_scores

__all__ = [
    "NOVELTY_METRICS",
    "Novelty",
    "NoveltyConfig",
    "ObservedShapes",
    "default_threshold",
    "observed_name",
]

#: Prefix of the names of shapes added to an observed library.
OBSERVED_PREFIX = "seen-"
_NAME_CHARS = re.compile(r"[^a-z0-9]+")


@dataclass(frozen=True)
class NoveltyConfig:
    """Settings of the novelty score.

    Parameters
    ----------
    threshold : float or None
        A sample whose novelty exceeds this is flagged novel and added to the
        observed library. None takes :func:`default_threshold` of the library
        of interest.
    metric : {"face", "eigenspace"}
        ``"face"``: distance between whole faces (eigenspace distance and
        distance from face space); ``"eigenspace"``: the paper's ``eps`` only.
    """

    threshold: float | None = None
    metric: str = "face"

    def __post_init__(self) -> None:
        if self.metric not in NOVELTY_METRICS:
            raise ParameterError(
                f"novelty metric must be one of {', '.join(NOVELTY_METRICS)}; got {self.metric!r}"
            )
        if self.threshold is not None and not (
            isinstance(self.threshold, (int, float)) and math.isfinite(self.threshold) and self.threshold >= 0
        ):
            raise ParameterError(
                f"novelty threshold must be a non-negative number, got {self.threshold!r}; "
                "leave it unset for the library's default"
            )


@dataclass(frozen=True)
class Novelty:
    """How new one sample is.

    Attributes
    ----------
    score : float
        Distance to the nearest known shape at its best rotation (face units).
    nearest : str
        That shape's name.
    novel : bool
        ``score > threshold``.
    """

    score: float
    nearest: str
    novel: bool


def default_threshold(library: Library, *, metric: str = "face") -> float:
    """Half the median distance from each library shape to its nearest other one.

    Parameters
    ----------
    library : Library
        The library of interest.
    metric : {"face", "eigenspace"}

    Returns
    -------
    threshold : float
        In the units of the novelty score.

    Notes
    -----
    The library's shapes are the scale at which rockscan tells shapes apart: a
    sample closer to a known shape than half their typical spacing would be
    taken for that shape by the nearest-neighbour rule, and one farther from all
    of them is new. Each distance is taken at the best rotation, as the score is.
    For the built-in library this is about 0.13; photos of a library shape at
    480 x 640 pixels lie within 0.05 of it (docs/triage.md, "Novelty").
    """
    if metric not in NOVELTY_METRICS:
        raise ParameterError(f"metric must be one of {', '.join(NOVELTY_METRICS)}; got {metric!r}")
    nearest = []
    for k in range(len(library)):
        dist = rotation_scores(library.radii[k], library, metric=metric).min(axis=0)
        dist[k] = np.inf
        nearest.append(dist.min())
    return 0.5 * float(np.median(nearest))


def observed_name(stem: str, taken: tuple[str, ...] | set[str]) -> str:
    """A library name for a shape first seen in the photo ``stem``: ``seen-<stem>``,
    lower case letters, digits and dashes, made unique with ``-2``, ``-3``, ...

    Parameters
    ----------
    stem : str
        The photo's file name without its extension.
    taken : collection of str
        Names already in use.
    """
    base = OBSERVED_PREFIX + (_NAME_CHARS.sub("-", stem.lower()).strip("-")[:60] or "rock")
    name, count = base, 1
    while name in taken:
        count += 1
        name = f"{base}-{count}"
    return name


@dataclass(frozen=True, eq=False)
class ObservedShapes:
    """The shapes known so far and the novelty settings; immutable.

    Build one with :meth:`from_library` (a new mission: the library of interest's
    shapes) or :meth:`from_file` (one kept from earlier runs); grow it with
    :meth:`with_shape`, which returns a new object.

    Attributes
    ----------
    library : Library
        The known shapes and their eigenface basis.
    threshold : float
        Novelty above which a sample is novel.
    metric : {"face", "eigenspace"}
    n_seed : int
        How many of ``library``'s shapes came from the library of interest
        (the first ones); the rest were observed.
    """

    library: Library
    threshold: float
    metric: str = "face"
    n_seed: int = 0

    def __post_init__(self) -> None:
        NoveltyConfig(threshold=self.threshold, metric=self.metric)

    @classmethod
    def from_library(cls, library: Library, config: NoveltyConfig | None = None) -> ObservedShapes:
        """A new observed library seeded with the shapes of the library of interest.

        Parameters
        ----------
        library : Library
            The library of interest.
        config : NoveltyConfig, optional
        """
        config = config or NoveltyConfig()
        threshold = (
            default_threshold(library, metric=config.metric) if config.threshold is None else config.threshold
        )
        seed = Library.from_radii(
            library.names,
            library.radii,
            face_config=library.face_config,
            params=library.params,
            interest=library.interest,
            faces=library.faces(),
        )
        return cls(library=seed, threshold=float(threshold), metric=config.metric, n_seed=len(seed))

    @classmethod
    def from_file(
        cls, observed: Library, library: Library, config: NoveltyConfig | None = None
    ) -> ObservedShapes:
        """An observed library kept from earlier runs.

        Parameters
        ----------
        observed : Library
            As read by :func:`rockscan.io.load_library`.
        library : Library
            The library of interest; sets the default threshold and must share
            the observed library's face settings.
        config : NoveltyConfig, optional

        Raises
        ------
        LibraryError
            If the two libraries' faces are made differently.
        """
        config = config or NoveltyConfig()
        if observed.face_config.to_dict() != library.face_config.to_dict():
            raise LibraryError(
                "the observed library was built with other face settings than the library "
                f"({observed.face_config.to_dict()} vs {library.face_config.to_dict()}); "
                "start a new observed library file"
            )
        threshold = (
            default_threshold(library, metric=config.metric) if config.threshold is None else config.threshold
        )
        n_seed = sum(not name.startswith(OBSERVED_PREFIX) for name in observed.names)
        return cls(library=observed, threshold=float(threshold), metric=config.metric, n_seed=n_seed)

    @property
    def n_observed(self) -> int:
        """Number of shapes added from samples."""
        return len(self.library) - self.n_seed

    def assess(self, radii: ArrayLike) -> Novelty:
        """Novelty of one sample.

        Parameters
        ----------
        radii : (n_angles,) array_like of float
            The sample's radii at :func:`rockscan.polar.polar_angles`, any scale.

        Returns
        -------
        Novelty
        """
        # match_radii gives every shape's distance at its best rotation, the
        # nearest one recomputed exactly (a known shape scores 0, not ~1e-6).
        match = match_radii(radii, self.library, MatchConfig(metric=self.metric))
        score = float(match.distances[self.library.index(match.nearest)])
        return Novelty(score=score, nearest=match.nearest, novel=score > self.threshold)

    def with_shape(self, name: str, radii: ArrayLike) -> ObservedShapes:
        """A copy that also knows one more shape.

        Parameters
        ----------
        name : str
            Unique shape name (see :func:`observed_name`).
        radii : (n_angles,) array_like of float
            The shape's radii, any scale.

        Returns
        -------
        ObservedShapes
        """
        lib = self.library
        radii = np.asarray(radii, dtype=np.float64)
        if radii.shape != (lib.face_config.n_angles,):
            raise ParameterError(
                f"radii must be {lib.face_config.n_angles} values (the library's n_angles), got {radii.shape}"
            )
        grown = Library.from_radii(
            (*lib.names, name),
            np.vstack([lib.radii, radii[None, :]]),
            face_config=lib.face_config,
            params=(*lib.params, None),
            interest=np.append(lib.interest, 1.0),
            faces=np.concatenate([lib.faces(), information_face(radii, lib.face_config)[None]]),
        )
        return ObservedShapes(library=grown, threshold=self.threshold, metric=self.metric, n_seed=self.n_seed)
