"""Parked rows (traffic.parking_occupancy) and standing queues (traffic.queue): on a straight,
flat road every position is exact, so the rows' gaps, kerb distances and corners, and the
queue's lane and standstill gaps are checked against the constants they come from."""

from __future__ import annotations

import numpy as np
import pytest

from simgen.road import PARKING_WIDTH
from simgen.sample import CORNER_CLEAR, KERB_GAP, PARKED_GAP, PARKED_MARGIN, QUEUE_GAP, sample_world
from simgen.scenery import build_scenery
from simgen.scenery.frontage import DRIVE_GAP
from simgen.spec import spec_from_dict


def _spec(road: dict | None = None, **traffic):
    return spec_from_dict({
        "name": "rows", "road": {"type": "straight", "lanes_per_direction": 1, "lane_width": 3.0,
                                 **(road or {})},
        "rig": {"type": "onboard", "ego_speed": 0.0},
        "clutter": {"buildings": False, "trees_per_100m": 0.0, "pole_spacing": 0.0, "furniture": 0.0},
        "traffic": {"vehicles_per_100m": 0.0, "pedestrians_per_100m": 0.0, "cyclists_per_100m": 0.0,
                    "heading_sd_deg": 0.0, "lateral_sd": 0.0, **traffic}})


def _row(world, side: int) -> list:
    """The parked vehicles of one kerb's strip (side -1 right, +1 left), in order along the road."""
    lane = 1.5  # the ego lane's centre to its edge: lane_width / 2
    out = [a for a in world.actors if side * a.pose[1, 3] > lane and not a.moving]
    return sorted(out, key=lambda a: a.pose[0, 3])


@pytest.mark.parametrize("frame", [0, 1])
def test_a_full_row_stands_nose_to_tail_with_the_published_gaps_and_kerb_distance(frame):
    world = sample_world(_spec(parking_occupancy=1.0), 3, frame)
    right_curb = -1.5 - PARKING_WIDTH
    for side in (-1, 1):
        row = _row(world, side)
        assert len(row) > 20  # 100 m behind to 120 m ahead: a bay every 4-7 m
        rear = np.array([a.pose[0, 3] - a.recipe["dims"][2] / 2 for a in row])
        front = np.array([a.pose[0, 3] + a.recipe["dims"][2] / 2 for a in row])
        gaps = rear[1:] - front[:-1]
        assert gaps.min() >= PARKED_GAP[0] - 1e-9 and gaps.max() <= PARKED_GAP[1] + 1e-9
        for a in row:
            half_w = a.recipe["dims"][1] / 2
            kerb = (a.pose[1, 3] - half_w - right_curb) if side < 0 else (1.5 + 3.0 + PARKING_WIDTH
                                                                         - a.pose[1, 3] - half_w)
            assert KERB_GAP[0] - 1e-9 <= kerb <= KERB_GAP[1] + 1e-9
            assert np.allclose(a.pose[:3, 0], [-side, 0.0, 0.0], atol=1e-12)  # along its side's traffic
            assert a.cls in ("Car", "Van")


def test_occupancy_takes_that_share_of_the_bays():
    right = {"parking_sides": "right"}
    counts = [len(_row(sample_world(_spec(right, parking_occupancy=p), 3, 0), -1)) for p in (1.0, 0.5)]
    # 40-odd bays at p = 0.5: about 20 +- 3.2 taken; the bounds are 3 sd out
    assert abs(counts[1] - counts[0] / 2) < 3 * np.sqrt(counts[0] * 0.25)
    assert not _row(sample_world(_spec(right, parking_occupancy=1.0), 3, 0), 1)


def test_the_corners_of_a_junction_stay_free():
    spec = _spec({"type": "intersection", "intersection_distance": 40.0}, parking_occupancy=1.0)
    for frame in range(3):
        world = sample_world(spec, 5, frame)
        half = 1 * 3.0  # the cross street: one lane each way
        for side in (-1, 1):
            for a in _row(world, side):
                l = a.recipe["dims"][2]
                assert abs(a.pose[0, 3] - 40.0) - l / 2 >= half + CORNER_CLEAR - 1e-9


