"""The numbers read from the runs: table rows, curves, and how the matchers and grids agree.

Pure data in and out; the figures and the document both read these.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .experiments import METHODS, PAPER_TABLES, SHAPES, Matcher, Row


def table_rows(matcher: Matcher, table: str) -> list[dict[str, object]]:
    """Rows of the reproduction of Table I or V (polar grid), with the paper's numbers."""
    out = []
    for name, (label, _) in SHAPES.items():
        paper = PAPER_TABLES[table][name]
        for method in METHODS:
            where = {"experiment": f"table-{table}", "shape": name, "method": method, "grid": "polar"}
            (scan,) = matcher.select(scan=True, **where)
            (fixed,) = matcher.select(scan=False, **where)
            out.append(
                {
                    "shape": name,
                    "label": label if table == "I" else f"Near {label}",
                    "method": method,
                    "paper": dict(zip(("mscore", "out_weight", "nearest", "average"), paper, strict=True)),
                    "mscore": scan.mscore,
                    "mscore_no_scan": fixed.mscore,
                    "out_weight": scan.out_weight,
                    "nearest": scan.nearest_other,
                    "average": scan.average,
                    "out_weight_no_scan": fixed.out_weight,
                    "nearest_no_scan": fixed.nearest_other,
                    "average_no_scan": fixed.average,
                    "match": scan.nearest,
                    "correct": scan.correct and fixed.correct,
                }
            )
    return out


def paper_pairwise_distances() -> dict[str, tuple[float, float]]:
    """The two distances to the other shapes that Table I implies for each shape.

    In a library of three shapes, Average outWeight = (0 + d1 + d2) / 3 with d1 the
    Nearest Match; excluding the shape's own 0 it would be (d1 + d2) / 2.
    """
    return {
        name: (nearest, 3 * average - nearest) for name, (_, _, nearest, average) in PAPER_TABLES["I"].items()
    }


# ---------------------------------------------------------------- agreement


def _key(row: Row) -> tuple[object, ...]:
    return (row.experiment, row.shape, row.x, row.seed, row.method, row.scan)


def grid_pairs(matcher: Matcher) -> list[tuple[Row, Row]]:
    """(polar, Cartesian) results of the same sample, matcher and scan setting."""
    polar = {_key(r): r for r in matcher.rows if r.grid == "polar"}
    return [(polar[_key(r)], r) for r in matcher.rows if r.grid == "cartesian"]


def grid_agreement(matcher: Matcher) -> dict[str, object]:
    """Same winners and MScore differences between the grids, overall and per experiment."""
    pairs = grid_pairs(matcher)
    by_experiment: dict[str, dict[str, object]] = {}
    for experiment in dict.fromkeys(p.experiment for p, _ in pairs):
        subset = [(p, c) for p, c in pairs if p.experiment == experiment]
        diffs = np.array([abs(p.mscore - c.mscore) for p, c in subset])
        worst_p, worst_c = subset[int(np.argmax(diffs))]
        by_experiment[experiment] = {
            "pairs": len(subset),
            "same_winner": sum(p.nearest == c.nearest for p, c in subset),
            "max_mscore_diff": float(diffs.max()),
            "median_mscore_diff": float(np.median(diffs)),
            "worst": f"{_describe(worst_p)} (polar {worst_p.mscore:.4f}, Cartesian {worst_c.mscore:.4f})",
        }
    diffs = np.array([abs(p.mscore - c.mscore) for p, c in pairs])
    disagree = [
        f"{_describe(p)}: polar {p.nearest}, Cartesian {c.nearest}"
        for p, c in pairs
        if p.nearest != c.nearest
    ]
    quiet = [abs(p.mscore - c.mscore) for p, c in pairs if p.experiment != "noise"]
    noisy = [c.mscore > p.mscore for p, c in pairs if p.experiment == "noise" and p.x > 0]
    return {
        "pairs": len(pairs),
        "same_winner": len(pairs) - len(disagree),
        "max_mscore_diff": float(diffs.max()),
        "median_mscore_diff": float(np.median(diffs)),
        "max_mscore_diff_without_noise": float(max(quiet)),
        "cartesian_higher_under_noise": float(np.mean(noisy)) if noisy else None,
        "disagreements": disagree,
        "by_experiment": by_experiment,
    }


