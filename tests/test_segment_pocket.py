"""A crop's rock walled in by its neighbours, found against a pocket of ground
(``rockscan.core.segment.pocket``), on photos of the independent generator."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_segment

import rockscan.core.segment as segment_module
from rockscan.core.segment import SegmentConfig, segment
from rockscan.core.segment.channels import _at_scale, _channels, _pyramid, _unit
from rockscan.core.segment.detect import _detect
from rockscan.core.segment.pocket import centre_object, covers_centre


def detections(pixels: np.ndarray) -> list:
    """Each channel's detection of a photo, as ``segment`` makes them."""
    config = SegmentConfig()
    scale = max(1.0, max(pixels.shape[:2]) / config.detect_size)
    small, _ = _at_scale(_pyramid(pixels, config.detect_size), scale)
    small = _unit(small, pixels.dtype)
    found = (_detect(channel.values(small), channel, config, False) for channel in _channels(small))
    return [detection for detection in found if detection is not None]


def outlined(condition: str, index: int) -> float:
    pixels, truth, kind = bench_segment.photo("dev", condition, index)
    found, _ = bench_segment.as_method(segment)(pixels, kind)
    return bench_segment.score_rock(found == 1, truth == 1).iou


# Development crops whose border is mostly the neighbours': every region that
# stands out from it is a pocket of ground, none covers the centre, and the
# rock under the centre, of its neighbours' level, stood out from nothing
# (IoU 0.000, 0.008 and 0.000 without the pocket step).
WALLED = [4062, 4087, 4158]


@pytest.mark.parametrize("index", WALLED)
def test_no_region_found_covers_a_walled_in_rocks_centre(index):
    pixels, _, _ = bench_segment.photo("dev", "crop-neighbours", index)
    found = detections(pixels)
    assert found
    assert not any(covers_centre(detection) for detection in found)


@pytest.mark.parametrize("index", WALLED)
def test_a_walled_in_rock_is_found_against_its_pocket_of_ground(index):
    pixels, truth, _ = bench_segment.photo("dev", "crop-neighbours", index)
    objects = [centre_object(detection, SegmentConfig()) for detection in detections(pixels)]
    objects = [o for o in objects if o is not None]
    assert objects
    for found in objects:
        region = found.regions[0]
        rows, cols = region.shape
        assert region[rows // 2, cols // 2]
        # Inside the frame, and at detection size over most of the rock.
        assert not (region[0].any() or region[-1].any() or region[:, 0].any() or region[:, -1].any())
        small_truth = cv2.resize((truth == 1).astype(np.float32), (cols, rows), interpolation=cv2.INTER_AREA)
        assert bench_segment.iou(region, small_truth >= 0.5) >= 0.7


@pytest.mark.parametrize("index", WALLED)
def test_a_walled_in_rock_is_outlined(index):
    assert outlined("crop-neighbours", index) >= 0.9


def test_without_the_pocket_step_the_walled_in_rocks_are_lost(monkeypatch):
    monkeypatch.setattr(segment_module, "_pocket_candidates", lambda *args, **kwargs: [])
    assert all(outlined("crop-neighbours", index) < 0.1 for index in WALLED)


def test_a_rock_off_the_centre_keeps_its_outline():
    # A small light rock off the centre of a brick wall: taken for ground, it
    # leaves a brick under the centre, walled in by mortar as light as the
    # rock, that stands out from it less than it did from the wall.
    pixels, _, _ = bench_segment.photo("dev", "small", 4029)
    found = detections(pixels)
    assert not any(covers_centre(detection) for detection in found)
    assert all(centre_object(detection, SegmentConfig()) is None for detection in found)
    assert outlined("small", 4029) >= 0.9


def test_the_ground_under_the_centre_reaching_the_frame_is_no_object():
    # A dark disc off the centre of an even, noisy ground: taken for ground,
    # it leaves the ground under the centre, which reaches the frame (and,
    # running along it, stands out less than the disc did).
    rng = np.random.default_rng(3)
    rows, cols = np.mgrid[0:200, 0:240] + 0.5
    pixels = np.full((200, 240), 0.6) + rng.normal(0.0, 0.02, (200, 240))
    pixels[(rows - 50) ** 2 + (cols - 60) ** 2 <= 25**2] = 0.25
    found = detections(np.clip(pixels, 0.0, 1.0).astype(np.float32))
    assert found and not any(covers_centre(detection) for detection in found)
    assert all(centre_object(detection, SegmentConfig()) is None for detection in found)
