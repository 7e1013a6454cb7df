"""The README section on the paper, written from the numbers: one function per part of it.

Every sentence that states a result reads it from the findings, so the text
follows the runs; nothing here matches or draws.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import fields
from pathlib import Path

import numpy as np

from rockscan import MatchConfig

from .experiments import METHODS, SHAPES, Matcher, Settings
from .findings import paper_pairwise_distances, table_rows

#: Distances below this are float rounding of a true 0.
ZERO = 1e-12
EXPERIMENTS = {
    "table-I": "Table I",
    "table-V": "Table V",
    "noise": "the noise sweep",
    "rotation": "the rotation sweep",
    "m": "the m sweep",
    "n1": "the n1 sweep",
    "n23": "the n2 = n3 sweep",
}
Noise = dict[str, dict[str, dict[str, object]]]


# ---------------------------------------------------------------- numbers and tables


def fmt(value: float, digits: int = 2) -> str:
    """A distance the way the paper prints it (``2.1e-3``); 0 below float rounding."""
    if value == 0 or abs(value) < ZERO:
        return "0"
    mantissa, exponent = f"{value:.{digits - 1}e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def fmt_score(value: float) -> str:
    """One of rockscan's MScores: four decimals."""
    return f"{value:.4f}"


def markdown_table(rows: list[dict[str, object]]) -> str:
    """Table I or V: the paper's numbers beside rockscan's."""
    lines = [
        "| Sample | Matcher | MScore, paper | MScore | MScore, no scan | outWeight, paper | outWeight "
        "| Nearest Match, paper | Nearest Match | Average outWeight, paper | Average outWeight "
        "| Correct Match |",
        "|" + "---|" * 12,
    ]
    for row in rows:
        paper = row["paper"]
        assert isinstance(paper, dict)
        lines.append(
            f"| {row['label']} | {row['method']} | {paper['mscore']:g} | {fmt_score(row['mscore'])} "
            f"| {fmt_score(row['mscore_no_scan'])} | {fmt(paper['out_weight'])} | {fmt(row['out_weight'])} "
            f"| {fmt(paper['nearest'])} | {fmt(row['nearest'])} | {fmt(paper['average'])} "
            f"| {fmt(row['average'])} | {'Yes' if row['correct'] else 'No'} |"
        )
    return "\n".join(lines)


def ratio_table(rows: list[dict[str, object]]) -> str:
    """The comparable part of Tables I and V: ratios of distances (the paper's method, no scan)."""
    lines = [
        "| Sample | outWeight / Nearest, paper | outWeight / Nearest | Nearest / Average, paper "
        "| Nearest / Average |",
        "|---|---|---|---|---|",
    ]
    for row in rows:
        if row["method"] != "paper":
            continue
        paper = row["paper"]
        assert isinstance(paper, dict)
        ours_out = float(row["out_weight_no_scan"]) / float(row["nearest_no_scan"])
        lines.append(
            f"| {row['label']} | {fmt(paper['out_weight'] / paper['nearest'])} | {fmt(ours_out)} "
            f"| {paper['nearest'] / paper['average']:.2f} "
            f"| {float(row['nearest_no_scan']) / float(row['average_no_scan']):.2f} |"
        )
    return "\n".join(lines)


# ---------------------------------------------------------------- words


def _link(path: Path, doc_folder: Path) -> str:
    """A figure's link as written in a document in ``doc_folder``."""
    return Path(os.path.relpath(path.resolve(), doc_folder.resolve())).as_posix()


def _label(name: str) -> str:
    return SHAPES[name][0]


def _join(parts: Sequence[str]) -> str:
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]


def _config_call(config: MatchConfig) -> str:
    """The call that makes ``config``: its fields that differ from the defaults, in order."""
    default = MatchConfig()
    changed = {
        f.name: getattr(config, f.name)
        for f in fields(config)
        if getattr(config, f.name) != getattr(default, f.name)
    }
    # Double quotes, as the rest of the document writes Python strings.
    arguments = (
        f'{name}="{value}"' if isinstance(value, str) else f"{name}={value!r}"
        for name, value in changed.items()
    )
    return "MatchConfig(" + ", ".join(arguments) + ")"


def _distance_name(metric: str) -> str:
    return {
        "eigenspace": "eigenspace distance (the paper's)",
        "face": "whole-face distance",
        "sensor": "sensor-model distance",
    }[metric]


