"""The paper reproduction and the core benchmark scripts, run with tiny settings.

The scripts are not part of the package; they are loaded from ``scripts/`` and
their ``main`` is run in a temporary directory; their small functions get exact checks.
"""

from __future__ import annotations

import importlib.util
import json
import os
import re
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from conftest import PAPER_NEAR, PAPER_SHAPES
from PIL import Image

from rockscan.core.information import sample_term
from rockscan.core.polar import polar_angles
from rockscan.core.superformula import shape_radii

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"
FIGURES = (
    "paper-fig07-shapes.png",
    "paper-fig12-noise.png",
    "paper-fig13-rotation.png",
    "paper-fig14-m.png",
    "paper-fig15-n1.png",
    "paper-fig16-n23.png",
    "paper-grids.png",
)
LABELS = {
    "rounded-triangle": "Rounded Triangle",
    "three-faced-blunt": "3-Faced Blunt",
    "six-pointed-star": "6-Pointed Star",
}


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"rockscan_script_{name}", SCRIPTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def reproduce() -> ModuleType:
    return _load("reproduce_paper")


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return _load("bench_core")


@pytest.fixture(scope="module")
def paper_run(reproduce, tmp_path_factory) -> tuple[Path, dict, str]:
    out = tmp_path_factory.mktemp("paper")
    code = reproduce.main(
        [
            "--quick",
            "--out",
            str(out / "figures"),
            "--doc",
            str(out / "paper.md"),
            "--json",
            str(out / "r.json"),
        ]
    )
    assert code == 0
    return out, json.loads((out / "r.json").read_text()), (out / "paper.md").read_text()


def test_reproduction_writes_every_figure_as_a_png(paper_run):
    out, _, doc = paper_run
    for name in FIGURES:
        path = out / "figures" / name
        with Image.open(path) as image:
            assert image.format == "PNG"
            assert image.width > 100 and image.height > 100
            # A blank canvas would be one colour; a plot has axes, lines and text.
            assert len(image.convert("L").getcolors(maxcolors=1 << 16) or ()) > 10
        # Linked relative to the document, so that it shows wherever the folder goes.
        assert f"](figures/{name})" in doc


def test_table_1_has_the_papers_shapes_matched_to_themselves(paper_run):
    _, result, doc = paper_run
    rows = result["table_I"]
    assert {(r["shape"], r["method"]) for r in rows} == {
        (s, m) for s in PAPER_SHAPES for m in ("default", "paper")
    }
    for r in rows:
        assert r["match"] == r["shape"] and r["correct"]
        assert r["mscore"] == pytest.approx(1.0, abs=1e-9)
        assert r["mscore_no_scan"] == pytest.approx(1.0, abs=1e-9)
        assert r["out_weight"] < 1e-12
        assert r["paper"]["mscore"] == 1.0 and r["paper"]["out_weight"] == 0.0
        # The Nearest Match column is another shape, clearly apart.
        assert r["nearest"] > 0.1
    for shape, label in LABELS.items():
        line = next(line for line in doc.splitlines() if line.startswith(f"| {label} | default |"))
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[2:7] == ["1", "1.0000", "1.0000", "0", "0"]
        assert cells[-1] == "Yes"
        paper = result["table_I"][[r["shape"] for r in rows].index(shape)]["paper"]
        assert cells[7] == f"{paper['nearest']:.1e}".replace("e-0", "e-")


