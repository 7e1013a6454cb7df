"""A shadow cut keeps to parts with the ground's hue (``shadow.hue_from_ground``
and its use in ``rockscan.core.segment.finish`` and, for an inner outline that
leaves a shadow out, in ``rockscan.core.segment``).

The model photos are the lit dome of ``test_segment_shadow`` in colour: the
rock and the ground each reflect the light in a hue of their own, and a cast
shadow is the ground darkened. Then photos of the independent generator on
which the shadow step, before it read hue, cut a darker band of the rock.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_segment_shadow import lit_rock

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_segment

import rockscan.core.segment as segment_module
import rockscan.core.segment.finish as finish
from rockscan.core.segment import segment
from rockscan.core.segment.shadow import hue_from_ground

PURPLE = np.array([0.9, 0.55, 1.0])
GREEN = np.array([0.55, 1.0, 0.6])


def in_colour(
    rock_hue: np.ndarray, ground_hue: np.ndarray, **kwargs
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lit dome's photo with the rock's reflectance in one hue and the ground's in
    another (each channel's albedo scaled), its rock and its cast shadow."""
    photo, rock, shadow = lit_rock(**kwargs)
    hue = np.where(rock[..., None], rock_hue, ground_hue)
    return np.clip(photo[..., None] * hue, 0.0, 1.0), rock, shadow


@pytest.mark.parametrize("azimuth", [0.0, 100.0, 200.0, 300.0])
def test_a_cast_shadow_has_the_grounds_hue(azimuth):
    colour, rock, shadow = in_colour(PURPLE, GREEN, azimuth=np.radians(azimuth))
    assert shadow.sum() > 500
    # Every pixel of the shadow has the ground's chromaticity exactly.
    assert hue_from_ground(colour, rock | shadow, shadow) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("azimuth", [0.0, 100.0, 200.0, 300.0])
def test_a_rocks_shaded_side_has_the_rocks_hue(azimuth):
    colour, rock, _ = in_colour(PURPLE, GREEN, azimuth=np.radians(azimuth))
    # The darkest third of the dome: its side turned from the light.
    brightness = colour.sum(axis=2)
    shaded = rock & (brightness <= np.percentile(brightness[rock], 33))
    assert hue_from_ground(colour, rock, shaded) == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_under_sensor_noise_shadow_and_shaded_side_stay_on_their_sides(seed):
    colour, rock, shadow = in_colour(PURPLE, GREEN, seed=seed)
    rng = np.random.default_rng(seed)
    colour = np.clip(colour + 0.02 * rng.standard_normal(colour.shape), 0.0, 1.0)
    brightness = colour.sum(axis=2)
    shaded = rock & (brightness <= np.percentile(brightness[rock], 33))
    assert hue_from_ground(colour, rock | shadow, shadow) < 1.0 - finish.ROCK_HUE
    assert hue_from_ground(colour, rock, shaded) >= finish.ROCK_HUE


@settings(max_examples=25, deadline=None)
@given(st.floats(0.4, 1.0), st.sampled_from([0.0, 100.0, 200.0, 300.0]))
def test_the_place_in_hue_does_not_depend_on_how_dark_the_part_is(factor, azimuth):
    # Chromaticity is brightness divided out: a deeper or a paler shadow, or
    # shaded side, lies in hue where it did.
    colour, rock, shadow = in_colour(PURPLE, GREEN, azimuth=np.radians(azimuth))
    brightness = colour.sum(axis=2)
    shaded = rock & (brightness <= np.percentile(brightness[rock], 33))
    for region, part in ((rock | shadow, shadow), (rock, shaded)):
        dimmed = colour.copy()
        dimmed[part] *= factor
        assert hue_from_ground(dimmed, region, part) == pytest.approx(
            hue_from_ground(colour, region, part), abs=1e-9
        )


def test_a_gray_photo_in_colour_cannot_tell():
    colour, rock, shadow = in_colour(np.ones(3), np.ones(3))
    assert hue_from_ground(colour, rock | shadow, shadow) is None


def test_a_part_too_dark_for_a_hue_cannot_tell():
    colour, rock, shadow = in_colour(PURPLE, GREEN)
    colour[shadow] = 0.0
    assert hue_from_ground(colour, rock | shadow, shadow) is None


# Development photos whose outline was right until the shadow step cut a
# darker band of the rock off it, a band of the rock's hue on ground of
# another (IoU 0.991 -> 0.899, 0.989 -> 0.890 and 0.989 -> 0.865), and photos
# whose cast shadow the step takes off in colour (0.641 -> 0.918, 0.757 ->
# 0.932 and 0.705 -> 0.953).
ROCK_BANDS = [("large", 4235), ("touching-pebbles", 4290), ("shaded", 4152)]
SHADOWS = [("shaded", 4164), ("shaded", 4262), ("shaded", 4271)]


def outlined(condition: str, index: int) -> float:
    pixels, truth, kind = bench_segment.photo("dev", condition, index)
    found, _ = bench_segment.as_method(segment)(pixels, kind)
    return bench_segment.score_rock(found == 1, truth == 1).iou


# Development photos whose chosen outline was replaced by a candidate inside it
# that left out a darker part of the rock's own hue, taken for its shadow
# (IoU 0.855 and 0.668 before the hue was read).
INNER_BANDS = [("bipolar-ground", 4200), ("shaded", 4298)]


@pytest.mark.parametrize(
    ("condition", "index", "least"),
    [(*photo, 0.95) for photo in ROCK_BANDS + INNER_BANDS] + [(*photo, 0.9) for photo in SHADOWS],
)
def test_a_band_of_the_rocks_hue_stays_and_a_shadow_of_the_grounds_goes(condition, index, least):
    assert outlined(condition, index) >= least


@pytest.mark.parametrize(
    ("module", "photo", "most"),
    [(finish, ROCK_BANDS[0], 0.92), (segment_module, INNER_BANDS[0], 0.9)],
    ids=["rays' cut", "inner outline"],
)
def test_without_hue_the_band_is_taken_for_a_shadow(monkeypatch, module, photo, most):
    monkeypatch.setattr(module, "rock_hued", lambda *args: False)
    # The last step would take the band back by its hue (``hued``).
    monkeypatch.setattr(finish, "hue_on", lambda colour, mask: mask)
    assert outlined(*photo) < most
