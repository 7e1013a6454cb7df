"""The paper's figures (7, 12-16, and the two grids) as PNGs, drawn from the runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rockscan import polar_angles, shape_radii

from .experiments import METHODS, NEAR, SHAPES, Matcher
from .findings import curve, grid_pairs, nanmedian_rows

COLORS = {"rounded-triangle": "tab:blue", "three-faced-blunt": "tab:orange", "six-pointed-star": "tab:green"}
METHOD_LABELS = {"default": "rockscan default", "paper": "paper's exact method"}
#: Figure key -> file stem; the keys are what the document links.
FIGURES = {
    "shapes": "fig07-shapes",
    "noise": "fig12-noise",
    "rotation": "fig13-rotation",
    "m": "fig14-m",
    "n1": "fig15-n1",
    "n23": "fig16-n23",
    "grids": "grids",
}


def figure_paths(folder: Path) -> dict[str, Path]:
    """Where each figure goes in ``folder``."""
    return {key: folder / f"paper-{stem}.png" for key, stem in FIGURES.items()}


def write_figures(matcher: Matcher, paths: dict[str, Path], dpi: int) -> None:
    """Draw every figure to its path from `figure_paths`."""
    paths["shapes"].parent.mkdir(parents=True, exist_ok=True)
    figure_shapes(paths["shapes"], matcher.polar.face_config.n_angles, dpi)
    figure_noise(matcher, paths["noise"], dpi)
    figure_rotation(matcher, paths["rotation"], dpi)
    for parameter in ("m", "n1", "n23"):
        figure_parameter(matcher, parameter, paths[parameter], dpi)
    figure_grids(matcher, paths["grids"], dpi)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _handles(*extra: object) -> list[object]:
    from matplotlib.lines import Line2D

    return [
        *(Line2D([], [], color=COLORS[name], lw=2, label=label) for name, (label, _) in SHAPES.items()),
        Line2D([], [], color="0.3", ls="-", label=METHOD_LABELS["default"]),
        Line2D([], [], color="0.3", ls="none", marker="o", mfc="none", label=METHOD_LABELS["paper"]),
        *extra,
    ]


def _both_methods(
    ax, xs: np.ndarray, values: dict[str, np.ndarray], color: str, *, line: bool = True
) -> None:
    """The default matcher as a line (or dots), the paper's method as hollow circles."""
    if line:
        ax.plot(xs, values["default"], color=color, lw=1.8)
    else:
        ax.plot(xs, values["default"], ".", color=color, ms=4)
    ax.plot(xs, values["paper"], color=color, ls="none", marker="o", mfc="none", ms=4)


