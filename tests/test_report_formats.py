"""What a field scientist gets from a triage: GeoJSON outlines, CSV for pandas, every rock with --all,
sizes in millimetres, and novel rocks ranked up."""

from __future__ import annotations

import json
import shutil
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from rockscan.cli import main
from rockscan.core.render import RenderConfig, render_photo, render_scene
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import default_spec_path, read_spec
from rockscan.io.report import CSV_COLUMNS, ROW_KEYS, ReportJournal, read_rows
from rockscan.run.pipeline import ClassifyConfig, classify_path
from rockscan.run.report import finalize_report

EXAMPLES = Path(__file__).resolve().parents[1] / "data" / "examples"


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """Four rendered photos, one of them with three rocks."""
    root = tmp_path_factory.mktemp("formats") / "photos"
    root.mkdir()
    specs = {s.name: s.params for s in read_spec(default_spec_path())}
    rng = np.random.default_rng(11)
    for i, name in enumerate(["five-armed-star", "egg", "rounded-triangle"]):
        photo = render_photo(specs[name], RenderConfig(rows=150, cols=180), rng=rng, name=name)
        (root / f"{i}-{name}.png").write_bytes(photo.encode(".png"))
    scene = render_scene(
        [specs["egg"], specs["six-pointed-star"], specs["circle"]],
        RenderConfig(rows=240, cols=320, area_fraction=0.24, pebbles=0),
        rng=rng,
    )
    (root / "3-three-rocks.png").write_bytes(scene.encode(".png"))
    return root


def _triage(folder: Path, report: Path, *extra: str) -> None:
    result = CliRunner().invoke(main, ["triage", str(folder), "-o", str(report), "-j", "1", "-q", *extra])
    assert result.exit_code == 0, result.output


def _classify(paths: list[str], *extra: str) -> list[dict]:
    result = CliRunner().invoke(main, ["classify", "--json", *extra, *paths])
    assert result.exit_code == 0, result.output
    return [json.loads(line) for line in result.stdout.splitlines()]


def _shoelace(ring: list[list[float]]) -> float:
    x, y = np.array(ring).T
    return 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]))


def test_geojson_is_a_feature_collection_of_valid_polygons_with_the_classify_keys(folder, tmp_path):
    report = tmp_path / "rocks.geojson"
    _triage(folder, report, "--all")
    collection = json.loads(report.read_text())
    assert collection["type"] == "FeatureCollection"
    assert collection["rockscan_report"]["options"]["all_rocks"] is True
    features = collection["features"]
    photos = sorted(str(p) for p in folder.iterdir())
    printed = {(r["path"], r["index"]): r for r in _classify(photos, "--all")}
    n = len(printed)
    assert len(features) == n and n >= 5
    assert [f["properties"]["rank"] for f in features] == list(range(1, n + 1))
    for feature in features:
        props, geometry = feature["properties"], feature["geometry"]
        assert feature["type"] == "Feature" and geometry["type"] == "Polygon"
        (ring,) = geometry["coordinates"]
        assert len(ring) >= 4 and ring[0] == ring[-1]
        # The outline's own area is the rock's area (2%), the ring counter-clockwise in its
        # own x, y numbers (RFC 7946's right-hand rule): the outline's points in reverse.
        assert _shoelace(ring) > 0
        assert abs(_shoelace(ring) - props["area_px"]) <= 0.02 * props["area_px"]
        record = printed[(props["path"], props["index"])]
        assert ring[:-1] == record["outline"][::-1]
        assert {k: props[k] for k in record if k != "outline"} == {
            k: v for k, v in record.items() if k != "outline"
        }
        assert "outline" not in props


def test_csv_loads_in_pandas_with_every_column(folder, tmp_path):
    pd = pytest.importorskip("pandas")
    report = tmp_path / "rocks.csv"
    _triage(folder, report, "--px-per-mm", "4")
    # The first line records how the report was made.
    frame = pd.read_csv(report, skiprows=1)
    assert tuple(frame.columns) == CSV_COLUMNS
    rows = list(read_rows(report))
    assert len(frame) == len(rows) == 4
    assert frame["path"].tolist() == [r["path"] for r in rows]
    assert frame["rank"].tolist() == [1, 2, 3, 4]
    # pandas' default float parser may differ from an exact one in the last bit.
    np.testing.assert_allclose(frame["interest"], [r["interest"] for r in rows], rtol=1e-15, atol=0)
    np.testing.assert_allclose(frame["centroid_x"], [r["centroid"][0] for r in rows], rtol=1e-15, atol=0)
    assert frame["error"].isna().all() and frame["interesting"].dtype == bool


