"""The paper's experiments: its shapes and tables, the samples, and the runs.

Every sample is matched by both matchers (`METHODS`) and recorded as a `Row` in
a `Matcher`; nothing here draws or writes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from rockscan import (
    FaceConfig,
    Library,
    MatchConfig,
    RockscanError,
    ShapeSpec,
    SuperformulaParams,
    match_radii,
    polar_angles,
    recenter_radii,
    shape_radii,
)

#: The paper's library shapes (Section IV, Fig. 7): name -> (label, parameters).
SHAPES: dict[str, tuple[str, SuperformulaParams]] = {
    "rounded-triangle": ("Rounded Triangle", SuperformulaParams(3, 3, 1500, 1500, 1500)),
    "three-faced-blunt": ("3-Faced Blunt", SuperformulaParams(6, 6, 60, 55, 10)),
    "six-pointed-star": ("6-Pointed Star", SuperformulaParams(6, 6, 0.2, 1.7, 1.7)),
}
#: The near shapes of Tables II-IV, by base shape.
NEAR: dict[str, SuperformulaParams] = {
    "rounded-triangle": SuperformulaParams(3, 3, 1650, 1650, 1650),
    "three-faced-blunt": SuperformulaParams(6, 6, 66, 60.5, 11),
    "six-pointed-star": SuperformulaParams(6, 6, 0.205, 1.71, 1.71),
}
#: The paper's Tables I and V: MScore, outWeight, Nearest Match, Average outWeight.
PAPER_TABLES: dict[str, dict[str, tuple[float, float, float, float]]] = {
    "I": {
        "rounded-triangle": (1.0, 0.0, 2.1e-3, 3.5e-3),
        "three-faced-blunt": (1.0, 0.0, 2.3e-3, 3.9e-3),
        "six-pointed-star": (1.0, 0.0, 2.8e-3, 4.9e-3),
    },
    "V": {
        "rounded-triangle": (1.0, 8.9e-7, 2.1e-3, 3.5e-3),
        "three-faced-blunt": (1.0, 1.1e-5, 2.3e-3, 3.9e-3),
        "six-pointed-star": (0.92, 3.6e-4, 2.6e-3, 4.7e-3),
    },
}
#: The paper's exact method: the eigenspace distance ranks the shapes and picks the angle.
PAPER = MatchConfig.paper()
#: The two matchers every experiment runs.
METHODS: dict[str, MatchConfig] = {"default": MatchConfig(), "paper": PAPER}


@dataclass(frozen=True)
class Settings:
    """How thoroughly to sample each experiment."""

    seed: int = 2017
    n_seeds: int = 20
    noise_levels: tuple[float, ...] = tuple(i / 100 for i in range(21))
    #: 1.25 deg puts samples on the rays and a quarter, half and three quarters between them.
    angle_step_deg: float = 1.25
    m_values: tuple[float, ...] = tuple(float(m) for m in np.arange(1.0, 12.01, 0.5))
    factors: tuple[float, ...] = tuple(float(f) for f in np.geomspace(0.25, 4.0, 17))
    #: The Cartesian grid map needs a new face per rotation (about 0.1 s a scan),
    #: so beside the tables it runs the default matcher on a subset of each sweep:
    #: the first noise draws, every n-th angle and every n-th parameter value (0: none).
    cartesian_seeds: int = 3
    cartesian_angle_every: int = 12
    cartesian_param_every: int = 1
    cartesian_table_methods: tuple[str, ...] = ("default", "paper")
    #: Why noise moves the two grids apart: draws at this level, matched without the scan.
    check_level: float = 0.1
    check_seeds: int = 5
    check_map_size: int = 300
    dpi: int = 100


QUICK = Settings(
    n_seeds=2,
    noise_levels=(0.0, 0.05, 0.2),
    angle_step_deg=45.0,
    m_values=(2.0, 3.0, 6.0),
    factors=(0.5, 1.0, 2.0),
    cartesian_seeds=0,
    cartesian_angle_every=0,
    cartesian_param_every=0,
    cartesian_table_methods=(),
    check_seeds=1,
    check_map_size=120,
    dpi=40,
)


@dataclass(frozen=True)
class Row:
    """One sample matched by one matcher on one grid."""

    experiment: str
    shape: str
    x: float
    seed: int
    method: str
    grid: str
    scan: bool
    nearest: str
    correct: bool
    mscore: float
    out_weight: float
    nearest_other: float
    average: float
    angle_error_deg: float


# ---------------------------------------------------------------- samples


def library_specs() -> list[ShapeSpec]:
    """The paper's three library shapes as specs."""
    return [ShapeSpec(name, params) for name, (_, params) in SHAPES.items()]


