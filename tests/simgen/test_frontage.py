"""Lots beside the street (clutter.frontage): the geometry the plan promises, checked on the
meshes and actors of sampled worlds."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
import trimesh

from simgen.road import PARKING_WIDTH, RoadLayout
from simgen.sample import _footprint, sample_world
from simgen.scenery import (
    CLEAR_FOOTWAY,
    FRONT_YARD,
    GREEN_MARGIN,
    LAND_DEPTH,
    POST_PITCH,
    POST_W,
    RAIL_DEPTH,
    RAIL_TOP,
    SHRUB_BELT_HEIGHT,
    SHRUB_BELT_RADIUS,
    STALL_W,
    _outer,
    build_scenery,
    plan_frontage,
)
from simgen.spec import SceneSpec, SpecError, spec_from_dict


def _spec(frontage: dict, **clutter) -> SceneSpec:
    """A straight street with parked cars, pedestrians, side streets and the given lots."""
    return spec_from_dict({
        "name": "f", "road": {"type": "straight", "lanes_per_direction": 1, "length_behind": 60},
        "traffic": {"parking_occupancy": 0.5, "pedestrians_per_100m": 15, "car_park_occupancy": 1.0},
        "clutter": {"frontage": frontage, "side_streets_per_100m": 1.5, "trees_per_100m": 8,
                    **clutter}})


@pytest.fixture(scope="module")
def mixed():
    """A world with every kind of lot (seed and frame chosen so that all four occur)."""
    spec = _spec({"row": 1, "houses": 1, "open": 1, "car_park": 1})
    world = sample_world(spec, 3, 0)
    plan = plan_frontage(world.scenery)
    assert {lot.kind for lot in plan.lots} == {"row", "houses", "open", "car_park"}
    assert plan.mouths[-1] and plan.mouths[1] and plan.stalls
    return world, plan, RoadLayout(**world.scenery["road"])


def _sd_box(s0: float, s1: float, d0: float, d1: float) -> shapely.Polygon:
    """The rectangle [s0, s1] x [d0, d1] of road coordinates: world x, y on a straight road."""
    return shapely.box(s0, min(d0, d1), s1, max(d0, d1))


def _facades(world) -> list[np.ndarray]:
    """Each building's 8 corners (facade parts merge boxes of one colour)."""
    boxes = []
    for p in world.static:
        if p.material.name == "facade":
            v = np.asarray(p.mesh.vertices)
            assert len(v) % 8 == 0
            boxes += list(v.reshape(-1, 8, 3))
    return boxes


def test_no_actor_stands_in_a_building_hedge_fence_or_trunk(mixed):
    world, _, _ = mixed
    _, obstacles = build_scenery(world.scenery)
    solid = [o.polygon for o in obstacles if o.base == 0.0]  # buildings, boundaries, trunks
    facades = shapely.union_all([shapely.convex_hull(shapely.MultiPoint(b[:, :2]))
                                 for b in _facades(world)])
    for a in world.actors:
        fp = _footprint(a.pose, a.recipe["dims"][2], a.recipe["dims"][1], 0.0)
        assert not fp.intersects(facades), a.id
        assert not any(fp.intersects(p) for p in solid), a.id


def test_set_backs_are_honoured():
    """Houses stand at least a front yard behind the sidewalk, closed rows `building_setback`."""
    for frontage, setback, least in (({"houses": 1}, 0.0, FRONT_YARD[0]), ({"row": 1}, 2.5, 2.5)):
        world = sample_world(_spec(frontage, building_setback=setback), 1, 0)
        road = RoadLayout(**world.scenery["road"])
        facades = _facades(world)
        assert len(facades) > 10
        for b in facades:
            y = b[:, 1]
            side = 1 if y.mean() > 0 else -1
            behind = side * y - side * _outer(road, side)  # metres behind the sidewalk's back
            assert behind.min() >= least - 1e-9, (frontage, behind.min())