def _first_wrong(level: float | None, top: float) -> str:
    return f"at {level:.0%}" if level is not None else f"none up to {top:.0%}"


# ---------------------------------------------------------------- the introduction and the tables


def _intro_section(
    matcher: Matcher, ranking: str, seconds: float, command: str, shapes_link: str
) -> list[str]:
    """What was run, on which library, with which two matchers."""
    face_config = matcher.polar.face_config
    return [
        "## Reproducing the paper",
        "",
        "`scripts/reproduce_paper.py` repeats the simulation experiments of the paper (Fleetwood & "
        "Thangavelautham, Section IV) through rockscan's public API and writes this section and its figures: "
        f"`{command}` ({seconds:.0f} s on {os.cpu_count()} cores).",
        "",
        "As in the paper, the library holds its three shapes: the rounded triangle (m = 3, "
        "n1 = n2 = n3 = 1500), the three-faced blunt (m = 6, n1 = 60, n2 = 55, n3 = 10) and the six-pointed "
        "star (m = 6, n1 = 0.2, n2 = n3 = 1.7). Faces are the paper's variant 1 (reference circle, sensor "
        "sigma 0.1) on rockscan's "
        f"polar grid of {face_config.n_angles} rays cut into sections of "
        f"{face_config.resolution:g}. Every experiment runs two matchers:",
        "",
        f"- **default**: `{_config_call(METHODS['default'])}`, rockscan's matcher: here the "
        f"{_distance_name(ranking)} ranks the "
        'shapes (`metric="auto"` resolved for a library of three) and the whole-face distance picks the '
        "angle;",
        f"- **paper**: `{_config_call(METHODS['paper'])}`, the paper's exact method.",
        "",
        "Both scan all rotations unless a column or panel says *no scan* (`MatchConfig(scan=False)`). MScore "
        "is `1 - min(w) / mean(w)`; *Nearest Match* is the distance to the nearest *other* library shape and "
        "*Average outWeight* the mean distance to all three, each shape at its own best rotation when "
        "scanning, and *outWeight* the distance to the matched shape, all in the distance the matcher ranks "
        f"by. Distances below {ZERO:g}, float rounding of an exact 0, print as 0.",
        "",
        f"![The paper's shapes]({shapes_link})",
        "",
    ]


def _tables_section(matcher: Matcher) -> list[str]:
    """Tables I and V beside the paper's, and the ratios of distances that can be compared."""
    table_i, table_v = table_rows(matcher, "I"), table_rows(matcher, "V")
    default_i = [r for r in table_i if r["method"] == "default"]
    default_v = {str(r["shape"]): r for r in table_v if r["method"] == "default"}
    paper_v = {str(r["shape"]): r for r in table_v if r["method"] == "paper"}
    all_correct = all(r["correct"] for r in table_i + table_v)
    return [
        "### Table I: the library shapes matched to themselves",
        "",
        markdown_table(table_i),
        "",
        "### Table V: the near shapes of Tables II-IV",
        "",
        markdown_table(table_v),
        "",
        (
            "Every sample is matched to its own shape by both matchers, with and without the scan, as in "
            "the paper."
            if all_correct
            else "Not every sample is matched to its own shape: see the *Correct Match* column."
        )
        + " The library shapes score MScore "
        + _join([fmt_score(float(r["mscore"])) for r in default_i])
        + " at outWeight "
        + _join([fmt(float(r["out_weight"])) for r in default_i])
        + ". "
        + _near_order_sentence(default_v, paper_v),
        "",
        "Absolute distances depend on the face (see the differences below), so what can be compared is "
        "ratios (the paper's method, no scan). *outWeight / Nearest* says how much nearer a sample lies to "
        "its own shape than to the next; *Nearest / Average* depends on which other shapes the library "
        "holds, and the paper's library held more than these three (see below).",
        "",
        ratio_table(table_i + table_v),
        "",
        _near_sentence(table_v, matcher),
        "",
    ]


