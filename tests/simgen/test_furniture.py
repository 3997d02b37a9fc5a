"""Street furniture (clutter.furniture): where signs, signals, bins, bollards, cycle stands and
the bicycles parked at them may stand, checked on the footprints of sampled worlds."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from simgen.road import RoadLayout
from simgen.sample import _footprint, sample_world
from simgen.materials import TYRE
from simgen.scenery import (
    BIKE_GAP,
    BIKE_L,
    SIDE_CLEARANCE,
    SIGN_LOWER_EDGE,
    SIGNS_PER_100M,
    STAND_OCCUPANCY,
    STAND_PITCH,
    _Furnisher,
    _Meshes,
    _outer,
    _stands,
    build_scenery,
)
from simgen.spec import spec_from_dict

ROADS = {"straight": {"type": "straight"}, "curved": {"type": "curved", "curvature": 0.006},
         "intersection": {"type": "intersection", "intersection_distance": 25.0,
                          "cross_lanes_per_direction": 2}}


def _world(road: str, frontage: dict | None = None, seed: int = 2, **traffic):
    spec = spec_from_dict({
        "name": "f", "road": {**ROADS[road], "sidewalk_width": 3.0},
        "traffic": {"parking_occupancy": 0.4, "pedestrians_per_100m": 20, **traffic},
        "clutter": {"furniture": 3.0, "frontage": frontage or {}, "side_streets_per_100m": 1.0}})
    return sample_world(spec, seed, 0)


def _furniture(scenery: dict):
    """The furniture's obstacles: built last, they follow those of the scenery without it."""
    _, base = build_scenery(dict(scenery, clutter=dict(scenery["clutter"], furniture=0.0)))
    _, full = build_scenery(scenery)
    for a, b in zip(base, full):  # the rest of the scenery is untouched
        assert a.base == b.base and a.polygon.equals_exact(b.polygon, 0.0)
    return full[len(base):]


def _carriageways(road: RoadLayout) -> shapely.Geometry:
    ss = road.samples(road.s_min, road.s_max, 1.0)
    main = shapely.Polygon(np.concatenate([road.xy(ss, road.right_curb), road.xy(ss[::-1], road.left_curb)]))
    if road.cross_s is None:
        return main
    hw = road.cross_half_width
    return shapely.union(main, shapely.box(road.cross_s - hw, -1e4, road.cross_s + hw, 1e4))


def _sidewalks(road: RoadLayout) -> shapely.Geometry:
    ss = road.samples(road.s_min, road.s_max, 1.0)
    return shapely.union_all([shapely.Polygon(np.concatenate([
        road.xy(ss, road.right_curb if side < 0 else road.left_curb), road.xy(ss[::-1], _outer(road, side))]))
        for side in (-1, 1)])


@pytest.mark.parametrize("road,frontage", [("straight", None), ("curved", None), ("intersection", None),
                                           ("straight", {"row": 1, "houses": 1}),
                                           ("intersection", {"row": 1, "houses": 1})])
def test_furniture_stands_on_the_sidewalks_clear_of_the_carriageway(road, frontage):
    world = _world(road, frontage)
    layout = RoadLayout(**world.scenery["road"])
    pieces = _furniture(world.scenery)
    assert len(pieces) > 20
    lanes, walks = _carriageways(layout), _sidewalks(layout)
    for o in pieces:
        assert o.polygon.distance(lanes) > 0.3  # VwV-StVO's least lateral clearance in town
        assert o.polygon.within(walks.buffer(1e-6))


def test_no_actor_stands_in_the_furniture():
    for road in ("straight", "intersection"):
        world = _world(road, {"row": 1, "houses": 1}, pedestrians_per_100m=50)
        pieces = _furniture(world.scenery)
        walkers = [a for a in world.actors if a.cls == "Pedestrian"]
        assert len(walkers) > 20
        for a in world.actors:
            h, w, l = a.recipe["dims"]
            fp = _footprint(a.pose, l, w, 0.0)
            top = a.pose[2, 3] + h
            assert not any(o.base < top and fp.intersects(o.polygon) for o in pieces), a.id


@pytest.mark.parametrize("road", ["straight", "curved", "intersection"])
def test_traffic_signals_stand_only_at_the_intersection_one_per_corner(road):
    world = _world(road)
    layout = RoadLayout(**world.scenery["road"])
    lenses = [p for p in world.static if p.material.name == "signal_lens"]
    if layout.cross_s is None:
        assert not lenses
        return
    v = np.concatenate([p.mesh.vertices for p in lenses])
    assert len(v) == 4 * 3 * 16  # four heads of three octagonal lenses
    hw, walk = layout.cross_half_width, layout.sidewalk_width
    for x, y in v[:, :2]:  # at the corners: on both streets' sidewalks
        assert hw < abs(x - layout.cross_s) < hw + walk
        assert layout.right_curb - walk < y < layout.right_curb or layout.left_curb < y < layout.left_curb + walk
    lit = [p for p in lenses if max(p.material.color) == 1.0]
    assert sum(len(p.mesh.vertices) for p in lit) == 4 * 16  # one lamp lit per head
    assert len(lit) <= 2  # the main road's phase and the cross street's