def test_car_park_cars_stand_in_their_stalls_on_the_paving(mixed):
    world, plan, road = mixed
    paving = shapely.union_all([_sd_box(lot.s0, lot.s1, _outer(road, lot.side),
                                        _outer(road, lot.side) + lot.side * lot.depth)
                                for lot in plan.lots if lot.kind == "car_park"])
    centres = np.array([st[:2, 3] for st in plan.stalls])
    in_park = [a for a in world.actors if shapely.Point(a.pose[:2, 3]).within(paving)]
    assert len(in_park) > 20
    for a in in_park:
        assert a.cls in ("Car", "Van") and not np.any(a.velocity)
        assert a.pose[2, 3] == road.curb_height  # on the paving, which lies at sidewalk height
        assert np.min(np.linalg.norm(centres - a.pose[:2, 3], axis=1)) < 1e-9  # a stall's centre
        assert abs(a.pose[1, 0]) > 0.99  # across the road, nose in or out
        fp = _footprint(a.pose, a.recipe["dims"][2], a.recipe["dims"][1], 0.0)
        assert fp.within(paving.buffer(0.1))
    # stalls are EAR's 2.5 m apart along the row
    row = np.sort(centres[np.abs(centres[:, 1] - centres[0, 1]) < 1e-6, 0])
    assert np.allclose(np.diff(row)[np.diff(row) < 3.0], STALL_W)


def test_side_streets_are_open_and_clear(mixed):
    world, plan, road = mixed
    _, obstacles = build_scenery(world.scenery)
    for side, mouths in plan.mouths.items():
        curb = road.right_curb if side < 0 else road.left_curb
        far = _outer(road, side) + side * LAND_DEPTH
        for a, b in mouths:
            band = _sd_box(a, b, curb, far)
            assert not any(o.polygon.intersects(band) for o in obstacles)
            for actor in world.actors:
                if actor.cls == "Pedestrian" or not np.any(actor.velocity):  # walkers, parked cars
                    fp = _footprint(actor.pose, actor.recipe["dims"][2], actor.recipe["dims"][1], 0.0)
                    assert not fp.intersects(band), (actor.id, actor.cls)


def test_frontage_is_rebuilt_exactly_from_its_json_parameters(mixed):
    world, _, _ = mixed
    static, _ = build_scenery(json.loads(json.dumps(world.scenery)))
    for p, q in zip(world.static, static, strict=True):
        assert p.material == q.material
        assert np.array_equal(p.mesh.vertices, q.mesh.vertices)
        assert np.array_equal(p.mesh.faces, q.mesh.faces)


def test_no_frontage_keeps_the_first_street_model():
    world = sample_world(spec_from_dict({"name": "x"}), 2, 0)
    assert world.scenery["clutter"]["frontage"] == {} and plan_frontage(world.scenery) is None
    old = dict(world.scenery, clutter={k: v for k, v in world.scenery["clutter"].items()
                                       if k not in ("frontage", "side_streets_per_100m")})
    for p, q in zip(world.static, build_scenery(old)[0], strict=True):
        assert np.array_equal(p.mesh.vertices, q.mesh.vertices)
    # the frontage needs buildings in the city: elsewhere it is ignored
    grass = sample_world(_spec({"houses": 1}, environment="grass"), 2, 0)
    assert plan_frontage(grass.scenery) is None


@pytest.mark.parametrize("frontage,words", [({"yards": 1.0}, "unknown lot kind"),
                                            ({"row": -1.0}, "negative"),
                                            ({"row": 0.0}, "sum to zero")])
def test_frontage_spec_errors_name_the_key(frontage, words):
    with pytest.raises(SpecError, match=rf"clutter\.frontage.*{words}"):
        spec_from_dict({"name": "x", "clutter": {"frontage": frontage}})


def test_crash_barriers_stand_along_open_land_at_their_height():
    """clutter.guardrail 1: every open lot gets a W-beam rail whose top stands RAIL_TOP above the
    sidewalk, 0.15-0.23 m behind it, on posts POST_PITCH apart; at 0 no metal stands there."""
    rails = []
    for share in (1.0, 0.0):
        world = sample_world(_spec({"open": 1}, guardrail=share, pole_spacing=0), 2, 0)
        road = RoadLayout(**world.scenery["road"])
        ch = road.curb_height
        metal = np.concatenate([np.asarray(p.mesh.vertices) for p in world.static
                                if p.material.name == "pole"] or [np.zeros((0, 3))])
        outer = _outer(road, 1)
        near = metal[(metal[:, 1] > outer + 0.1) & (metal[:, 1] < outer + 0.4)]  # the left side
        rails.append(near)
    near, none = rails
    assert len(none) == 0
    assert near[:, 2].max() == pytest.approx(road.curb_height + RAIL_TOP, abs=1e-9)
    face = near[near[:, 1] < outer + 0.15 + 1e-9]
    assert len(face) and np.allclose(face[:, 1], outer + 0.15)  # the rail's face towards the road
    assert face[:, 2].min() == pytest.approx(ch + RAIL_TOP - RAIL_DEPTH, abs=1e-9)
    feet = near[np.isclose(near[:, 2], ch)]  # only the posts reach down to the ground
    xs = np.unique(np.round(feet[:, 0], 6))  # each post's two ends along the road
    assert len(xs) > 20 and len(xs) % 2 == 0
    np.testing.assert_allclose(xs[1::2] - xs[::2], POST_W, atol=1e-6)
    gaps = np.diff((xs[::2] + xs[1::2]) / 2)
    # POST_PITCH apart along each lot (a new lot starts its own row of posts)
    assert np.mean(np.isclose(gaps, POST_PITCH, atol=1e-6)) > 0.9, gaps[~np.isclose(gaps, POST_PITCH)]