def _near_order_sentence(default: dict[str, dict[str, object]], paper: dict[str, dict[str, object]]) -> str:
    """Do the near shapes keep the paper's order (1, 1, 0.92): the star lowest, with both matchers?"""

    def lowest(rows: dict[str, dict[str, object]], key: str) -> str:
        return min(rows, key=lambda name: float(rows[name][key]))

    kept = all(
        lowest(rows, key) == "six-pointed-star"
        for rows in (default, paper)
        for key in ("mscore", "mscore_no_scan")
    )
    scores = {
        method: ", ".join(
            f"{_label(name).lower()} {fmt_score(float(rows[name]['mscore']))}" for name in SHAPES
        )
        for method, rows in (("default", default), ("paper", paper))
    }
    return (
        "The near shapes keep the paper's order: the star, whose many features feel a change most, scores "
        "lowest"
        if kept
        else "The near shapes do not keep the paper's order (the star lowest)"
    ) + f" (with the scan, default: {scores['default']}; paper's method: {scores['paper']})."


def _near_sentence(rows: list[dict[str, object]], matcher: Matcher) -> str:
    """How rockscan's outWeight / Nearest of the near shapes compares with the paper's."""
    ours, paper = {}, {}
    for row in rows:
        if row["method"] == "paper":
            numbers = row["paper"]
            assert isinstance(numbers, dict)
            ours[str(row["shape"])] = float(row["out_weight_no_scan"]) / float(row["nearest_no_scan"])
            paper[str(row["shape"])] = numbers["out_weight"] / numbers["nearest"]
    ratios = {name: ours[name] / paper[name] for name in ours}
    text = (
        "The near shapes lie "
        + (
            "relatively nearer their own shape here than in the paper"
            if max(ratios.values()) < 1
            else "elsewhere"
        )
        + " ("
        + _join(
            [f"near {_label(name).lower()}: {r:.2g} times the paper's ratio" for name, r in ratios.items()]
        )
        + ")"
    )
    same_order = sorted(ours, key=ours.__getitem__) == sorted(paper, key=paper.__getitem__)
    text += ", in the paper's order." if same_order else ", in another order than the paper's."
    cartesian = {
        r.shape: r.out_weight / r.nearest_other
        for r in matcher.select(experiment="table-V", grid="cartesian", method="paper", scan=False)
    }
    if len(cartesian) == len(ours):
        text += (
            " The Cartesian grid map gives "
            + _join([fmt(cartesian[name]) for name in ours])
            + f" against the polar grid's {_join([fmt(v) for v in ours.values()])}, so the grid does not "
            "explain the gap; the paper does not say how it sampled its shapes or scaled its faces."
        )
    return text


# ---------------------------------------------------------------- Figs. 12-16


def _figures_section(
    facts: dict[str, object], settings: Settings, links: dict[str, str], step: float
) -> list[str]:
    """The figures, each with what it shows."""
    noise, rotation, params = facts["noise"], facts["rotation"], facts["parameters"]
    assert isinstance(noise, dict) and isinstance(rotation, dict) and isinstance(params, dict)
    return [
        "### Figures 12-16",
        "",
        f"![Fig. 12]({links['noise']})",
        "",
        *noise_section(noise, settings),
        "",
        f"![Fig. 13]({links['rotation']})",
        "",
        *rotation_section(rotation, settings, step),
        "",
        f"![Fig. 14]({links['m']})",
        "",
        f"![Fig. 15]({links['n1']})",
        "",
        f"![Fig. 16]({links['n23']})",
        "",
        *parameter_section(params, facts["triangle_mirror_max_diff"]),
        "",
    ]


def noise_section(noise: Noise, settings: Settings) -> list[str]:
    """Fig. 12: how MScore, the winner and the angle found hold up under radial noise."""
    levels = list(settings.noise_levels)
    top = levels[-1]
    steady = all(
        np.all(np.diff(noise[name][method]["mscore_mean"]) <= 0) for name in SHAPES for method in METHODS
    )
    return [
        f"**Fig. 12, noise.** {settings.n_seeds} noise draws per shape, each scaled to every level from "
        f"{levels[0]:.0%} to {top:.0%}, so that a curve shows the level and not a new draw at every point. "
        + (
            "MScore falls steadily as the noise grows, with both matchers, as in the paper "
            if steady
            else "MScore falls as the noise grows, as in the paper, though not at every step "
        )
        + "(mean MScore, 10-90 % of the draws in brackets, and the share matched to their own shape):",
        "",
        *(_noise_shape_line(noise[name], name, levels) for name in SHAPES),
        "",
        _noise_ranking(noise, settings) + " " + _noise_angle_sentence(noise, settings),
    ]


