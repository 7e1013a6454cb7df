"""A part of a rock of the rock's own hue, left out of its outline, taken back
in (``rockscan.core.segment.hued`` and its use in ``rockscan.core.segment.finish``).

The model photos are the lit dome of ``test_segment_shadow`` in colour
(``test_segment_shadow_hue.in_colour``): the rock and the ground each reflect
the light in a hue of their own, so the dome's side turned from the light
keeps the rock's hue and its cast shadow the ground's. The outline given is
the dome's lit part alone, as a cue that reads brightness draws it. Then
photos of the independent generator whose outline left out a side of the
rock's hue.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_segment_shadow import iou
from test_segment_shadow_hue import GREEN, PURPLE, in_colour, outlined

import rockscan.core.segment.finish as finish
from rockscan.core.segment.hued import hue_on


def lit_part(colour: np.ndarray, rock: np.ndarray, share: float = 0.6) -> np.ndarray:
    """The brightest ``share`` of the dome: the part an outline by brightness takes."""
    brightness = colour.sum(axis=2)
    return rock & (brightness >= np.percentile(brightness[rock], 100.0 * (1.0 - share)))


@pytest.mark.parametrize("azimuth", [0.0, 100.0, 200.0, 300.0])
def test_the_shaded_side_joins_and_the_shadow_stays_out(azimuth):
    colour, rock, shadow = in_colour(PURPLE, GREEN, azimuth=np.radians(azimuth))
    lit = lit_part(colour, rock)
    assert iou(lit, rock) < 0.65
    grown = hue_on(colour, lit)
    assert iou(grown, rock) >= 0.95
    assert (grown & shadow).sum() <= 0.02 * shadow.sum()


@pytest.mark.parametrize("seed", range(3))
def test_under_sensor_noise_the_side_still_joins(seed):
    colour, rock, shadow = in_colour(PURPLE, GREEN, seed=seed)
    rng = np.random.default_rng(seed)
    colour = np.clip(colour + 0.02 * rng.standard_normal(colour.shape), 0.0, 1.0)
    grown = hue_on(colour, lit_part(colour, rock))
    assert iou(grown, rock) >= 0.93
    assert (grown & shadow).sum() <= 0.02 * shadow.sum()


@settings(max_examples=20, deadline=None)
@given(st.floats(0.4, 1.0), st.sampled_from([0.0, 100.0, 200.0, 300.0]))
def test_what_joins_does_not_depend_on_how_dark_the_side_is(factor, azimuth):
    # Chromaticity divides brightness out: a light rock's side in deeper
    # shade joins as well (raw colour would place it nearer the darker
    # ground).
    colour, rock, _ = in_colour(
        PURPLE, GREEN, azimuth=np.radians(azimuth), rock_albedo=0.6, ground_albedo=0.3
    )
    lit = lit_part(colour, rock)
    dimmed = colour.copy()
    dimmed[rock & ~lit] *= factor
    grown = hue_on(dimmed, lit)
    assert iou(grown, rock) >= 0.95
    # Only the rim, where the side's colour blurs into the ground's, moves.
    assert iou(grown, hue_on(colour, lit)) >= 0.97


def test_a_gray_photo_and_a_rock_of_the_grounds_hue_stay_as_they_are():
    for rock_hue, ground_hue in ((np.ones(3), np.ones(3)), (GREEN, GREEN)):
        colour, rock, _ = in_colour(rock_hue, ground_hue)
        lit = lit_part(colour, rock)
        assert hue_on(colour, lit) is lit


def test_a_side_too_dark_for_a_hue_is_not_taken():
    colour, rock, _ = in_colour(PURPLE, GREEN)
    lit = lit_part(colour, rock)
    colour[rock & ~lit] = 0.0
    assert hue_on(colour, lit).sum() <= 1.01 * lit.sum()


def test_a_neighbour_of_the_rocks_hue_does_not_join():
    # A pebble of the rock's hue, half its radius, touching the outlined
    # rock: taking it would leave the rock far less compact than it was.
    colour, rock, _ = in_colour(PURPLE, GREEN, azimuth=np.radians(90.0))
    lit = lit_part(colour, rock, share=1.0)
    rows, cols = np.mgrid[: rock.shape[0], : rock.shape[1]]
    pebble = (np.hypot(rows - 110, cols - (130 + 55 + 27)) <= 28) & ~rock
    colour[pebble] = colour[rock].mean(axis=0)
    assert hue_on(colour, lit) is lit


# Development photos whose outline left out a side of the rock's hue (IoU
# 0.572, 0.573, 0.783 and 0.811 before the side was taken in).
SIDES = [("shaded", 4061), ("highlights", 4307), ("touching-pebbles", 4193), ("low-contrast", 4094)]


@pytest.mark.parametrize(("condition", "index"), SIDES)
def test_a_side_of_the_rocks_hue_joins_its_outline(condition, index):
    assert outlined(condition, index) >= 0.95


@pytest.mark.parametrize(("condition", "index"), SIDES[:2])
def test_without_hue_the_side_is_left_out(monkeypatch, condition, index):
    monkeypatch.setattr(finish, "hue_on", lambda colour, mask: mask)
    assert outlined(condition, index) < 0.8