def turned_radii(params: SuperformulaParams, angle_deg: float, n_angles: int) -> np.ndarray:
    """A Superformula shape turned counter-clockwise by ``angle_deg``, sampled at the
    matcher's rays about its own centroid (the exact curve, not an interpolation)."""
    raw = params.radii(polar_angles(n_angles) - math.radians(angle_deg))
    return recenter_radii(raw)[0]


def noise_errors(settings: Settings, shape_index: int, draw: int, n_angles: int) -> np.ndarray:
    """The standard normal errors of one noise draw of one shape, the same in every experiment."""
    return np.random.default_rng([settings.seed, shape_index, draw]).standard_normal(n_angles)


def noisy_radii(radii: np.ndarray, level: float, errors: np.ndarray) -> np.ndarray:
    """Fig. 11's sensor model: every radius times ``1 + level * e``, e standard normal.

    A radius cannot be negative; the clip matters only past five standard errors.
    """
    return np.maximum(radii * (1.0 + level * errors), 0.0)


def angle_error_deg(angle_deg: float, truth_deg: float, symmetry: int) -> float:
    """Angle error folded by the shape's order of symmetry (0: a circle, any angle is right)."""
    if symmetry == 0:
        return 0.0
    period = 360.0 / symmetry
    d = (angle_deg - truth_deg) % period
    return float(min(d, period - d))


def sweep_params(base: SuperformulaParams, parameter: str, value: float) -> SuperformulaParams:
    """The base shape with m (m1 = m2), n1, or n2 and n3 together, changed."""
    if parameter == "m":
        return replace(base, m1=value, m2=value)
    if parameter == "n1":
        return replace(base, n1=base.n1 * value)
    return replace(base, n2=base.n2 * value, n3=base.n3 * value)


# ---------------------------------------------------------------- matching


@dataclass
class Matcher:
    """The two libraries (polar and Cartesian grid) and every result so far."""

    polar: Library
    cartesian: Library
    rows: list[Row]

    @classmethod
    def build(cls) -> Matcher:
        specs = library_specs()
        return cls(
            polar=Library.from_shapes(specs),
            cartesian=Library.from_shapes(specs, face_config=FaceConfig(grid="cartesian")),
            rows=[],
        )

    def run(
        self,
        radii: np.ndarray,
        *,
        experiment: str,
        shape: str,
        x: float,
        seed: int = 0,
        truth_angle_deg: float = 0.0,
        methods: Iterable[str] = METHODS,
        grids: Iterable[str] = ("polar",),
        scans: Iterable[bool] = (True,),
    ) -> None:
        """Match one sample with every method, grid and scan setting asked for."""
        for grid in grids:
            library = self.polar if grid == "polar" else self.cartesian
            for scan in scans:
                for method in methods:
                    config = replace(METHODS[method], scan=scan)
                    match = match_radii(radii, library, config)
                    k = library.index(match.nearest)
                    correct = match.nearest == shape
                    error = (
                        angle_error_deg(match.angle_deg, truth_angle_deg, match.symmetry)
                        if scan and correct
                        else math.nan
                    )
                    self.rows.append(
                        Row(
                            experiment=experiment,
                            shape=shape,
                            x=float(x),
                            seed=seed,
                            method=method,
                            grid=grid,
                            scan=scan,
                            nearest=match.nearest,
                            correct=correct,
                            mscore=float(match.mscore),
                            out_weight=float(match.distances[k]),
                            nearest_other=float(np.delete(match.distances, k).min()),
                            average=float(match.distances.mean()),
                            angle_error_deg=error,
                        )
                    )

    def select(self, **where: object) -> list[Row]:
        return [row for row in self.rows if all(getattr(row, key) == value for key, value in where.items())]


# ---------------------------------------------------------------- the runs


def run_tables(matcher: Matcher, settings: Settings) -> None:
    """Tables I and V: the library shapes and the near shapes, with and without the scan."""
    for table, samples in (("I", {name: p for name, (_, p) in SHAPES.items()}), ("V", NEAR)):
        for name, params in samples.items():
            radii = shape_radii(params, matcher.polar.face_config.n_angles)
            matcher.run(radii, experiment=f"table-{table}", shape=name, x=0.0, scans=(True, False))
            matcher.run(
                radii,
                experiment=f"table-{table}",
                shape=name,
                x=0.0,
                methods=settings.cartesian_table_methods,
                grids=("cartesian",),
                scans=(True, False),
            )