def _describe(row: Row) -> str:
    where = {
        "noise": f"{row.x:.0%} noise, draw {row.seed}",
        "rotation": f"turned {row.x:g} deg",
        "m": f"m = {row.x:g}",
        "n1": f"n1 x {row.x:.3g}",
        "n23": f"n2, n3 x {row.x:.3g}",
    }.get(row.experiment, row.experiment.replace("-", " "))
    scan = "" if row.scan else ", no scan"
    return f"{SHAPES[row.shape][0]}, {where}, {row.method}{scan}"


def method_agreement(matcher: Matcher) -> dict[str, object]:
    """How far the two matchers' MScores and winners differ (polar grid), overall and per experiment."""
    pairs: dict[tuple[object, ...], dict[str, Row]] = {}
    for r in matcher.rows:
        if r.grid == "polar":
            pairs.setdefault((r.experiment, r.shape, r.x, r.seed, r.scan), {})[r.method] = r
    complete = [p for p in pairs.values() if len(p) == len(METHODS)]
    by_experiment = {}
    for experiment in dict.fromkeys(p["default"].experiment for p in complete):
        subset = [p for p in complete if p["default"].experiment == experiment]
        diffs = np.array([abs(p["default"].mscore - p["paper"].mscore) for p in subset])
        by_experiment[experiment] = {
            "pairs": len(subset),
            "max_mscore_diff": float(diffs.max()),
            "median_mscore_diff": float(np.median(diffs)),
            "winner_differs": sum(p["default"].nearest != p["paper"].nearest for p in subset),
            "default_correct": sum(p["default"].correct for p in subset),
            "paper_correct": sum(p["paper"].correct for p in subset),
            "default_lower": sum(p["default"].mscore < p["paper"].mscore - 1e-9 for p in subset),
        }
    return {
        "pairs": len(complete),
        "default_lower": sum(int(e["default_lower"]) for e in by_experiment.values()),
        "max_mscore_diff": max(float(e["max_mscore_diff"]) for e in by_experiment.values()),
        "winner_differs": sum(int(e["winner_differs"]) for e in by_experiment.values()),
        "by_experiment": by_experiment,
    }


# ---------------------------------------------------------------- curves


def curve(
    matcher: Matcher, experiment: str, shape: str, method: str, value: Callable[[Row], float], **where: object
) -> tuple[np.ndarray, np.ndarray]:
    """x and the values of the polar grid's rows, grouped by x: (n_x,), (n_x, n_repeats)."""
    rows = matcher.select(experiment=experiment, shape=shape, method=method, grid="polar", **where)
    xs = sorted({r.x for r in rows})
    groups = [[value(r) for r in rows if r.x == x] for x in xs]
    values = np.full((len(xs), max(len(g) for g in groups)), np.nan)
    for i, g in enumerate(groups):
        values[i, : len(g)] = g
    return np.array(xs), values


def nanmedian_rows(values: np.ndarray) -> np.ndarray:
    """Median of each row's finite values (NaN for a row without any)."""
    return np.array([np.median(v[np.isfinite(v)]) if np.isfinite(v).any() else np.nan for v in values])


def _noise_findings(matcher: Matcher) -> dict[str, dict[str, object]]:
    """Fig. 12 per shape and matcher: MScore spread, correct share and angle error by level."""
    noise: dict[str, dict[str, object]] = {}
    for name in SHAPES:
        noise[name] = {}
        for method in METHODS:
            xs, mscore = curve(matcher, "noise", name, method, lambda r: r.mscore)
            _, correct = curve(matcher, "noise", name, method, lambda r: r.correct)
            errors = nanmedian_rows(curve(matcher, "noise", name, method, lambda r: r.angle_error_deg)[1])
            rate = correct.mean(axis=1)
            failing = [float(x) for x, c in zip(xs, rate, strict=True) if c < 1]
            noise[name][method] = {
                "levels": xs.tolist(),
                "mscore_mean": mscore.mean(axis=1).tolist(),
                "mscore_p10": np.percentile(mscore, 10, axis=1).tolist(),
                "mscore_p90": np.percentile(mscore, 90, axis=1).tolist(),
                "correct_rate": rate.tolist(),
                "first_wrong_level": failing[0] if failing else None,
                "angle_error_median": errors.tolist(),
            }
    return noise


