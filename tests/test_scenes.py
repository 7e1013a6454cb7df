"""The second photo generator (scripts/scenes.py) and the segmentation benchmark's metrics.

The generator's truth must be exact (it is what every segmenter is judged
against), reproducible from a seed and split into parts that share nothing;
the metrics are checked on tiny cases whose answers are known.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from scipy import ndimage as ndi

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"


def _load(name: str) -> ModuleType:
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


scenes = _load("scenes")
bench = _load("bench_segment")

LUMA = np.array([0.299, 0.587, 0.114])


# --------------------------------------------------------------------------- shapes


def test_disc_blob_mask_is_the_disc_of_pixel_centres():
    blob = scenes.Blob((40.3, 51.7), 17.2)
    rr, cc = np.mgrid[0:90, 0:100]
    disc = (rr - 40.3) ** 2 + (cc - 51.7) ** 2 <= 17.2**2
    np.testing.assert_array_equal(blob.mask((90, 100)), disc)


def test_irregular_blob_mask_matches_its_drawn_outline():
    from skimage.draw import polygon2mask

    rng = np.random.default_rng(3)
    blob = scenes.random_blob(rng, (100.0, 120.0), 9000.0, 0.5, 1.7)
    mask = blob.mask((200, 240))
    drawn = polygon2mask((200, 240), blob.boundary(4000))
    differ = mask != drawn
    # The two agree but where the dense polygon's chords cut a pixel centre
    # lying within a hair of the curve.
    rr, cc = np.nonzero(differ)
    f = blob.field(rr.astype(float), cc.astype(float))
    assert differ.sum() <= 3
    np.testing.assert_allclose(f, 1.0, atol=1e-3)


def test_blob_area_formula_matches_the_pixel_count():
    rng = np.random.default_rng(5)
    blob = scenes.random_blob(rng, (150.0, 150.0), 20000.0, 0.4, 1.5)
    assert blob.area == pytest.approx(20000.0, rel=1e-9)
    assert blob.mask((300, 300)).sum() == pytest.approx(blob.area, rel=0.01)


def test_blob_extent_encloses_the_outline():
    rng = np.random.default_rng(8)
    for _ in range(20):
        blob = scenes.random_blob(rng, (0.0, 0.0), rng.uniform(100, 5000), rng.uniform(0, 0.6), 1.8)
        assert np.hypot(*blob.boundary(720).T).max() < blob.extent


# --------------------------------------------------------------------------- truth of a rendering


def test_truth_is_the_drawn_rock_on_an_unshaded_untextured_photo():
    rng = np.random.default_rng(1)
    shape = (120, 160)
    blob = scenes.random_blob(rng, (60.0, 75.0), 2500.0, 0.4, 1.5)
    rock = scenes._Object(blob, 1, 0.0, 2.0, 0.0, (0.8, 0.8, 0.8), 0.0)
    ground = np.full((*shape, 3), 0.2)
    light = scenes._Light(np.pi / 2, 0.0, 1.0)
    camera = scenes._Camera(blur=0.0, noise=0.0, jpeg=100)
    image, labels = scenes._render(rng, "dev", shape, ground, [rock], light, camera)
    np.testing.assert_array_equal(labels == 1, blob.mask(shape))
    inside = ndi.binary_erosion(labels == 1)
    outside = ndi.binary_erosion(labels == 0)
    assert np.all(image[inside] == round(0.8 * 255))
    assert np.all(image[outside] == round(0.2 * 255))
    # An edge pixel is a mix, on its side of half-way.
    edge_in = (labels == 1) & ~inside
    edge_out = (labels == 0) & ~outside
    half = 0.5 * (0.8 + 0.2) * 255
    assert np.all(image[edge_in][:, 0] >= half - 1)
    assert np.all(image[edge_out][:, 0] <= half + 1)


def test_a_pebble_under_the_rock_leaves_the_rock_whole():
    rng = np.random.default_rng(2)
    shape = (100, 100)
    blob = scenes.Blob((50.0, 50.0), 20.0)
    pebble = scenes._touching(rng, blob, scenes.Blob((0.0, 0.0), 6.0), 0.5)
    objects = [
        scenes._Object(pebble, 0, 3.0, 2.0, 0.0, (0.5, 0.5, 0.5), 0.0),
        scenes._Object(blob, 1, 8.0, 2.0, 0.0, (0.7, 0.7, 0.7), 0.0),
    ]
    _, _, _, _, labels = scenes._paint(rng, "dev", shape, objects)
    np.testing.assert_array_equal(labels == 1, blob.mask(shape))
    # The pebble touches the rock: its disc reaches into the rock.
    assert (pebble.mask(shape) & blob.mask(shape)).any()


def test_a_block_in_low_light_casts_a_shadow_of_its_height_over_tan_elevation():
    height = np.zeros((60, 120))
    height[25:35, 40:50] = 10.0
    # Light from +col, 30 degrees up: the shadow falls towards -col, 10 / tan(30) = 17.3 px long.
    blocked = scenes._shadow(height, scenes._Light(np.radians(30), 0.0, 0.3))
    assert blocked[30, 30] > 0.9  # 10 px behind the block
    assert blocked[30, 15] < 0.1  # 25 px behind: beyond the shadow
    assert blocked[30, 60] < 0.05  # on the lit side
    assert blocked[10, 30] < 0.05  # beside it


# --------------------------------------------------------------------------- seeds and parts


def test_parts_of_seeds():
    assert scenes.part_of_seed(0) == "dev"
    assert scenes.part_of_seed(9999) == "dev"
    assert scenes.part_of_seed(100000) == "heldout"
    with pytest.raises(ValueError, match="no part"):
        scenes.part_of_seed(10000)
    assert list(scenes.part_seeds("heldout", 3)) == [100000, 100001, 100002]
    with pytest.raises(ValueError, match="only"):
        scenes.part_seeds("dev", 5, 9998)


@pytest.mark.parametrize("source", scenes.GROUND_SOURCES)
def test_development_and_held_out_textures_come_from_disjoint_halves(source):
    rows = scenes._source(source).shape[0]
    rng = np.random.default_rng(0)
    for _ in range(200):
        top, bottom, left, right = scenes.texture_window(rng, "dev", source)
        assert 0 <= top < bottom <= rows // 2 and left < right
        top, bottom, left, right = scenes.texture_window(rng, "heldout", source)
        assert rows // 2 <= top < bottom <= rows


def test_a_seed_gives_the_same_scene_and_another_seed_another():
    a = scenes.make_scene("small", 7)
    b = scenes.make_scene("small", 7)
    c = scenes.make_scene("small", 8)
    np.testing.assert_array_equal(a.image, b.image)
    np.testing.assert_array_equal(a.labels, b.labels)
    assert a.image.shape != c.image.shape or not np.array_equal(a.image, c.image)


def test_conditions_draw_their_own_photos_from_one_seed():
    a = scenes.make_scene("plain", 3)
    b = scenes.make_scene("small", 3)
    assert a.labels.shape != b.labels.shape or not np.array_equal(a.labels, b.labels)


# --------------------------------------------------------------------------- every condition, rendered


@pytest.mark.parametrize("condition", scenes.CONDITIONS)
def test_every_condition_renders_a_photo_with_its_truth(condition):
    scene = scenes.make_scene(condition, 11)
    assert scene.image.dtype == np.uint8 and scene.image.ndim in (2, 3)
    assert scene.labels.shape == scene.image.shape[:2] and scene.labels.dtype == np.int32
    assert scene.kind == scenes.CONDITION_KINDS[condition] and scene.part == "dev"
    n = scene.n_rocks
    assert set(np.unique(scene.labels)) == set(range(n + 1))
    coverage = (scene.labels > 0).mean()
    if scene.kind == "one":
        assert n == 1
        assert 0.01 <= coverage <= 0.60
        # The rock lies inside the frame.
        border = np.concatenate([scene.labels[0], scene.labels[-1], scene.labels[:, 0], scene.labels[:, -1]])
        assert not border.any()
    if scene.kind == "all":
        assert 2 <= n <= 40
    if scene.kind == "crop":
        assert n == 1 and scene.info["neighbours"] >= 1
        centre = np.array(ndi.center_of_mass(scene.labels == 1))
        np.testing.assert_allclose(
            centre, (np.array(scene.labels.shape) - 1) / 2, atol=0.15 * scene.labels.shape[0]
        )


@pytest.mark.parametrize(("condition", "low", "high"), [("small", 0.01, 0.03), ("large", 0.35, 0.60)])
def test_rock_sizes_of_small_and_large(condition, low, high):
    for seed in (0, 1):
        coverage = (scenes.make_scene(condition, seed).labels == 1).mean()
        assert low * 0.97 <= coverage <= high * 1.02


def _ring(labels: np.ndarray, width: int) -> np.ndarray:
    rock = labels == 1
    return ndi.binary_dilation(rock, iterations=width) & ~ndi.binary_dilation(rock, iterations=2)


def test_bipolar_ground_is_lighter_than_the_rock_on_one_side_and_darker_on_the_other():
    for seed in (0, 1, 2):
        scene = scenes.make_scene("bipolar-ground", seed)
        luma = scene.image @ LUMA if scene.image.ndim == 3 else scene.image.astype(float)
        rock = np.median(luma[ndi.binary_erosion(scene.labels == 1, iterations=3)])
        ring = luma[_ring(scene.labels, 8)] / rock
        assert np.mean(ring > 1.05) > 0.08 and np.mean(ring < 0.95) > 0.08


def test_colour_only_rock_has_the_grounds_luminance_and_another_hue():
    for seed in (0, 1, 2):
        scene = scenes.make_scene("colour-only", seed)
        rgb = scene.image.astype(float)
        inside = ndi.binary_erosion(scene.labels == 1, iterations=3)
        ring = _ring(scene.labels, 10)
        luma_rock, luma_ground = np.median(rgb[inside] @ LUMA), np.median(rgb[ring] @ LUMA)
        assert luma_rock == pytest.approx(luma_ground, rel=0.12)
        chroma_rock = np.median(rgb[inside] / rgb[inside].sum(axis=1, keepdims=True), axis=0)
        chroma_ground = np.median(rgb[ring] / rgb[ring].sum(axis=1, keepdims=True), axis=0)
        assert np.abs(chroma_rock - chroma_ground).max() > 0.04


def test_shaded_rock_has_a_dark_far_side():
    scene = scenes.make_scene("shaded", 4)
    luma = scene.image @ LUMA if scene.image.ndim == 3 else scene.image.astype(float)
    values = luma[ndi.binary_erosion(scene.labels == 1, iterations=2)]
    lo, hi = np.percentile(values, [5, 95])
    assert lo < 0.5 * hi


# --------------------------------------------------------------------------- metrics


def test_iou_of_tiny_masks():
    a = np.zeros((4, 4), bool)
    b = np.zeros((4, 4), bool)
    a[:2, :2] = True  # 4 px
    b[1:3, 1:3] = True  # 4 px, 1 shared
    assert bench.iou(a, b) == pytest.approx(1 / 7)
    assert bench.iou(a, a) == 1.0
    assert bench.iou(a, ~a) == 0.0


def test_rock_score_centroid_error_in_equivalent_radii():
    truth = np.zeros((40, 40), bool)
    truth[10:20, 10:20] = True
    found = np.roll(truth, 3, axis=1)
    score = bench.score_rock(found, truth)
    assert score.iou == pytest.approx(70 / 130)
    assert score.centroid_error == pytest.approx(3 / np.sqrt(100 / np.pi))
    assert not score.no_rock
    assert score.precision == pytest.approx(70 / 100) and score.recall == pytest.approx(70 / 100)
    empty = bench.score_rock(np.zeros_like(truth), truth)
    assert empty.no_rock and empty.iou == 0.0


def test_rock_score_precision_and_recall_tell_too_large_from_too_small():
    truth = np.zeros((40, 40), bool)
    truth[10:20, 10:20] = True
    large = np.zeros_like(truth)
    large[10:20, 10:22] = True  # the rock and 20 px of ground
    score = bench.score_rock(large, truth)
    assert (score.precision, score.recall) == (pytest.approx(100 / 120), 1.0)
    small = np.zeros_like(truth)
    small[10:20, 10:18] = True  # 80 px of the rock
    score = bench.score_rock(small, truth)
    assert (score.precision, score.recall) == (1.0, pytest.approx(80 / 100))


def test_wrong_outlines_are_counted_by_how_they_go_wrong():
    def record(iou, precision, recall, no_rock=False, kind="one", method="rockscan"):
        return {
            "part": "dev",
            "method": method,
            "kind": kind,
            "iou": iou,
            "precision": precision,
            "recall": recall,
            "no_rock": no_rock,
        }

    records = [
        record(0.95, 0.97, 0.98),  # right
        record(0.85, 0.86, 0.99),  # near miss, too large
        record(0.60, 0.99, 0.61),  # too small
        record(0.0, 0.0, 0.0, no_rock=True),
        record(0.5, 0.5, 1.0, kind="crop"),  # crops count, too large
        record(0.5, 0.5, 1.0, method="otsu"),  # another method's
    ]
    assert bench.wrong_outlines(records, "dev") == {
        "wrong": 3,
        "too_large": 2,
        "too_small": 1,
        "near": 1,
        "no_rock": 1,
    }


def _squares() -> np.ndarray:
    truth = np.zeros((20, 30), np.int32)
    truth[2:8, 2:8] = 1
    truth[2:8, 8:14] = 2  # touching 1
    truth[12:18, 20:26] = 3
    return truth


def test_crowd_score_of_a_perfect_but_renumbered_answer():
    truth = _squares()
    found = np.choose(truth, [0, 7, 3, 5])
    assert bench.score_crowd(found, truth) == bench.CrowdScore(3, 3, 3, 0, 0)


def test_crowd_score_counts_a_merge_and_a_split():
    truth = _squares()
    found = np.zeros_like(truth)
    found[(truth == 1) | (truth == 2)] = 1  # two touching rocks as one
    found[12:18, 20:23] = 2  # rock 3 in two halves
    found[12:18, 23:26] = 3
    assert bench.score_crowd(found, truth) == bench.CrowdScore(3, 3, 0, 1, 1)


def test_crowd_score_matches_one_to_one_above_half_overlap():
    truth = _squares()
    found = np.zeros_like(truth)
    found[2:8, 2:8] = 1  # exact
    found[2:8, 10:14] = 2  # two thirds of rock 2: IoU 0.67
    found[12:18, 23:26] = 3  # half of rock 3: IoU 0.5 is no match
    found[0:2, 25:30] = 4  # a false find
    score = bench.score_crowd(found, truth)
    assert (score.n_true, score.n_found, score.matched, score.merges, score.splits) == (3, 4, 2, 0, 0)


def test_overlap_table_counts_pixels():
    truth = np.array([[0, 1, 1], [2, 2, 0]])
    found = np.array([[1, 1, 0], [1, 0, 0]])
    np.testing.assert_array_equal(bench.overlap_table(found, truth), [[1, 1, 1], [1, 1, 1]])


def test_crop_choice_is_the_region_under_the_centre():
    labels = np.zeros((21, 21), np.int32)
    labels[:, :4] = 1  # a big neighbour at the edge
    labels[8:13, 8:13] = 2
    out = bench._choose(labels, "crop")
    np.testing.assert_array_equal(out == 1, labels == 2)
    np.testing.assert_array_equal(bench._choose(labels, "one") == 1, labels == 1)


def test_segmentation_labels_fill_the_pipelines_outline_at_photo_resolution():
    from rockscan.core.segment import segment

    scene = scenes.make_scene("plain", 1)
    labels = bench.segmentation_labels(segment(scene.image), scene.image.shape[:2])
    assert labels.shape == scene.labels.shape
    assert bench.iou(labels == 1, scene.labels == 1) > 0.8


def test_evaluate_scores_a_segmenter_that_finds_nothing():
    from rockscan.core.errors import NoRockFoundError

    def nothing(pixels, *, all_rocks):
        raise NoRockFoundError("no rock found")

    rows = bench.evaluate(nothing, "dev", ["plain", "crowded"], 1)
    by = {r["condition"]: r for r in rows}
    assert by["plain"]["good"] == 0.0 and by["plain"]["no_rock"] == 1
    assert by["crowded"]["matched"] == 0.0 and by["crowded"]["exact_count"] == 0.0
    with pytest.raises(ValueError, match="unknown conditions"):
        bench.evaluate(nothing, "dev", ["nope"], 1)


# --------------------------------------------------------------------------- real photos


def test_coin_reference_has_24_separate_round_coins():
    from skimage.measure import regionprops

    labels = bench.coins_reference()
    assert labels.shape == (303, 384) and labels.max() == 24
    for region in regionprops(labels):
        assert 900 < region.area < 3400
        assert region.solidity > 0.95
        assert region.eccentricity < 0.6
        # Every coin is one piece.
        assert ndi.label(labels == region.label)[1] == 1


@pytest.mark.parametrize(("crops", "count"), [("coin_crops", 24), ("nuclei_crops", 40)])
def test_crops_are_centred_with_a_third_of_a_diameter_of_margin(crops, count):
    crops = getattr(bench, crops)()
    assert len(crops) == count
    for image, truth in crops:
        assert image.shape == truth.shape and truth.max() == 1
        rows = np.flatnonzero(truth.any(axis=1))
        cols = np.flatnonzero(truth.any(axis=0))
        diameter = max(rows[-1] - rows[0], cols[-1] - cols[0]) + 1
        # A square of the diameter and a third on each side (less where the photo ends).
        assert max(image.shape) <= round(5 * diameter / 3) + 2
        margins = (rows[0], image.shape[0] - 1 - rows[-1], cols[0], image.shape[1] - 1 - cols[-1])
        assert max(margins) >= diameter / 3 - 1


def test_nuclei_reference_has_40_whole_nuclei_apart_from_what_is_not_scored():
    from skimage.measure import regionprops

    image, labels = bench.nuclear_photo(), bench.nuclei_reference()
    assert image.shape == labels.shape == (1024, 1344) and image.dtype == np.uint8
    nuclei = np.maximum(labels, 0)
    assert nuclei.max() == 40 and set(np.unique(labels)) == {bench.UNSCORED, *range(41)}
    for region in regionprops(nuclei):
        assert 1000 < region.area < 9000
        assert region.solidity > 0.95  # nuclei are convex; the reference's outline is their hull
        r0, c0, r1, c1 = region.bbox
        assert min(r0, c0, 1024 - r1, 1344 - c1) >= 3  # whole: none cut by the frame
        assert ndi.label(nuclei == region.label)[1] == 1
    # Every nucleus stands out of the ground's noise (the faintest by 3.7 of its
    # standard deviations: 7 gray levels).
    ground = image[labels == 0]
    for k in range(1, 41):
        assert np.median(image[nuclei == k]) > np.median(ground) + 3 * ground.std()


def test_unscored_regions_are_dropped_and_unscored_truth_is_ground():
    truth = np.zeros((20, 20), np.int32)
    truth[2:8, 2:8] = 1
    truth[10:18, 10:18] = bench.UNSCORED
    found = np.zeros_like(truth)
    found[2:8, 2:8] = 1
    found[10:18, 9:18] = 2  # most of it on unscored pixels
    found[12:18, 0:4] = 3  # on the ground: a false rock
    kept, scored = bench.scored_parts(found, truth)
    assert set(np.unique(kept)) == {0, 1, 3} and set(np.unique(scored)) == {0, 1}
    crowd = bench.score_crowd(kept, scored)
    assert (crowd.n_true, crowd.n_found, crowd.matched) == (1, 2, 1)


def test_cell_reference_is_one_round_cell_inside_its_halo():
    from skimage import data
    from skimage.measure import regionprops

    labels = bench.cell_reference()
    image = data.cell()
    assert labels.shape == image.shape and labels.max() == 1
    (region,) = regionprops(labels)
    assert region.solidity > 0.97 and region.eccentricity < 0.4
    # Inside, the cell is bright; just outside lies the dark halo, not the cell.
    ring = ndi.binary_dilation(labels == 1, iterations=3) & ~(labels == 1)
    assert np.median(image[labels == 1]) > 2 * np.median(image[ring])


def test_the_benchmark_prints_one_table_and_writes_strict_json(tmp_path, capsys):
    import json

    out = tmp_path / "bench.json"
    assert (
        bench.main(["--n", "1", "--conditions", "small,crowded", "--methods", "otsu", "--json", str(out)])
        == 0
    )
    table = capsys.readouterr().out
    assert table.startswith("| part | condition | method |")
    assert "| dev | small | otsu | 1 |" in table and "| dev | crowded | otsu | 1 (" in table
    data = json.loads(out.read_text(), parse_constant=lambda name: pytest.fail(f"{name} in JSON"))
    assert {r["condition"] for r in data["rows"]} == {"small", "crowded", "all one-rock"}
    assert len(data["records"]) == 2


def test_the_benchmark_reads_a_later_block_of_seeds_with_first(tmp_path, capsys):
    import json

    out = tmp_path / "bench.json"
    args = ["--n", "2", "--first", "7", "--conditions", "small", "--methods", "otsu", "--json", str(out)]
    assert bench.main(args) == 0
    assert [r["index"] for r in json.loads(out.read_text())["records"]] == [7, 8]
    image, _, _ = bench.photo("dev", "small", 7)
    assert np.array_equal(image, scenes.make_scene("small", 7).image)
    assert bench.main(["--first", "-1", "--methods", "otsu"]) == 2
    assert "--first below 0" in capsys.readouterr().err


def test_the_benchmark_says_the_auroc_is_undefined_without_wrong_outlines(capsys):
    # The real cell alone: one photo, outlined right (IoU 0.99), none wrong.
    assert bench.main(["--part", "real", "--conditions", "cell", "--methods", "rockscan"]) == 0
    out = capsys.readouterr().out
    assert "| real | cell | rockscan | 1 | 100.0% (20.7-100.0) |" in out
    assert "real: segmentation_score AUROC undefined (IoU >= 0.9: 1, IoU < 0.8: 0)" in out
    assert "nan" not in out


def test_the_benchmark_refuses_an_unknown_condition_in_one_line(capsys):
    assert bench.main(["--conditions", "nope", "--methods", "otsu"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: unknown conditions") and "plain" in err[-1]


def test_a_label_image_of_the_wrong_shape_is_refused():
    method = bench.as_method(lambda pixels, *, all_rocks: np.zeros((3, 3), np.int32))
    with pytest.raises(ValueError, match="shape"):
        method(np.zeros((10, 10), np.uint8), "one")


def test_a_rock_is_lighter_or_darker_than_the_ground_around_it():
    rr, cc = np.mgrid[:90, :120]
    rock = (rr - 45) ** 2 + (cc - 60) ** 2 <= 20**2
    for rock_level, ground_level, lighter in ((200, 90, True), (40, 90, False)):
        gray = np.where(rock, rock_level, ground_level).astype(np.uint8)
        assert bench.rock_is_lighter(np.dstack([gray] * 3), rock) is lighter
    assert bench.rock_is_lighter(np.zeros((20, 20), np.uint8), np.zeros((20, 20), bool)) is None


def test_right_outlines_are_counted_apart_for_light_and_dark_rocks():
    def record(iou, lighter, kind="one", method="rockscan"):
        return {"part": "dev", "method": method, "kind": kind, "iou": iou, "lighter": lighter}

    records = [
        record(0.95, True),
        record(0.5, True),
        record(0.92, False),
        record(0.99, None),  # a rock without a ring of ground counts in neither
        record(0.99, True, method="otsu"),
        {"part": "dev", "method": "rockscan", "kind": "all", "iou": None},
    ]
    assert bench.by_brightness(records, "dev") == {"lighter": (1, 2), "darker": (1, 1)}


def _record(score: float, iou: float, part: str = "heldout") -> dict:
    return {"part": part, "method": "rockscan", "kind": "one", "score": score, "iou": iou}


def test_score_auroc_counts_right_above_wrong_and_ignores_the_middle():
    records = [_record(0.9, 0.95), _record(0.3, 0.92), _record(0.5, 0.5), _record(0.1, 0.7)]
    records += [_record(0.99, 0.85), _record(0.2, 0.99, part="dev")]
    # Right (0.9, 0.3) against wrong (0.5, 0.1): three of the four pairs ranked right.
    assert bench.score_auroc(records, "heldout") == (0.75, 2, 2)


def test_the_auroc_interval_holds_the_auroc_and_narrows_with_more_photos():
    rng = np.random.default_rng(1)

    def drawn(n: int) -> list[dict]:
        # Right outlines score higher on average, with overlap.
        right = rng.uniform(size=n) < 0.8
        scores = np.clip(rng.normal(np.where(right, 0.7, 0.4), 0.2), 0.0, 1.0)
        return [_record(float(s), 0.95 if r else 0.5) for s, r in zip(scores, right, strict=True)]

    few, many = drawn(60), drawn(2000)
    for records in (few, many):
        auroc, _, _ = bench.score_auroc(records, "heldout")
        low, high = bench.auroc_interval(records, "heldout")
        assert low < auroc < high
    few_width = np.subtract(*bench.auroc_interval(few, "heldout")[::-1])
    many_width = np.subtract(*bench.auroc_interval(many, "heldout")[::-1])
    assert many_width < few_width / 2
    # Seeded: the same records give the same interval.
    assert bench.auroc_interval(few, "heldout") == bench.auroc_interval(few, "heldout")


def test_the_auroc_interval_is_nan_without_wrong_outlines():
    low, high = bench.auroc_interval([_record(0.9, 0.95), _record(0.2, 0.99)], "heldout")
    assert np.isnan(low) and np.isnan(high)


def test_the_score_figure_is_a_png_and_none_without_scores(tmp_path):
    rng = np.random.default_rng(0)
    records = [_record(float(s), float(i)) for s, i in rng.uniform(size=(60, 2))]
    path = bench.write_score_figure(records, "heldout", tmp_path / "score.png")
    assert path == tmp_path / "score.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert bench.write_score_figure(records, "dev", tmp_path / "none.png") is None
    assert not (tmp_path / "none.png").exists()


# --------------------------------------------------------------------------- intervals


@pytest.mark.parametrize(
    ("successes", "n", "low", "high"),
    [
        # Wilson's score interval at 95%, worked by hand:
        # centre (p + z^2/2n) / (1 + z^2/n), half-width z sqrt(p(1-p)/n + z^2/4n^2) / (1 + z^2/n).
        (0, 10, 0.0, 0.27753),
        (10, 10, 0.72247, 1.0),
        (20, 40, 0.35200, 0.64800),
        (30, 40, 0.59806, 0.85813),
        (1, 1, 0.20654, 1.0),
    ],
)
def test_the_wilson_interval_matches_its_formula(successes, n, low, high):
    assert bench.wilson_interval(successes, n) == pytest.approx((low, high), abs=1e-5)


@pytest.mark.parametrize("n", [1, 7, 40, 440])
def test_the_wilson_interval_holds_the_share_and_stays_in_the_unit_range(n):
    for successes in range(n + 1):
        low, high = bench.wilson_interval(successes, n)
        assert 0.0 <= low <= successes / n <= high <= 1.0


def test_the_wilson_interval_narrows_as_the_square_root_of_the_photos():
    few = np.subtract(*bench.wilson_interval(30, 40)[::-1])
    many = np.subtract(*bench.wilson_interval(3000, 4000)[::-1])
    assert many == pytest.approx(few / 10, rel=0.05)
    assert all(np.isnan(bench.wilson_interval(0, 0)))


def _scene(matched: int, n_true: int, exact: bool = True) -> dict:
    return {
        "part": "heldout",
        "condition": "crowded",
        "method": "rockscan",
        "kind": "all",
        "n_true": n_true,
        "n_found": n_true if exact else n_true + 1,
        "matched": matched,
        "merges": 0,
        "splits": 0,
        "seconds": 0.1,
    }


def test_the_matched_interval_resamples_scenes_not_rocks():
    # Twenty scenes of 20 rocks: ten all matched, ten half matched (75% in all).
    scenes_ = [_scene(20, 20)] * 10 + [_scene(10, 20)] * 10
    low, high = bench.matched_interval(scenes_)
    assert low < 0.75 < high
    # The same 400 rocks as if each failed alone would give a far narrower interval.
    rocks = bench.wilson_interval(300, 400)
    assert high - low > 1.5 * (rocks[1] - rocks[0])
    assert bench.matched_interval(scenes_) == (low, high)  # seeded
    assert all(np.isnan(bench.matched_interval([])))


def test_the_table_prints_each_share_with_its_interval():
    records = [_scene(20, 20)] * 3 + [_scene(18, 20, exact=False)]
    records += [
        {**_record(0.5, iou), "condition": "plain", "centroid_error": 0.0, "no_rock": False, "seconds": 0.1}
        for iou in (0.95, 0.95, 0.5, 0.99)
    ]
    table = bench.format_table(bench.summarize(records))
    assert "| heldout | plain | rockscan | 4 | 75.0% (30.1-95.4) |" in table
    assert "| 75.0% (30.1-95.4) | 97.5% (" in table  # exact count 3 of 4; rocks 78 of 80