def test_px_per_mm_reaches_every_row_and_the_provenance(folder, tmp_path, default_lib):
    report = tmp_path / "rocks.jsonl"
    _triage(folder, report, "--px-per-mm", "4")
    rows = list(read_rows(report))
    for row in rows:
        assert row["area_mm2"] == pytest.approx(row["area_px"] / 16, rel=1e-3)
        assert row["equivalent_diameter_mm"] == pytest.approx(2 * np.sqrt(row["area_mm2"] / np.pi), rel=1e-3)
        assert row["major_axis_mm"] >= row["minor_axis_mm"] > 0
    header = json.loads(report.read_text().splitlines()[0])
    assert header["rockscan_report"]["options"]["px_per_mm"] == 4.0
    config = ClassifyConfig(px_per_mm=4.0)
    for row in rows:
        (record,) = classify_path(row["path"], default_lib, config).records()
        assert {k: row[k] for k in record} == record


def test_all_ranks_every_rock_of_every_photo_with_its_index(folder, tmp_path):
    report = tmp_path / "rocks.jsonl"
    _triage(folder, report, "--all")
    rows = list(read_rows(report))
    scene = str(folder / "3-three-rocks.png")
    printed = _classify([scene], "--all")
    assert len(printed) >= 2
    assert sorted(r["index"] for r in rows if r["path"] == scene) == list(range(len(printed)))
    assert [r["rank"] for r in rows] == list(range(1, len(rows) + 1))
    by_index = {r["index"]: r for r in rows if r["path"] == scene}
    for record in printed:
        assert {k: by_index[record["index"]][k] for k in record} == record
    # Resumed, a photo's rocks are done together: none twice, none lost.
    again = CliRunner().invoke(
        main, ["triage", str(folder), "-o", str(report), "-j", "1", "--all", "--resume"]
    )
    assert again.exit_code == 0 and "4 already in the report, 0 classified" in again.stdout
    assert len(list(read_rows(report))) == len(rows)


def test_a_rock_unlike_every_library_shape_ranks_in_the_top_three_with_observed(tmp_path):
    root = tmp_path / "photos"
    shutil.copytree(EXAMPLES, root, ignore=shutil.ignore_patterns("*.json", "*.md"))
    # A four-lobed rock: no library shape is like it.
    blob = render_photo(SuperformulaParams(4, 4, 0.6, 1, 1), RenderConfig(rows=240, cols=320), rng=5)
    (root / "novel.png").write_bytes(blob.encode(".png"))
    novel = str(root / "novel.png")
    plain = tmp_path / "plain.jsonl"
    _triage(root, plain)
    rows = {r["path"]: r for r in read_rows(plain)}
    # Without novelty it fails the cutoffs and ranks last of the five.
    assert rows[novel]["match"] is None and rows[novel]["rank"] == len(rows) == 5
    report = tmp_path / "observed.jsonl"
    _triage(root, report, "--observed", str(tmp_path / "observed.npz"))
    rows = {r["path"]: r for r in read_rows(report)}
    assert rows[novel]["novel"] is True and rows[novel]["rank"] <= 3
    # It scores the weight of the library's most wanted shape (five-armed-star, 2).
    assert rows[novel]["interest"] == 2.0
    # A rock that matches keeps its MScore times its shape's interest where that is more.
    for row in rows.values():
        if row["match"] is not None:
            assert row["interest"] >= row["mscore"] * row["shape_interest"]


def test_the_final_ranking_streams_through_sorted_chunks(tmp_path):
    report = tmp_path / "big.csv"
    rng = np.random.default_rng(0)
    n = 1200
    with ReportJournal(report, provenance={"test": 1}) as journal:
        for i in range(n):
            row = {**dict.fromkeys(ROW_KEYS), "path": f"p{i:05d}.png", "interest": float(rng.integers(0, 50))}
            row["mscore"] = row["interest"] / 50
            journal.append(row)
        journal.append({**dict.fromkeys(ROW_KEYS), "path": "p00007.png", "interest": 99.0, "mscore": 1.0})
    tracemalloc.start()
    ranked = finalize_report(report, chunk_rows=100)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rows = list(read_rows(report))
    assert ranked.n_rows == len(rows) == n
    # A photo's latest attempt wins; the order is the rank key's, across chunks.
    assert [r["rank"] for r in rows] == list(range(1, n + 1))
    keys = [(-r["interest"], -r["mscore"], r["path"]) for r in rows]
    assert keys == sorted(keys) and (rows[0]["path"], rows[0]["interest"]) == ("p00007.png", 99)
    # Memory held: chunks of 100 rows, not the 1,200 (a row object is ~2 kB here).
    assert peak < 100 * 2000 * 3