def _noise_shape_line(noise: dict[str, dict[str, object]], name: str, levels: list[float]) -> str:
    """One shape's MScores and correct shares at 7 % (if run) and the top level, by matcher."""
    top = levels[-1]
    quoted = [level for level in (0.07, top) if level in levels] or [top]
    parts = []
    for level in quoted:
        i = levels.index(level)
        by_method = []
        for method in METHODS:
            n = noise[method]
            mean, p10, p90, rate = (
                n[key][i] for key in ("mscore_mean", "mscore_p10", "mscore_p90", "correct_rate")
            )
            by_method.append(f"{method} {mean:.3f} ({p10:.3f}-{p90:.3f}), {rate:.0%}")
        parts.append(f"at {level:.0%}: " + "; ".join(by_method))
    tail = "; first wrong match: " + ", ".join(
        f"{m} {_first_wrong(noise[m]['first_wrong_level'], top)}" for m in METHODS
    )
    return f"- {_label(name)}: " + " | ".join(parts) + tail + "."


def _noise_ranking(noise: Noise, settings: Settings) -> str:
    """The shapes from most to least robust at the top level, by matcher."""
    top = settings.noise_levels[-1]
    order = {
        method: sorted(SHAPES, key=lambda name: -noise[name][method]["mscore_mean"][-1]) for method in METHODS
    }
    return (
        f"At {top:.0%} the order from most to least robust is "
        + (
            _join([_label(n).lower() for n in order["default"]]) + " with both matchers"
            if order["default"] == order["paper"]
            else "; ".join(f"{m}: {_join([_label(n).lower() for n in o])}" for m, o in order.items())
        )
        + "."
    )


def _noise_angle_sentence(noise: Noise, settings: Settings) -> str:
    """Panel c: which matcher's angle distance finds the turn more closely under noise."""
    levels = list(settings.noise_levels)
    level = settings.check_level if settings.check_level in levels else levels[-1]
    i = levels.index(level)
    medians = {name: {m: noise[name][m]["angle_error_median"][i] for m in METHODS} for name in SHAPES}
    errors = [
        f"{_label(n).lower()} {e['default']:.2f} deg against {e['paper']:.2f} deg" for n, e in medians.items()
    ]
    better = sum(e["default"] < e["paper"] for e in medians.values())
    verdict = {
        len(SHAPES): "finds it more closely than the eigenspace distance of the paper's method",
        0: "does not find it more closely than the eigenspace distance of the paper's method",
    }.get(better, f"finds it more closely for {better} of the {len(SHAPES)} shapes")
    return (
        "Panel c shows the angle reported for correct matches (the truth is 0): the whole-face "
        f"distance of the default matcher {verdict}; median error at {level:.0%}: " + _join(errors) + "."
    )


def rotation_section(rotation: dict[str, dict[str, object]], settings: Settings, step: float) -> list[str]:
    """Fig. 13: MScore and the angle found as the sample turns, without and with the scan."""
    symmetric = all(
        all(
            math.isclose(x % (360 / rotation[name]["symmetry"]), 0.0, abs_tol=1e-9)
            for x in rotation[name][m]["returns_to_1_at"]
        )
        for name in SHAPES
        for m in METHODS
        if rotation[name]["symmetry"]
    )
    lines = [
        f"**Fig. 13, rotation**, every {settings.angle_step_deg:g} deg, each sample the exact curve turned "
        "and sampled at the rays. Without the scan (panel a, the paper's figure) MScore dips as the sample "
        "turns"
        + (
            " and comes back to 1 only at turns that are symmetries of the shape"
            if symmetric
            else "; it also comes back to 1 at turns that are not symmetries of the shape"
        )
        + "; with the scan (panel b) every rotation is scored at once (default matcher, the paper's method "
        "in brackets):",
        "",
    ]
    for name in SHAPES:
        d, p = rotation[name]["default"], rotation[name]["paper"]
        assert isinstance(d, dict) and isinstance(p, dict)
        back = ", ".join(f"{x:g}" for x in d["returns_to_1_at"])
        n = d["n_angles"]
        lines.append(
            f"- {_label(name)} ({rotation[name]['symmetry']}-fold): without the scan MScore falls to "
            f"{d['no_scan_min']:.3f} ({p['no_scan_min']:.3f}), is 1 at {back} deg, and the shape wins at "
            f"{d['no_scan_correct']} ({p['no_scan_correct']}) of {n} angles; with the scan it wins at "
            f"{d['scan_correct']} ({p['scan_correct']}) of {n}, MScore is at least {d['scan_min']:.4f} "
            f"({p['scan_min']:.4f}), on the rays {d['scan_min_on_ray']:.4f} ({p['scan_min_on_ray']:.4f}), "
            f"and the angle is off by at most {d['angle_error_max']:.3f} deg "
            f"({p['angle_error_max']:.3f} deg)."
        )
    return lines + _between_rays(rotation, step)


