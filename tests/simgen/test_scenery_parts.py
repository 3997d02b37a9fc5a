"""The scenery's shared helpers that stand in for slower calls: each gives the bits of the call
it replaces."""

from __future__ import annotations

import numpy as np
import shapely

from simgen.scenery.parts import UNIT_SPHERES, _placed, discs, placed_many, plan_hull, uniform


def test_discs_are_geos_point_buffers():
    rng = np.random.default_rng(0)
    x, y, r = rng.uniform(-300.0, 300.0, 200), rng.uniform(-300.0, 300.0, 200), rng.uniform(0.1, 6.0, 200)
    y[:3] = -0.0
    for quad_segs in (4, 8):
        for disc, a, b, c in zip(discs(x, y, r, quad_segs), x, y, r):
            assert shapely.to_wkb(disc) == shapely.to_wkb(shapely.Point(a, b).buffer(c, quad_segs))


def test_plan_hull_is_the_multipoint_hull():
    rng = np.random.default_rng(1)
    for n in (4, 8, 24):
        xy = np.round(rng.uniform(-50.0, 50.0, (n, 2)), 1)  # rounded: repeats and collinear points
        expected = shapely.convex_hull(shapely.MultiPoint(xy))
        assert shapely.to_wkb(plan_hull(xy)) == shapely.to_wkb(expected)


def test_uniform_draws_are_the_generators():
    a, b = np.random.default_rng(2), np.random.default_rng(2)
    one_by_one = [a.uniform(-0.4, 2.5) for _ in range(100)]
    assert uniform((-0.4, 2.5), b.random(100)).tolist() == one_by_one


def test_placed_many_is_the_placed_shapes_merged():
    rng = np.random.default_rng(3)
    scale, at = rng.uniform(0.5, 3.0, (5, 3)), rng.uniform(-100.0, 100.0, (5, 3))
    unit = UNIT_SPHERES[0]
    many = placed_many(unit, scale, at)
    one_by_one = [_placed(unit, s, a) for s, a in zip(scale, at)]
    assert many.vertices.tobytes() == np.concatenate([m.vertices for m in one_by_one]).tobytes()
    offsets = np.arange(5) * len(unit.vertices)
    assert np.array_equal(many.faces, np.concatenate([m.faces + o for m, o in zip(one_by_one, offsets)]))