def _rotation_findings(matcher: Matcher) -> dict[str, dict[str, object]]:
    """Fig. 13 per shape and matcher: lowest MScores, wins and angle errors without and with the scan."""
    rotation: dict[str, dict[str, object]] = {}
    step = 360 / matcher.polar.face_config.n_angles
    for name in SHAPES:
        rotation[name] = {"symmetry": int(matcher.polar.symmetry[matcher.polar.index(name)])}
        for method in METHODS:
            xs, fixed = curve(matcher, "rotation", name, method, lambda r: r.mscore, scan=False)
            _, scanned = curve(matcher, "rotation", name, method, lambda r: r.mscore, scan=True)
            _, fixed_ok = curve(matcher, "rotation", name, method, lambda r: r.correct, scan=False)
            _, scanned_ok = curve(matcher, "rotation", name, method, lambda r: r.correct, scan=True)
            _, errors = curve(matcher, "rotation", name, method, lambda r: r.angle_error_deg, scan=True)
            on_ray = np.isclose(np.mod(xs + step / 2, step) - step / 2, 0.0)
            rotation[name][method] = {
                "n_angles": len(xs),
                "no_scan_min": float(fixed.min()),
                "no_scan_correct": int(fixed_ok.sum()),
                "returns_to_1_at": [float(x) for x, v in zip(xs, fixed[:, 0], strict=True) if v > 1 - 1e-9],
                "scan_min": float(scanned.min()),
                "scan_min_on_ray": float(scanned[on_ray].min()),
                "scan_correct": int(scanned_ok.sum()),
                "angle_error_max": float(np.nanmax(errors)),
                "angle_error_median": float(np.nanmedian(errors)),
            }
    return rotation


def _parameter_findings(matcher: Matcher) -> dict[str, dict[str, dict[str, object]]]:
    """Figs. 14-16 per parameter and shape (default matcher): MScore next to the base and at its lowest."""
    params: dict[str, dict[str, dict[str, object]]] = {}
    for parameter in ("m", "n1", "n23"):
        params[parameter] = {}
        for name, (_, base_params) in SHAPES.items():
            xs, mscore = curve(matcher, parameter, name, "default", lambda r: r.mscore)
            _, correct = curve(matcher, parameter, name, "default", lambda r: r.correct)
            mscore, correct = mscore[:, 0], correct[:, 0].astype(bool)
            base = base_params.m1 if parameter == "m" else 1.0
            below, above = np.flatnonzero(xs < base), np.flatnonzero(xs > base)
            away = xs != base
            lowest = int(np.argmin(np.where(away, mscore, np.inf)))
            params[parameter][name] = {
                "x": xs.tolist(),
                "mscore": mscore.tolist(),
                "correct": correct.tolist(),
                "base": base,
                "below": (float(xs[below[-1]]), float(mscore[below[-1]])) if below.size else None,
                "above": (float(xs[above[0]]), float(mscore[above[0]])) if above.size else None,
                "lowest": (float(xs[lowest]), float(mscore[lowest])),
                "base_nearest": int(correct[away].sum()),
                "points_away": int(away.sum()),
            }
    return params


def _triangle_mirror(params: dict[str, dict[str, dict[str, object]]]) -> float | None:
    """Largest MScore difference between the triangle's n1 x f and its n2, n3 x 1/f.

    For large exponents only n2/n1 and n3/n1 shape the curve, so for the rounded
    triangle scaling n1 by f should look like scaling n2, n3 by 1/f.
    """
    n1 = params["n1"]["rounded-triangle"]
    n23 = params["n23"]["rounded-triangle"]
    mirror = [
        abs(a - b)
        for x, a in zip(n1["x"], n1["mscore"], strict=True)
        for y, b in zip(n23["x"], n23["mscore"], strict=True)
        if math.isclose(x * y, 1.0, rel_tol=1e-9)
    ]
    return float(max(mirror)) if mirror else None


def findings(matcher: Matcher) -> dict[str, object]:
    """The numbers the README section quotes."""
    params = _parameter_findings(matcher)
    face = matcher.polar.faces()
    return {
        "noise": _noise_findings(matcher),
        "rotation": _rotation_findings(matcher),
        "parameters": params,
        "triangle_mirror_max_diff": _triangle_mirror(params),
        "methods": method_agreement(matcher),
        "grids": grid_agreement(matcher),
        "face": {
            "polar_max": float(face.max()),
            "polar_pixels": int(np.prod(matcher.polar.face_config.face_shape)),
            "cartesian_pixels": int(np.prod(matcher.cartesian.face_config.face_shape)),
        },
    }