def figure_shapes(path: Path, n_angles: int, dpi: int) -> None:
    """Figs. 7-10: the three library shapes and their near shapes."""
    plt = _pyplot()
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(1, 3, figsize=(10, 3.9), layout="constrained")
    theta = np.append(polar_angles(n_angles), 0.0)
    for ax, (name, (label, params)) in zip(axes, SHAPES.items(), strict=True):
        for sample, style in ((params, "-"), (NEAR[name], "--")):
            r = np.append(shape_radii(sample, n_angles), 0.0)
            r[-1] = r[0]
            ax.plot(r * np.cos(theta), r * np.sin(theta), style, color=COLORS[name])
        ax.set_title(label)
        ax.set_aspect("equal")
        ax.set_xlabel("x / mean radius")
        ax.set_ylabel("y / mean radius")
    fig.legend(
        handles=[
            Line2D([], [], color="0.3", ls="-", label="library shape (Fig. 7)"),
            Line2D([], [], color="0.3", ls="--", label="near shape (Tables II-IV, Figs. 8-10)"),
        ],
        loc="outside lower center",
        ncols=2,
    )
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def figure_noise(matcher: Matcher, path: Path, dpi: int) -> None:
    """Fig. 12: MScore, correct matches and angle error against radial noise."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.4), layout="constrained")
    for name in SHAPES:
        color = COLORS[name]
        curves = {m: curve(matcher, "noise", name, m, lambda r: r.mscore) for m in METHODS}
        xs = curves["default"][0] * 100
        lo, hi = np.percentile(curves["default"][1], [10, 90], axis=1)
        axes[0].fill_between(xs, lo, hi, color=color, alpha=0.15, lw=0)
        _both_methods(axes[0], xs, {m: v.mean(axis=1) for m, (_, v) in curves.items()}, color)
        rate = {
            m: 100 * curve(matcher, "noise", name, m, lambda r: r.correct)[1].mean(axis=1) for m in METHODS
        }
        _both_methods(axes[1], xs, rate, color)
        errors = {
            m: nanmedian_rows(curve(matcher, "noise", name, m, lambda r: r.angle_error_deg)[1])
            for m in METHODS
        }
        _both_methods(axes[2], xs, errors, color)
    axes[0].set_ylabel("MScore (line: mean; band: 10-90 % of draws)")
    axes[1].set_ylabel("samples matched to their own shape (%)")
    axes[2].set_ylabel("angle error of correct matches (deg, median)")
    for ax, title in zip(
        axes, ("a. match quality", "b. correct matches", "c. angle found (truth: 0)"), strict=True
    ):
        ax.set_xlabel("radial noise, standard error (%)")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[1].set_ylim(-5, 105)
    fig.legend(handles=_handles(), loc="outside lower center", ncols=5)
    fig.suptitle("Fig. 12: radial sensor noise (every radius times 1 + e, e normal)")
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def figure_rotation(matcher: Matcher, path: Path, dpi: int) -> None:
    """Fig. 13: MScore against rotation without and with the scan; the angle found."""
    plt = _pyplot()
    step = 360 / matcher.polar.face_config.n_angles
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.4), layout="constrained")
    for name in SHAPES:
        color = COLORS[name]
        for ax, scan in ((axes[0], False), (axes[1], True)):
            values = {m: curve(matcher, "rotation", name, m, lambda r: r.mscore, scan=scan) for m in METHODS}
            xs = values["default"][0]
            _both_methods(ax, xs, {m: v[:, 0] for m, (_, v) in values.items()}, color, line=not scan)
        # The error depends on where the turn falls between two rays, not on the turn itself.
        errors = {
            m: curve(matcher, "rotation", name, m, lambda r: r.angle_error_deg, scan=True) for m in METHODS
        }
        offset = np.mod(errors["default"][0], step) / step
        _both_methods(axes[2], offset, {m: v[:, 0] for m, (_, v) in errors.items()}, color, line=False)
    axes[0].set_title("a. without the rotation scan (the paper's Fig. 13)")
    axes[1].set_title("b. with the scan (dips: samples between rays)")
    axes[2].set_title("c. angle error with the scan")
    axes[0].set_ylabel("MScore")
    axes[1].set_ylabel("MScore")
    axes[2].set_ylabel("angle error, folded by symmetry (deg)")
    for ax in axes[:2]:
        ax.set_xlabel("rotation of the sample (deg, counter-clockwise)")
        ax.set_xticks(np.arange(0, 361, 60))
    axes[2].set_xlabel(f"offset of the turn from a ray (fraction of the {step:g} deg step)")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.legend(handles=_handles(), loc="outside lower center", ncols=5)
    fig.suptitle("Fig. 13: rotation")
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def figure_parameter(matcher: Matcher, parameter: str, path: Path, dpi: int) -> None:
    """Figs. 14-16: MScore as a shape parameter moves; hollow squares mark other winners."""
    plt = _pyplot()
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(9, 4.6), layout="constrained")
    for name, (_, params) in SHAPES.items():
        color = COLORS[name]
        values = {m: curve(matcher, parameter, name, m, lambda r: r.mscore) for m in METHODS}
        xs = values["default"][0]
        _both_methods(ax, xs, {m: v[:, 0] for m, (_, v) in values.items()}, color)
        wrong = ~curve(matcher, parameter, name, "default", lambda r: r.correct)[1][:, 0].astype(bool)
        ax.plot(xs[wrong], values["default"][1][wrong, 0], "s", color=color, mfc="white", ms=8)
        ax.axvline(params.m1 if parameter == "m" else 1.0, color=color, ls=":", lw=1)
    if parameter == "m":
        ax.set_xlabel("m (m1 = m2); dotted: the base shape's m")
        title = "Fig. 14: varying m"
    else:
        ax.set_xscale("log", base=2)
        what = "n1" if parameter == "n1" else "n2 and n3"
        ax.set_xlabel(f"{what} as a multiple of the base shape's value (dotted: the base shape)")
        title = "Fig. 15: varying n1" if parameter == "n1" else "Fig. 16: varying n2 = n3 (both scaled)"
    ax.set_ylabel("MScore")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    square = Line2D(
        [],
        [],
        color="0.3",
        ls="none",
        marker="s",
        mfc="white",
        ms=8,
        label="another shape is nearest (default)",
    )
    ax.legend(handles=_handles(square), fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def figure_grids(matcher: Matcher, path: Path, dpi: int) -> None:
    """Polar grid against the paper's Cartesian grid map: MScores of the same samples."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.6, 5.2), layout="constrained")
    pairs = grid_pairs(matcher)
    markers = {"table-I": "*", "table-V": "P", "noise": "o", "rotation": "^", "m": "s", "n1": "D", "n23": "v"}
    for experiment, marker in markers.items():
        subset = [(p, c) for p, c in pairs if p.experiment == experiment]
        if subset:
            ax.plot(
                [p.mscore for p, _ in subset],
                [c.mscore for _, c in subset],
                marker,
                ms=4,
                alpha=0.6,
                label=experiment.replace("-", " "),
            )
    ax.plot([0, 1], [0, 1], color="0.4", lw=1)
    ax.set_xlabel("MScore, polar grid (rockscan)")
    ax.set_ylabel("MScore, Cartesian grid map (the paper's)")
    ax.set_title("The same samples on both grids")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