def _between_rays(rotation: dict[str, dict[str, object]], step: float) -> list[str]:
    """Why MScore dips with the scan for turns that fall between two rays (if it does)."""

    def scan_min(name: str, method: str) -> float:
        return rotation[name][method]["scan_min"]

    if not any(scan_min(n, m) < rotation[n][m]["scan_min_on_ray"] for n in SHAPES for m in METHODS):
        return []
    return [
        "",
        f"A sample turned by a fraction of the {step:g} deg ray step is seen by the rays at other points "
        "of its outline than the library shape, which no shift of the face undoes: MScore dips between "
        "rays"
        + (
            " (more with the default matcher, whose whole-face distance sees all of that difference)"
            if all(scan_min(name, "default") < scan_min(name, "paper") for name in SHAPES)
            else ""
        )
        + ", and the parabola through the three best rotations places the angle between them.",
    ]


def parameter_section(params: dict[str, dict[str, dict[str, object]]], mirror: float | None) -> list[str]:
    """Figs. 14-16: MScore as m, n1 or n2 = n3 move away from each library shape."""
    names = {"m": "m (m1 = m2)", "n1": "n1 (x base)", "n23": "n2 = n3 (x base)"}

    def point(p: object) -> str:
        return "-" if p is None else f"{p[1]:.3f} ({p[0]:.3g})"

    lines = [
        "**Figs. 14-16, shape parameters.** MScore of a sample whose m, n1 or n2 and n3 move away from a "
        "library shape's. MScore is that of the nearest shape, which may be another one (hollow squares):",
        "",
        "| Parameter | Base shape | MScore one step below | one step above | Lowest (at) "
        "| Base shape still nearest |",
        "|---|---|---|---|---|---|",
    ]
    for parameter, sweeps in params.items():
        for name in SHAPES:
            s = sweeps[name]
            lines.append(
                f"| {names[parameter]} | {_label(name)} | {point(s['below'])} | {point(s['above'])} "
                f"| {point(s['lowest'])} | {s['base_nearest']} of {s['points_away']} |"
            )
    lines += [
        "",
        "As in the paper, MScore falls as the parameters move away from the library's values. MScore "
        "compares the nearest shape with the others, not with the sample: in a library of three, a shape "
        "unlike all of them still scores well if one is much nearer than the rest, which is what the "
        "distance cutoff is for.",
    ]
    if mirror is not None:
        lines += [
            "",
            "For exponents as large as the rounded triangle's, (|cos|^n + |sin|^n)^(1/n) is nearly "
            "max(|cos|, |sin|), so the curve depends on n2/n1 and n3/n1 only: scaling n1 by f and "
            f"scaling n2, n3 by 1/f give MScores within {mirror:.4f} of each other (Figs. 15 and 16 mirror "
            "each other), and Table II's near triangle, all three exponents times 1.1, is almost the same "
            "shape.",
        ]
    return lines


def _skipped_section(skipped: list[str]) -> list[str]:
    if not skipped:
        return []
    return ["Sweep points that make no closed shape were left out: " + "; ".join(skipped) + ".", ""]


# ---------------------------------------------------------------- the two grids