def test_table_5_has_the_near_shapes_in_the_papers_order(paper_run):
    _, result, doc = paper_run
    rows = {(r["shape"], r["method"]): r for r in result["table_V"]}
    assert {s for s, _ in rows} == set(PAPER_NEAR)
    for r in rows.values():
        assert r["match"] == r["shape"] and r["correct"]
        assert 0 < r["out_weight"] < r["nearest"]
    for method in ("default", "paper"):
        # Paper: 1, 1 and 0.92; the star, with the most features, scores lowest.
        star = rows["six-pointed-star", method]
        assert 0.8 < star["mscore"] < 0.95
        assert rows["rounded-triangle", method]["mscore"] > 0.999
        assert rows["three-faced-blunt", method]["mscore"] > 0.99
    # The paper's method: the scan brings the other shapes nearer the near star (at their best rotation).
    paper_star = rows["six-pointed-star", "paper"]
    assert paper_star["mscore"] < paper_star["mscore_no_scan"] < 0.99
    # w, and so MScore = 1 - outWeight / Average, in the distance each matcher ranks by.
    for r in rows.values():
        assert r["mscore"] == pytest.approx(1 - r["out_weight"] / r["average"], abs=1e-12)
    for label in LABELS.values():
        assert f"| Near {label} | default |" in doc and f"| Near {label} | paper |" in doc
    assert "| No |" not in doc
    star = rows["six-pointed-star", "default"]
    assert (
        f"| Near 6-Pointed Star | default | 0.92 | {star['mscore']:.4f} | {star['mscore_no_scan']:.4f} |"
        in doc
    )


def test_reproduction_findings_hold_on_the_tiny_run(paper_run):
    _, result, doc = paper_run
    facts = result["findings"]
    methods = facts["methods"]
    assert methods["pairs"] == sum(e["pairs"] for e in methods["by_experiment"].values())
    assert methods["by_experiment"]["table-I"]["max_mscore_diff"] < 1e-9  # both score an exact match 1
    assert methods["by_experiment"]["rotation"]["winner_differs"] == 0
    assert facts["grids"]["same_winner"] == facts["grids"]["pairs"] > 0
    assert facts["grids"]["max_mscore_diff"] < 0.05
    for name, rotation in facts["rotation"].items():
        period = 360 / rotation["symmetry"]
        for method in ("default", "paper"):
            r = rotation[method]
            assert r["scan_correct"] == r["n_angles"]  # the scan finds every turned shape
            assert 0.0 in r["returns_to_1_at"]
            assert all(x % period == pytest.approx(0.0, abs=1e-9) for x in r["returns_to_1_at"]), name
    for noise in facts["noise"].values():
        for method in ("default", "paper"):
            means = noise[method]["mscore_mean"]
            assert means[0] == pytest.approx(1.0, abs=1e-9)
            assert means == sorted(means, reverse=True)
    assert "## Reproducing the paper" in doc and "### Differences from the paper, explained" in doc


def test_paper_table_1_implies_distances_no_three_shape_library_has(reproduce):
    implied = reproduce.paper_pairwise_distances()
    assert implied["rounded-triangle"] == pytest.approx((2.1e-3, 8.4e-3))
    assert implied["six-pointed-star"] == pytest.approx((2.8e-3, 11.9e-3))
    values = [round(v, 6) for pair in implied.values() for v in pair]
    assert len(set(values)) == 6  # no pairwise distance shared by two shapes


@pytest.mark.parametrize(
    ("angle", "truth", "order", "expected"),
    [
        (121.0, 0.0, 3, 1.0),
        (359.0, 0.0, 1, 1.0),
        (30.0, 0.0, 6, 30.0),
        (45.0, 10.0, 0, 0.0),
        (0.0, 179.5, 2, 0.5),
    ],
)
def test_angle_error_is_folded_by_symmetry(reproduce, angle, truth, order, expected):
    assert reproduce.angle_error_deg(angle, truth, order) == pytest.approx(expected)


def test_distance_format_follows_the_paper(reproduce):
    assert reproduce.fmt(2.1e-3) == "2.1e-3"
    assert reproduce.fmt(0.1485) == "1.5e-1"
    assert reproduce.fmt(3e-17) == "0"
    assert reproduce.fmt(0.0) == "0"