def test_green_lots_hold_a_closed_belt_of_shrubs_behind_a_grass_margin():
    """A level beam 1 m above the sidewalk, sent from its back edge straight away from the road
    every 0.5 m along a green lot, meets the belt's foliage no nearer than the least margin and no
    farther than the widest margin plus a shrub's reach; over the sidewalk and the margin no
    foliage hangs lower than the footway's clearance (the small trees' crowns may reach over)."""
    world = sample_world(_spec({"green": 1}, side_streets_per_100m=0.0, pole_spacing=0, trees_per_100m=0),
                         2, 0)
    road = RoadLayout(**world.scenery["road"])
    plan = plan_frontage(world.scenery)
    assert {lot.kind for lot in plan.lots} == {"green"}
    foliage = trimesh.util.concatenate([p.mesh for p in world.static if p.material.name == "foliage"])
    hits, rays = [], 0
    for lot in plan.lots:
        s = np.arange(max(lot.s0, road.s_min) + 3.0, min(lot.s1, road.s_max) - 3.0, 0.5)
        outer = _outer(road, lot.side)
        origins = np.c_[s, np.full(len(s), outer), np.full(len(s), road.curb_height + 1.0)]
        directions = np.tile([0.0, float(lot.side), 0.0], (len(s), 1))
        loc, idx, _ = foliage.ray.intersects_location(origins, directions, multiple_hits=True)
        rays += len(s)
        for k in range(len(s)):
            d = np.abs(loc[idx == k, 1] - outer)
            hits.append(d.min() if len(d) else np.inf)
        v = np.asarray(foliage.vertices)
        low = ((v[:, 0] > lot.s0) & (v[:, 0] < lot.s1) & (np.sign(v[:, 1]) == lot.side)
               & (v[:, 2] < road.curb_height + CLEAR_FOOTWAY))
        assert np.all(lot.side * (v[low, 1] - outer) >= GREEN_MARGIN[0] - 1e-9)
    hits = np.array(hits)
    assert rays > 300
    assert np.mean(hits <= GREEN_MARGIN[1] + 2 * SHRUB_BELT_RADIUS[1]) > 0.95, np.mean(np.isfinite(hits))
    assert hits.min() >= GREEN_MARGIN[0] - 1e-9
    # the shrubs reach down to the lawn (at the sidewalk's height) and up to at most their height
    z = np.asarray(foliage.vertices)[:, 2] - road.curb_height
    assert z.min() > -1e-9 and np.sum(z < 1e-9) > 100
    tops = np.asarray([m.vertices[:, 2].max() for m in foliage.split(only_watertight=False)])
    assert np.sum(tops - road.curb_height <= SHRUB_BELT_HEIGHT[1] + 1e-9) > 100
    # and the belts are rebuilt exactly from the scenery's JSON parameters (meta/)
    static, _ = build_scenery(json.loads(json.dumps(world.scenery)))
    for p, q in zip(world.static, static, strict=True):
        assert np.array_equal(p.mesh.vertices, q.mesh.vertices)