def grid_section(
    grids: dict[str, object], check: dict[str, dict[str, float]], settings: Settings, links: dict[str, str]
) -> list[str]:
    """The polar grid against the paper's Cartesian grid map, and why noise moves them apart."""
    return [
        "### The polar grid against the paper's Cartesian grid map",
        "",
        "rockscan keeps a face on a (theta, r) grid, so that turning a sample shifts its face along theta "
        "and the scan scores all rotations with a few FFTs. The paper plots the face onto a square grid map "
        '(`FaceConfig(grid="cartesian")`, 100 x 100 pixels here), where every rotation needs a new face. '
        f"Both ran on the same samples ({_join(_grid_subset(settings))}; the default matcher"
        + (", and both matchers for the tables):" if len(settings.cartesian_table_methods) > 1 else "):"),
        "",
        *_grid_table(grids),
        "",
        _grid_summary(grids),
        "",
        *_check_table(check, settings),
        "",
        _check_sentence(check),
        "",
        f"![Polar against Cartesian grid]({links['grids']})",
    ]


def _grid_subset(settings: Settings) -> list[str]:
    """Which samples the Cartesian grid map was run on."""
    subset = ["the tables"] if settings.cartesian_table_methods else []
    subset.append("every rotation without the scan")
    if settings.cartesian_seeds:
        subset.append(f"the first {settings.cartesian_seeds} noise draws")
    if settings.cartesian_angle_every:
        every = settings.cartesian_angle_every * settings.angle_step_deg
        subset.append(f"every {every:g} deg of rotation with the scan")
    if settings.cartesian_param_every:
        subset.append("the parameter sweeps")
    return subset


def _grid_table(grids: dict[str, object]) -> list[str]:
    by_experiment = grids["by_experiment"]
    assert isinstance(by_experiment, dict)
    lines = [
        "| Experiment | Pairs | Same winner | Largest MScore difference | Median | Largest at |",
        "|---|---|---|---|---|---|",
    ]
    for experiment, g in by_experiment.items():
        lines.append(
            f"| {experiment.replace('-', ' ')} | {g['pairs']} | {g['same_winner']} "
            f"| {g['max_mscore_diff']:.4f} | {g['median_mscore_diff']:.1e} | {g['worst']} |"
        )
    return lines


def _grid_summary(grids: dict[str, object]) -> str:
    """Same winners, MScore differences with and without noise, and where the grids disagree."""
    disagreements = grids["disagreements"]
    assert isinstance(disagreements, list)
    return (
        f"Over all {grids['pairs']} pairs the grids chose the same shape {grids['same_winner']} times. "
        f"Without noise the MScores differ by at most {grids['max_mscore_diff_without_noise']:.4f}"
        + _noise_grid_sentence(grids)
        + (
            " The grids disagree on: "
            + "; ".join(disagreements[:4])
            + (f"; and {len(disagreements) - 4} more" if len(disagreements) > 4 else "")
            + "."
            if disagreements
            else ""
        )
    )


def _noise_grid_sentence(grids: dict[str, object]) -> str:
    by_experiment = grids["by_experiment"]
    assert isinstance(by_experiment, dict)
    if "noise" not in by_experiment:
        return "."
    higher = grids["cartesian_higher_under_noise"]
    return (
        f"; with noise by up to {by_experiment['noise']['max_mscore_diff']:.4f}, the Cartesian map scoring "
        f"higher in {higher:.0%} of the noisy pairs."
    )


def _check_table(check: dict[str, dict[str, float]], settings: Settings) -> list[str]:
    lines = [
        f"How noise moves the grids apart: the same {settings.check_seeds} draws at "
        f"{settings.check_level:.0%} noise, without the scan, on four faces (mean MScore):",
        "",
        f"| Shape | polar grid | polar, radii smoothed over 3 rays | Cartesian 100 x 100 | Cartesian "
        f"{settings.check_map_size} x {settings.check_map_size} |",
        "|---|---|---|---|---|",
    ]
    for name in SHAPES:
        c = check[name]
        lines.append(
            f"| {_label(name)} | {c['polar']:.3f} | {c['smoothed']:.3f} | {c['cartesian']:.3f} "
            f"| {c['fine']:.3f} |"
        )
    return lines


