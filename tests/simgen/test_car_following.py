"""Car following (traffic.lead_vehicle, traffic.column): the vehicle ahead of the ego stands where
the time gap puts it, moves with the ego, a column ahead of it keeps its gaps, and a spec without
them keeps its worlds."""

from __future__ import annotations

import numpy as np
import pytest

from simgen.sample import EGO_FREE_AHEAD, MARGIN, QUEUE_GAP, QUEUE_LENGTH, sample_world
from simgen.spec import spec_from_dict


def _spec(**traffic):
    return spec_from_dict({
        "name": "follow", "road": {"type": "straight", "lanes_per_direction": 2, "ego_lane": 1},
        "rig": {"type": "onboard", "ego_speed": 8.0},
        "traffic": {"vehicles_per_100m": 2.0, "heading_sd_deg": 0.0, "lateral_sd": 0.0, **traffic}})


@pytest.mark.parametrize("frame", [0, 1, 2])
def test_the_leader_is_the_time_gap_ahead_in_the_ego_lane_at_the_ego_speed(frame):
    world = sample_world(_spec(lead_vehicle=1.0, headway_s=1.5), 4, frame)
    leader = world.actors[0]  # placed first
    _, _, length = leader.recipe["dims"]
    x, y, z = leader.pose[:3, 3]
    # The LiDAR is at the ego lane's centre: the leader's rear 8 m/s x 1.5 s beyond the ego's
    # free lane and its margin (plus 5 cm), on the lane's centre line, heading down the road.
    assert x - length / 2 == pytest.approx(EGO_FREE_AHEAD + MARGIN + 12.0 + 0.05, abs=1e-9)
    assert y == pytest.approx(0.0, abs=1e-9) and z == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(leader.pose[:3, 0], [1.0, 0.0, 0.0], atol=1e-12)
    assert np.allclose(leader.velocity, world.ego_velocity, atol=1e-12)
    assert leader.cls in ("Car", "Van", "Truck")


def test_a_spec_without_car_following_keeps_its_worlds():
    a = sample_world(_spec(), 4, 0)
    b = sample_world(_spec(lead_vehicle=0.0, headway_s=3.0), 4, 0)
    assert [x.cls for x in a.actors] == [x.cls for x in b.actors]
    assert all(np.array_equal(p.pose, q.pose) for p, q in zip(a.actors, b.actors))
    nearest = min(abs(x.pose[0, 3]) for x in a.actors if abs(x.pose[1, 3]) < 1.0)
    assert nearest > EGO_FREE_AHEAD  # nothing in the ego's own free lane


def test_leaders_follow_in_about_the_share_of_frames():
    spec = _spec(lead_vehicle=0.5, headway_s=1.0, vehicles_per_100m=0.0)
    rear = EGO_FREE_AHEAD + MARGIN + 8.0 + 0.05
    led = [any(abs(a.pose[0, 3] - a.recipe["dims"][2] / 2 - rear) < 1e-9 for a in w.actors)
           for w in (sample_world(spec, 7, i) for i in range(24))]
    # 24 draws at p = 0.5: 12 +- 2.4; the bounds are 4 sd out.
    assert 3 <= sum(led) <= 21


def test_no_leader_beyond_the_traffics_reach():
    spec = _spec(lead_vehicle=1.0, headway_s=10.0, vehicles_per_100m=0.0, max_distance=60.0)
    world = sample_world(spec, 4, 0)  # 8 m/s x 10 s puts its rear 86.6 m ahead
    assert not any(abs(a.pose[1, 3]) < 0.5 and a.pose[0, 3] > EGO_FREE_AHEAD for a in world.actors
                   if a.cls in ("Car", "Van", "Truck"))


def _in_ego_lane(world) -> list:
    """The vehicles ahead in the ego's lane (its centre line is y = 0), nearest first."""
    ahead = [a for a in world.actors if a.cls in ("Car", "Van", "Truck") and abs(a.pose[1, 3]) < 0.5
             and a.pose[0, 3] > 0]
    return sorted(ahead, key=lambda a: a.pose[0, 3])


@pytest.mark.parametrize("speed", [0.0, 8.0])
def test_a_column_ahead_of_the_leader_keeps_the_standstill_gap_plus_the_time_gap(speed):
    spec = _spec(lead_vehicle=1.0, column=1.0, headway_s=1.5, vehicles_per_100m=0.0)
    spec = spec.model_copy(update={"rig": spec.rig.model_copy(update={"ego_speed": speed})})
    for frame in range(3):
        world = sample_world(spec, 4, frame)
        column = _in_ego_lane(world)
        assert len(column) >= 2
        front = [a.pose[0, 3] + a.recipe["dims"][2] / 2 for a in column]
        rear = [a.pose[0, 3] - a.recipe["dims"][2] / 2 for a in column]
        gaps = np.subtract(rear[1:], front[:-1]) - speed * 1.5
        # Each gap is a standstill gap drawn from QUEUE_GAP (to rounding), each vehicle at the
        # ego's speed; the column ends within QUEUE_LENGTH of the leader's front.
        assert np.all(gaps >= QUEUE_GAP[0] - 1e-9) and np.all(gaps <= QUEUE_GAP[1] + 1e-9)
        assert rear[-1] - front[0] < QUEUE_LENGTH[1]
        for a in column:
            assert np.allclose(a.velocity, world.ego_velocity, atol=1e-12)


@pytest.mark.parametrize("frame", [0, 1, 2])
def test_without_a_column_the_leader_stands_alone_in_the_ego_lane(frame):
    spec = _spec(lead_vehicle=1.0, vehicles_per_100m=0.0)
    assert spec.traffic.column.values == (0.0,)
    assert len(_in_ego_lane(sample_world(spec, 4, frame))) == 1