def test_turned_sample_on_a_ray_is_the_library_shape_shifted(reproduce):
    params = PAPER_SHAPES["three-faced-blunt"]
    radii = shape_radii(params, 360)
    turned = reproduce.turned_radii(params, 37.0, 360)
    np.testing.assert_allclose(turned / turned.mean(), np.roll(radii, 37), rtol=1e-12)
    errors = np.random.default_rng(0).standard_normal(360)
    np.testing.assert_array_equal(reproduce.noisy_radii(radii, 0.0, errors), radii)
    assert np.all(reproduce.noisy_radii(radii, 20.0, errors) >= 0)


def test_sweeps_change_only_the_named_parameters(reproduce):
    base = PAPER_SHAPES["three-faced-blunt"]
    assert reproduce.sweep_params(base, "m", 4.0).as_dict() == {**base.as_dict(), "m1": 4.0, "m2": 4.0}
    assert reproduce.sweep_params(base, "n1", 2.0).as_dict() == {**base.as_dict(), "n1": 120.0}
    assert reproduce.sweep_params(base, "n23", 0.5).as_dict() == {**base.as_dict(), "n2": 27.5, "n3": 5.0}


def test_reproduction_rejects_zero_seeds(reproduce, capsys):
    with pytest.raises(SystemExit) as exc:
        reproduce.main(["--quick", "--seeds", "0"])
    assert exc.value.code == 2
    assert "--seeds must be at least 1" in capsys.readouterr().err


def test_benchmark_writes_its_section(bench, tmp_path, capsys):
    doc = tmp_path / "bench.md"
    assert bench.main(["--quick", "--doc", str(doc)]) == 0
    text = doc.read_text()
    assert text.rstrip("\n") == capsys.readouterr().out.rstrip("\n")
    assert f"a machine with {os.cpu_count()} cores" in text
    assert "python scripts/bench_core.py" in text
    # Each row: both settings (default BLAS threads, one BLAS thread), a time and a ratio each.
    rows = {
        m.group(1): [float(x) for x in m.group(2, 3, 4, 5)]
        for m in re.finditer(
            r"^\| ([^|]+?) \| ([0-9.]+) ms \| ([0-9.]+) \| ([0-9.]+) ms \| ([0-9.]+) \|$", text, re.M
        )
    }
    assert list(rows) == list(bench.SCAN_ROWS)
    assert rows[bench.ONE_ROTATION][1::2] == rows[bench.ONE_MATCH][1::2] == [1.0, 1.0]
    assert all(min(values) > 0 for values in rows.values())
    sizes = re.findall(r"^\| (\d+) \| (\d+) \| [0-9.]+ ms \|", text, re.M)
    assert [int(s) for s, _ in sizes] == list(bench.QUICK.sizes)
    assert all(int(c) == int(s) - 1 for s, c in sizes)  # random shapes: every eigenface kept
    assert re.search(r"`Library\.from_shapes` \| [0-9.]+ s \| \d+ MiB \| \d+ MiB \|", text)


def test_benchmark_rejects_zero_repeats(bench, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main(["--quick", "--repeats", "0"])
    assert exc.value.code == 2
    assert "--repeats must be at least 1" in capsys.readouterr().err


def test_the_benchmarks_one_rotation_path_scores_the_unturned_sample(bench, paper_lib):
    # The benchmark compares the scan with a direct projection: both must be the same
    # numbers, to the single precision of the scan's eigenface products.
    radii = np.roll(shape_radii(PAPER_NEAR["six-pointed-star"], 360), 17)
    q = sample_term(radii, paper_lib.face_config)
    one = paper_lib.basis.distances(paper_lib.reference_map * q)
    every = paper_lib.scan_templates.squared_distances(q, ("eigenspace",))["eigenspace"]
    # rtol 1e-5: the scan's complex64 templates (numpy before 2.0 rounds them from double).
    np.testing.assert_allclose(np.sqrt(every[0]), one, rtol=1e-5)
    np.testing.assert_allclose(
        np.sqrt(every[17]),
        paper_lib.basis.distances(paper_lib.reference_map * np.roll(q, -17, axis=0)),
        rtol=1e-5,
    )
    assert polar_angles(360).size == every.shape[0]