def _check_sentence(check: dict[str, dict[str, float]]) -> str:
    """Read the four-face check: is it the map's pixel count, or its interpolation between rays?"""
    gap = [c["cartesian"] - c["polar"] for c in check.values()]
    size_effect = max(abs(c["fine"] - c["cartesian"]) for c in check.values())
    smoothing_same_way = all(
        np.sign(c["smoothed"] - c["polar"]) == np.sign(c["cartesian"] - c["polar"]) for c in check.values()
    )
    if size_effect < 0.25 * min(abs(g) for g in gap) and smoothing_same_way:
        return (
            f"The finer map scores like the coarse one (within {size_effect:.3f}), so the pixel count is not "
            "the cause, and smoothing the radii moves the polar grid the same way. Each pixel of the map "
            "takes the radius interpolated between the two rays beside its angle, which averages away part "
            "of the independent noise of neighbouring rays; the polar grid uses every ray as measured. "
            "Without noise there is nothing to average, and the grids agree closely."
        )
    return (
        "The four faces do not single out one cause: the map's pixel count changes its MScores by up to "
        f"{size_effect:.3f}, and smoothing the radii "
        + ("moves" if smoothing_same_way else "does not move")
        + " the polar grid the way the map does."
    )


# ---------------------------------------------------------------- the differences from the paper


def _differences_section(
    matcher: Matcher, settings: Settings, facts: dict[str, object], ranking: str
) -> list[str]:
    """Each difference from the paper, with its cause."""
    methods, noise, face = facts["methods"], facts["noise"], facts["face"]
    assert isinstance(methods, dict) and isinstance(noise, dict) and isinstance(face, dict)
    return [
        "### Differences from the paper, explained",
        "",
        _distances_bullet(matcher, face),
        _library_bullet(),
        _scan_bullet(matcher),
        _methods_sentence(methods, ranking),
        "- **Noise.** The paper reports that 7 % noise makes the rounded triangle hard to tell from the "
        "other shapes; here "
        + _noise_difference(noise, settings)
        + " The paper does not give its number of rays, its map size or how it interpolated between rays, "
        "and the comparison of grids above shows that interpolation alone moves MScore under noise.",
        _superformula_bullet(matcher),
        "",
    ]


def _distances_bullet(matcher: Matcher, face: dict[str, object]) -> str:
    """Why absolute distances differ from the paper's, and by how much."""
    scale = [
        float(r[key]) / float(r["paper"][key])
        for r in table_rows(matcher, "I")
        if r["method"] == "paper"
        for key in ("nearest", "average")
    ]
    return (
        "- **Absolute distances.** An outWeight is a Euclidean distance between faces, so it grows with the "
        "number of cells a face has and with their values. rockscan's polar face has "
        f"{face['polar_pixels']} sections holding bits (at most {face['polar_max']:.3f} here); the paper's "
        'faces peak "on the order of 1e-4" on a grid whose size it does not give. rockscan\'s Nearest Match '
        f"and Average outWeight come out {min(scale):.0f} to {max(scale):.0f} times the paper's: only ratios "
        "and orders can be compared, and MScore, a ratio, is the number to compare."
    )


def _library_bullet() -> str:
    """Table I's distances imply a library larger than the paper's three shapes."""
    implied = paper_pairwise_distances()
    return (
        "- **The paper's library held more than these three shapes.** With three shapes and symmetric "
        "distances, each shape's distances to the other two are two of three pairwise distances, so each "
        "distance is shared by two shapes. Table I's Nearest Match and Average outWeight imply these pairs "
        "(Average counting the shape's own 0, as MScore's mean does): "
        + "; ".join(f"{_label(n)} {fmt(a)} and {fmt(b)}" for n, (a, b) in implied.items())
        + ". No value is shared (nor without the 0 in the mean), so the paper's Nearest and Average columns "
        "describe a larger library than the one it names; rockscan's describe the three shapes."
    )


def _scan_bullet(matcher: Matcher) -> str:
    """How the scan lowers the near star's MScore against the paper's 0.92."""
    table_v = table_rows(matcher, "V")
    star, star_paper = (
        next(r for r in table_v if r["method"] == method and r["shape"] == "six-pointed-star")
        for method in ("default", "paper")
    )
    return (
        "- **MScore with and without the scan.** The scan gives every library shape its own best rotation, "
        "so the other shapes come nearer an imperfect sample and its MScore "
        + ("falls" if float(star_paper["mscore"]) < float(star_paper["mscore_no_scan"]) else "changes")
        + ": with the paper's method the near star scores "
        f"{fmt_score(float(star_paper['mscore']))} with the scan and "
        f"{fmt_score(float(star_paper['mscore_no_scan']))} without (default: "
        f"{fmt_score(float(star['mscore']))} and {fmt_score(float(star['mscore_no_scan']))}), against the "
        "paper's 0.92. Ideal shapes score 1 either way."
    )