@pytest.mark.parametrize("lots", ["houses", "car_park"])
def test_the_drives_and_car_park_entrances_stay_free(lots):
    """Each house's drive and each car park's two entrances leave the strip in front of them
    empty (StVO section 12(3) no. 3): every mouth is DRIVE_GAP long, lies between the kerb and
    the lane's edge, and no parked vehicle (grown by its placing margin) reaches into it."""
    spec = _spec(parking_occupancy=1.0)
    clutter = spec.clutter.model_copy(update={"frontage": {lots: 1.0}, "buildings": True})
    spec = spec.model_copy(update={"clutter": clutter})
    lane, curb = 1.5, 1.5 + PARKING_WIDTH  # |y| of the lane's edge and of the kerb, right side
    checked = 0
    for frame in range(2):
        world = sample_world(spec, 7, frame)
        _, obstacles = build_scenery(world.scenery)
        for side in (-1, 1):
            edge, kerb = (-lane, -curb) if side < 0 else (lane + 3.0, curb + 3.0)  # left: past the oncoming lane
            lo, hi = min(edge, kerb), max(edge, kerb)
            mouths = [o.polygon.bounds for o in obstacles
                      if np.isclose(o.polygon.bounds[1], lo) and np.isclose(o.polygon.bounds[3], hi)]
            row = [a for a in _row(world, side) if lo < a.pose[1, 3] < hi]  # the strip's, not the lots'
            assert mouths and len(row) > 10
            for x0, _, x1, _ in mouths:
                assert x1 - x0 == pytest.approx(DRIVE_GAP, abs=1e-9)
                for a in row:
                    reach = a.recipe["dims"][2] / 2 + PARKED_MARGIN
                    assert a.pose[0, 3] + reach <= x0 + 1e-9 or a.pose[0, 3] - reach >= x1 - 1e-9
            checked += len(mouths)
    assert checked >= 4


def test_a_queue_stands_in_the_oncoming_lane_nose_to_tail_at_standstill_gaps():
    world = sample_world(_spec(queue=1.0, parking_occupancy=0.0), 4, 0)
    q = sorted([a for a in world.actors if a.cls in ("Car", "Van", "Truck")], key=lambda a: a.pose[0, 3])
    assert len(q) >= 3
    assert all(not a.moving for a in q)
    assert np.allclose([a.pose[1, 3] for a in q], 3.0)  # the oncoming lane's centre
    assert all(np.allclose(a.pose[:3, 0], [-1.0, 0.0, 0.0], atol=1e-12) for a in q)
    ends = np.array([(a.pose[0, 3] - a.recipe["dims"][2] / 2, a.pose[0, 3] + a.recipe["dims"][2] / 2) for a in q])
    gaps = ends[1:, 0] - ends[:-1, 1]
    assert gaps.min() >= QUEUE_GAP[0] - 1e-9 and gaps.max() <= QUEUE_GAP[1] + 1e-9


def test_a_queue_takes_the_next_lane_of_the_egos_direction_where_there_is_one():
    world = sample_world(_spec({"lanes_per_direction": 2}, queue=1.0, parking_occupancy=0.0), 4, 0)
    q = [a for a in world.actors if a.cls in ("Car", "Van", "Truck")]
    assert q and np.allclose([a.pose[1, 3] for a in q], 3.0)  # one lane width left of the ego
    assert all(np.allclose(a.pose[:3, 0], [1.0, 0.0, 0.0], atol=1e-12) for a in q)


def test_specs_without_queues_or_parking_draw_neither():
    world = sample_world(_spec(queue=0.0, parking_occupancy=0.0), 4, 0)
    assert not [a for a in world.actors if a.cls in ("Car", "Van", "Truck")]