def test_sign_plates_hang_high_enough_and_clear_of_the_carriageway():
    """VwV-StVO: lower edge 2.0 m above the footway, the nearest edge 0.5 m from the carriageway."""
    world = _world("straight")
    layout = RoadLayout(**world.scenery["road"])
    coloured = [p for p in world.static if p.material.name in ("sign_red", "sign_blue", "sign_yellow")]
    assert coloured and min(p.mesh.vertices[:, 2].min() for p in coloured) >= layout.curb_height + 2.0 - 1e-9
    plates = [o for o in _furniture(world.scenery) if o.base == layout.curb_height + SIGN_LOWER_EDGE]
    assert len(plates) > 5
    lanes = _carriageways(layout)
    for o in plates:
        assert o.polygon.distance(lanes) == pytest.approx(SIDE_CLEARANCE, abs=1e-6)


def test_sign_density_is_the_documented_rate():
    """Signs per side and 100 m, times clutter.furniture (on a street where nothing else stands)."""
    spec = spec_from_dict({"name": "d", "clutter": {"buildings": False, "trees_per_100m": 0,
                                                     "pole_spacing": 0, "furniture": 1.0}})
    scenery = sample_world(spec, 1, 0).scenery
    road = RoadLayout(**scenery["road"])
    counts = [sum(o.base == road.curb_height + SIGN_LOWER_EDGE for o in _furniture(dict(scenery, seed=k)))
              for k in range(30)]
    expected = 2 * SIGNS_PER_100M * (road.s_max - road.s_min) / 100.0
    assert np.mean(counts) == pytest.approx(expected, rel=0.15)


def test_scenery_parameters_from_before_the_furniture_build_none():
    world = _world("intersection")
    clutter = world.scenery["clutter"]
    old = dict(world.scenery, clutter={k: v for k, v in clutter.items() if k != "furniture"})
    off = dict(world.scenery, clutter=dict(clutter, furniture=0.0))
    for p, q in zip(build_scenery(old)[0], build_scenery(off)[0], strict=True):
        assert p.material == q.material and np.array_equal(p.mesh.vertices, q.mesh.vertices)
    assert "signal_lens" not in {p.material.name for p in build_scenery(old)[0]}


def test_parked_bicycles_stand_at_their_stands_on_the_sidewalk_and_fill_about_half_the_places():
    """Each stand has a place on either side of its bar; a bicycle (BIKE_L long, its wheels on the
    sidewalk) takes one with probability STAND_OCCUPANCY, its frame BIKE_GAP from the bar's axis."""
    layout = RoadLayout(curvature=0.0, lanes=1, lane_width=3.5, ego_lane=0, sidewalk_width=3.0,
                        curb_height=0.15, parking=False, s_min=-50.0, s_max=150.0)
    out = _Meshes([])
    f = _Furnisher(layout, out)
    rng = np.random.default_rng(11)
    groups, n = 12, 5
    for g in range(groups):
        _stands(f, -1, 10.0 * g, n, rng)
    tyres = out.by_mat.get(TYRE, [])  # a wheel is 16 segments of its ring
    assert len(tyres) % 32 == 0
    bikes = len(tyres) // 32
    places = 2 * groups * n
    # binomial: 120 places at p = 0.5 have an sd of 5.5 bicycles; 4 sd either way
    assert abs(bikes - STAND_OCCUPANCY * places) <= 4 * np.sqrt(places * 0.25)
    walk = shapely.Polygon(np.concatenate([layout.xy(np.array([-50.0, 150.0]), layout.right_curb),
                                           layout.xy(np.array([150.0, -50.0]), layout.right_curb - 3.0)]))
    bars_s = np.array([10.0 * g + k * STAND_PITCH for g in range(groups) for k in range(n)])
    for segment in tyres:
        v = np.asarray(segment.vertices)
        assert v[:, 2].min() >= layout.curb_height - 1e-9  # above the sidewalk
        assert shapely.MultiPoint(v[:, :2]).within(walk)
        # beside a bar: on a straight road x is s; the wheel's mid-plane BIKE_GAP from a bar's axis
        gaps = np.abs(v[:, 0].mean() - bars_s)
        assert gaps.min() == pytest.approx(BIKE_GAP, abs=1e-9)
    # across the sidewalk: the bicycles from SIDE_CLEARANCE to SIDE_CLEARANCE + BIKE_L behind the curb
    zs = np.concatenate([np.asarray(w.vertices)[:, 2] for w in tyres])
    assert zs.min() == pytest.approx(layout.curb_height, abs=1e-9)  # the wheels on the sidewalk
    ys = np.concatenate([np.asarray(w.vertices)[:, 1] for w in tyres])
    assert layout.right_curb - ys.max() == pytest.approx(SIDE_CLEARANCE, abs=1e-9)
    assert layout.right_curb - ys.min() == pytest.approx(SIDE_CLEARANCE + BIKE_L, abs=1e-9)