def _methods_sentence(methods: dict[str, object], ranking: str) -> str:
    """The difference between rockscan's default matcher and the paper's exact method, from the data."""
    by_experiment = methods["by_experiment"]
    assert isinstance(by_experiment, dict)
    where = [
        f"{EXPERIMENTS[experiment]}, {e['winner_differs']} of {e['pairs']} samples (matched to their own "
        f"shape: default {e['default_correct']}, paper's method {e['paper_correct']})"
        for experiment, e in by_experiment.items()
        if e["winner_differs"]
    ]
    if ranking == "eigenspace":
        head = (
            "- **rockscan's default and the paper's exact method** rank by the same eigenspace distance: "
            f"over {methods['pairs']} samples the MScores differ by at most {methods['max_mscore_diff']:.1e}"
        )
    else:
        head = (
            "- **rockscan's default and the paper's exact method** rank differently here: with only three "
            'shapes face space has two dimensions, and `metric="auto"` ranks by the whole-face distance, '
            "which keeps the part of a sample outside face space that the eigenspace distance ignores. Over "
            f"{methods['pairs']} samples the MScores differ by up to {methods['max_mscore_diff']:.2f}, the "
            f"default's being the lower in {methods['default_lower']} of them: the part outside face space "
            "is common to all three shapes, so it raises every w alike and brings min(w) nearer mean(w)"
        )
    return (
        head
        + ("; the winners differ in " + "; ".join(where) + "." if where else " and the winners never differ.")
        + " Both report the angle from their own angle distance (Figs. 12c and 13c)."
    )


def _noise_difference(noise: Noise, settings: Settings) -> str:
    levels = list(settings.noise_levels)
    level = 0.07 if 0.07 in levels else levels[len(levels) // 2]
    i = levels.index(level)
    parts = []
    for method, label in (("paper", "the paper's method"), ("default", "the default matcher")):
        tri = noise["rounded-triangle"][method]
        first = tri["first_wrong_level"]
        parts.append(
            f"with {label} its mean MScore at {level:.0%} is {tri['mscore_mean'][i]:.3f}, "
            f"{tri['correct_rate'][i]:.0%} of its draws are matched to it, and "
            + (
                f"its first wrong match comes at {first:.0%}"
                if first is not None
                else f"it is never mistaken up to {levels[-1]:.0%}"
            )
        )
    return "; ".join(parts) + "."


def _superformula_bullet(matcher: Matcher) -> str:
    """Why the symmetry is read from the radii, not from m."""
    return (
        "- **The Superformula as written.** With m/4 inside the formula, turning by 360/m deg swaps the "
        "cosine and sine terms, so an m-fold curve needs n2 = n3. rockscan reads the symmetry from the "
        "radii, never from m: "
        + _join(
            [
                f"{_label(name).lower()} (m = {params.m1:g}) {int(matcher.polar.symmetry[i])}-fold"
                for i, (name, (_, params)) in enumerate(SHAPES.items())
            ]
        )
        + ", which is why the three-faced blunt returns to MScore 1 every 120 deg in Fig. 13."
    )


# ---------------------------------------------------------------- the whole section


def write_doc(
    path: Path,
    matcher: Matcher,
    settings: Settings,
    facts: dict[str, object],
    check: dict[str, dict[str, float]],
    figures: dict[str, Path],
    skipped: list[str],
    seconds: float,
    command: str,
) -> None:
    """Write the README section: tables, figures, and the differences from the paper."""
    grids = facts["grids"]
    assert isinstance(grids, dict)
    links = {key: _link(value, path.parent) for key, value in figures.items()}
    ranking = METHODS["default"].resolved_metric(matcher.polar)
    step = 360 / matcher.polar.face_config.n_angles
    lines = [
        *_intro_section(matcher, ranking, seconds, command, links["shapes"]),
        *_tables_section(matcher),
        *_figures_section(facts, settings, links, step),
        *_skipped_section(skipped),
        *grid_section(grids, check, settings, links),
        "",
        *_differences_section(matcher, settings, facts, ranking),
    ]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines), encoding="utf-8")