def run_noise(matcher: Matcher, settings: Settings) -> None:
    """Fig. 12: every draw scaled to every noise level."""
    n = matcher.polar.face_config.n_angles
    for index, (name, (_, params)) in enumerate(SHAPES.items()):
        radii = shape_radii(params, n)
        for seed in range(settings.n_seeds):
            # The same errors at every level (common random numbers): the curves
            # show the effect of the level, not of a new draw at each point.
            errors = noise_errors(settings, index, seed, n)
            for level in settings.noise_levels:
                sample = noisy_radii(radii, level, errors)
                grids = ("polar", "cartesian") if seed < settings.cartesian_seeds else ("polar",)
                for grid in grids:
                    matcher.run(
                        sample,
                        experiment="noise",
                        shape=name,
                        x=level,
                        seed=seed,
                        grids=(grid,),
                        methods=METHODS if grid == "polar" else ("default",),
                    )


def run_rotation(matcher: Matcher, settings: Settings) -> None:
    """Fig. 13: every turn, without and with the scan."""
    n = matcher.polar.face_config.n_angles
    angles = np.arange(0.0, 360.0, settings.angle_step_deg)
    for name, (_, params) in SHAPES.items():
        for i, angle in enumerate(angles):
            sample = turned_radii(params, float(angle), n)
            common = {"experiment": "rotation", "shape": name, "x": float(angle), "truth_angle_deg": angle}
            matcher.run(sample, scans=(False, True), **common)
            matcher.run(sample, grids=("cartesian",), scans=(False,), methods=("default",), **common)
            if settings.cartesian_angle_every and i % settings.cartesian_angle_every == 0:
                matcher.run(sample, grids=("cartesian",), methods=("default",), **common)


def run_parameters(matcher: Matcher, settings: Settings) -> list[str]:
    """Figs. 14-16; returns the sweep points that make no closed shape."""
    n = matcher.polar.face_config.n_angles
    skipped = []
    for parameter, values in (("m", settings.m_values), ("n1", settings.factors), ("n23", settings.factors)):
        for name, (_, params) in SHAPES.items():
            for i, value in enumerate(values):
                try:
                    sample = shape_radii(sweep_params(params, parameter, value), n)
                except RockscanError as exc:
                    skipped.append(f"{name} {parameter}={value:g}: {exc}")
                    continue
                matcher.run(sample, experiment=parameter, shape=name, x=value)
                if settings.cartesian_param_every and i % settings.cartesian_param_every == 0:
                    matcher.run(
                        sample,
                        experiment=parameter,
                        shape=name,
                        x=value,
                        grids=("cartesian",),
                        methods=("default",),
                    )
    return skipped


def run_noise_check(matcher: Matcher, settings: Settings) -> dict[str, dict[str, float]]:
    """Why noise moves the Cartesian grid map's MScores above the polar grid's.

    The same noisy samples (no scan, default matcher) on four faces: the polar
    grid; the polar grid after smoothing the radii over three neighbouring rays
    (weights 1/4, 1/2, 1/4); the 100-pixel Cartesian map; and a finer one. If
    the finer map agrees with the coarse one while smoothing moves the polar grid
    the same way, it is the map's interpolation between rays, not its pixel
    count, that averages some noise away.
    """
    n = matcher.polar.face_config.n_angles
    fine = Library.from_shapes(
        library_specs(), face_config=FaceConfig(grid="cartesian", cartesian_size=settings.check_map_size)
    )
    config = replace(METHODS["default"], scan=False)
    out = {}
    for index, (name, (_, params)) in enumerate(SHAPES.items()):
        radii = shape_radii(params, n)
        scores: dict[str, list[float]] = {"polar": [], "smoothed": [], "cartesian": [], "fine": []}
        for seed in range(settings.check_seeds):
            sample = noisy_radii(radii, settings.check_level, noise_errors(settings, index, seed, n))
            smoothed = 0.25 * np.roll(sample, 1) + 0.5 * sample + 0.25 * np.roll(sample, -1)
            scores["polar"].append(match_radii(sample, matcher.polar, config).mscore)
            scores["smoothed"].append(match_radii(smoothed, matcher.polar, config).mscore)
            scores["cartesian"].append(match_radii(sample, matcher.cartesian, config).mscore)
            scores["fine"].append(match_radii(sample, fine, config).mscore)
        out[name] = {key: float(np.mean(values)) for key, values in scores.items()}
    return out


@dataclass(frozen=True)
class Results:
    """Every run: the matched rows, the sweep points left out, and the four-face noise check."""

    matcher: Matcher
    skipped: list[str]
    check: dict[str, dict[str, float]]


def run_all(settings: Settings) -> Results:
    """Run every experiment in the paper's order."""
    matcher = Matcher.build()
    run_tables(matcher, settings)
    run_noise(matcher, settings)
    run_rotation(matcher, settings)
    skipped = run_parameters(matcher, settings)
    return Results(matcher=matcher, skipped=skipped, check=run_noise_check(matcher, settings))