@pytest.mark.parametrize("sides", ["right", "left", "none"])
def test_parking_sides_put_a_strip_and_parked_cars_only_where_named(sides):
    """road.parking_sides: the strip (PARKING_WIDTH) lines only the named curbs, the other curbs
    stand at their lane's edge, and every parked car stands in a strip."""
    world = sample_world(spec_from_dict({
        "name": "p", "road": {"type": "straight", "lanes_per_direction": 1, "parking_sides": sides},
        "traffic": {"parking_occupancy": 0.5, "vehicles_per_100m": 0.0}}), 4, 0)
    road = RoadLayout(**world.scenery["road"])
    right, left = sides == "right", sides == "left"
    assert road.right_curb == pytest.approx(road.right_lane_edge - PARKING_WIDTH * right, abs=1e-12)
    assert road.left_curb == pytest.approx(road.left_lane_edge + PARKING_WIDTH * left, abs=1e-12)
    parked = [a.pose[1, 3] for a in world.actors if a.cls in ("Car", "Van")]
    if sides == "none":
        assert not parked
        return
    assert len(parked) > 10
    lo, hi = (road.right_curb, road.right_lane_edge) if right else (road.left_lane_edge, road.left_curb)
    assert all(lo < y < hi for y in parked)


def test_both_parking_strips_keep_the_road_dict_of_before():
    world = sample_world(spec_from_dict({"name": "b", "traffic": {"parking_occupancy": 0.2}}), 1, 0)
    assert "parking_sides" not in world.scenery["road"] and world.scenery["road"]["parking"]
    road = RoadLayout(**world.scenery["road"])
    assert road.right_curb == road.right_lane_edge - PARKING_WIDTH
    assert road.left_curb == road.left_lane_edge + PARKING_WIDTH


def test_front_boundaries_line_the_sidewalk_of_every_fronted_lot_and_change_nothing_else():
    """clutter.front_boundary 1: a level ray 0.4 m above the sidewalk (lower than the lowest
    wall), sent away from the road from just inside the sidewalk's back edge, meets a hedge,
    fence or wall exactly 0.2 m behind that edge all along every row, open and green lot; the
    world is the one without them plus those boundaries (their own random stream), and it is
    rebuilt exactly from its JSON parameters. A row standing less than ROW_GARDEN behind the
    sidewalk gets none."""
    kw = dict(side_streets_per_100m=0.0, pole_spacing=0, trees_per_100m=0, furniture=0.0)
    lots = {"row": 1, "open": 1, "green": 1}
    bare = sample_world(_spec(lots, building_setback=3.0, **kw), 5, 0)
    fenced = sample_world(_spec(lots, building_setback=3.0, front_boundary=1.0, **kw), 5, 0)
    road = RoadLayout(**fenced.scenery["road"])
    plan = plan_frontage(fenced.scenery)
    assert {lot.kind for lot in plan.lots} == set(lots)

    def by_material(world):  # the scenery merges each material's meshes into one part
        return {p.material.name: np.asarray(p.mesh.vertices) for p in world.static}

    was, now = by_material(bare), by_material(fenced)
    assert set(was) <= set(now) <= set(was) | {"fence"}
    for name, v in was.items():
        if name not in ("foliage", "fence", "curb"):
            assert np.array_equal(v, now[name]), name
        else:  # every vertex of before is still there, and more stand beside them
            rows = {r.tobytes() for r in now[name]}
            assert all(r.tobytes() in rows for r in v), name
    assert sum(len(now[k]) for k in now) > sum(len(was[k]) for k in was)
    scene = trimesh.util.concatenate([p.mesh for p in fenced.static])
    for lot in plan.lots:
        s = np.arange(max(lot.s0, road.s_min) + 1.0, min(lot.s1, road.s_max) - 1.0, 0.5)
        outer = _outer(road, lot.side)
        origins = np.c_[s, np.full(len(s), outer - lot.side * 0.05), np.full(len(s), road.curb_height + 0.4)]
        loc, idx, _ = scene.ray.intersects_location(origins, np.tile([0.0, float(lot.side), 0.0], (len(s), 1)),
                                                    multiple_hits=False)
        assert len(s) > 10 and sorted(idx) == list(range(len(s)))
        np.testing.assert_allclose(np.abs(loc[:, 1] - outer), 0.2, atol=1e-6)
    static, _ = build_scenery(json.loads(json.dumps(fenced.scenery)))
    assert [p.mesh.vertices.tobytes() for p in static] == [p.mesh.vertices.tobytes() for p in fenced.static]
    row_asked = sample_world(_spec({"row": 1}, building_setback=1.0, front_boundary=1.0, **kw), 5, 0)
    row_bare = sample_world(_spec({"row": 1}, building_setback=1.0, **kw), 5, 0)
    asked, bare_row = by_material(row_asked), by_material(row_bare)
    assert asked.keys() == bare_row.keys()
    assert all(np.array_equal(v, bare_row[k]) for k, v in asked.items())
