"""Procedural and user meshes: closed parts, exact extents, KITTI-like size statistics."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from simgen.meshes import (
    BODY_SHARE,
    HATCH_ONLY_LENGTH,
    RIM_SHARE,
    SIZE_STATS,
    SUV_HEIGHT,
    _car_layout,
    build_actor_parts,
    sample_recipe,
)
from simgen.usermesh import user_recipe


@pytest.mark.parametrize("cls", ["Car", "Van", "Truck", "Bus", "Pedestrian", "Cyclist"])
def test_every_part_is_closed_and_convex_and_the_extent_is_the_drawn_size(cls):
    rng = np.random.default_rng(1)
    for _ in range(5):
        recipe = sample_recipe(cls, rng)
        parts = build_actor_parts(recipe)
        assert all(p.mesh.is_watertight and p.mesh.is_volume for p in parts)
        for p in parts:  # convex: the part fills its own hull (labels.py relies on it)
            assert p.mesh.volume == pytest.approx(ConvexHull(p.mesh.vertices).volume, rel=1e-9)
        v = np.concatenate([p.mesh.vertices for p in parts])
        h, w, l = recipe["dims"]
        np.testing.assert_allclose(v.min(axis=0), [-l / 2, -w / 2, 0.0], atol=1e-12)
        np.testing.assert_allclose(v.max(axis=0), [l / 2, w / 2, h], atol=1e-12)
        # Rebuilding from the recipe gives the same vertices, bit for bit.
        again = build_actor_parts(recipe)
        assert all(np.array_equal(a.mesh.vertices, b.mesh.vertices) for a, b in zip(parts, again))


def test_vehicle_parts_have_distinct_lidar_materials():
    parts = build_actor_parts(sample_recipe("Car", np.random.default_rng(0)))
    refl = {p.material.name: p.material.reflectivity for p in parts}
    assert {"paint", "glass", "tyre", "plate", "headlight", "taillight", "trim", "rim"} <= set(refl)
    assert refl["plate"] > refl["paint"] > refl["glass"] > refl["tyre"]
    assert refl["rim"] > refl["trim"] > refl["tyre"]  # aluminium-grey rims, carbon-black plastics


def _tyres_and_rims(parts):
    return ([p.mesh.bounds for p in parts if p.material.name == "tyre"],
            [p.mesh.bounds for p in parts if p.material.name == "rim"])


@pytest.mark.parametrize("cls", ["Car", "Van", "Truck", "Bus"])
def test_wheels_are_round_and_carry_a_rim_on_the_outer_face(cls):
    rng = np.random.default_rng(4)
    for _ in range(10):
        recipe = sample_recipe(cls, rng)
        tyres, rims = _tyres_and_rims(build_actor_parts(recipe))
        assert len(tyres) == len(rims) >= 4
        for lo, hi in tyres:
            d = hi - lo
            assert d[0] == pytest.approx(d[2], rel=0.03)  # round in metres, whatever l and h
            centre = (lo + hi) / 2
            rim = [b for b in rims if np.allclose((b[0] + b[1])[[0, 2]] / 2, centre[[0, 2]], atol=1e-9)
                   and np.sign(b[0][1] + b[1][1]) == np.sign(centre[1])]
            assert len(rim) == 1
            (rlo, rhi), left = rim[0], centre[1] > 0
            assert rhi[2] - rlo[2] == pytest.approx(RIM_SHARE * d[2], rel=1e-9)
            # standing on the tyre's outer face, outwards, never beyond the box
            rim_inner, tyre_outer = (rlo[1], hi[1]) if left else (rhi[1], lo[1])
            assert rim_inner == pytest.approx(tyre_outer, abs=1e-9)
            assert max(abs(rlo[1]), abs(rhi[1])) <= recipe["dims"][1] / 2


def test_mirrors_span_the_box_and_the_body_is_narrower():
    rng = np.random.default_rng(5)
    for _ in range(20):
        recipe = sample_recipe("Car", rng)
        _, w, _ = recipe["dims"]
        parts = build_actor_parts(recipe)
        body = parts[0].mesh.bounds  # the lower body comes first
        assert body[1][1] == pytest.approx(BODY_SHARE * w / 2, rel=1e-3)
        widest = [p for p in parts if np.isclose(p.mesh.bounds[1][1], w / 2, atol=1e-12)]
        assert widest and all(p.mesh.bounds[0][0] > 0 for p in widest)  # mirrors, ahead of the centre


def test_car_styles_follow_height_and_length():
    """Tall cars get the SUV/MPV profile, short ones are hatchbacks; every style occurs in KITTI's
    size distribution, and the roof of a sedan ends well before the tail, an estate's near it."""
    rng = np.random.default_rng(6)
    seen = set()
    for _ in range(300):
        recipe = sample_recipe("Car", rng)
        h, _, l = recipe["dims"]
        k = _car_layout(np.random.default_rng(recipe["seed"]), recipe["dims"])
        seen.add(k.style)
        assert (k.style == "suv") == (h >= SUV_HEIGHT)
        if h < SUV_HEIGHT and l < HATCH_ONLY_LENGTH:
            assert k.style == "hatchback"
        roof_end = (k.roof[1] + l / 2) / l
        assert roof_end > 0.25 if k.style == "sedan" else roof_end < 0.15
    assert seen == {"sedan", "hatchback", "estate", "suv"}


def test_a_car_stays_within_twice_the_old_triangle_budget():
    """The previous car had 324 triangles; the renderer and the LiDAR pay for every one. Twice
    that, and on top the two bumpers' black valances and the rear lamps' pieces round the corners
    (a box each: six)."""
    rng = np.random.default_rng(7)
    counts = [sum(len(p.mesh.faces) for p in build_actor_parts(sample_recipe("Car", rng))) for _ in range(50)]
    assert max(counts) <= 2 * 324 + 6 * 12


@pytest.mark.parametrize("cls", ["Car", "Pedestrian", "Cyclist"])
def test_size_distribution_is_close_to_kitti(cls):
    rng = np.random.default_rng(2)
    dims = np.array([sample_recipe(cls, rng)["dims"] for _ in range(400)])
    mean, sd = (np.array(v) for v in SIZE_STATS[cls])
    np.testing.assert_allclose(dims.mean(axis=0), mean, atol=0.25 * sd.max())
    assert np.all(dims.std(axis=0) < 1.2 * sd) and np.all(dims.std(axis=0) > 0.5 * sd)


@pytest.mark.parametrize("cls, white, black, blue", [("Car", 0.016, 0.278, 0.163), ("Van", 0.24, 0.20, 0.09)])
def test_paint_shares(cls, white, black, blue):
    """Cars wear the KBA's 2006 passenger-car mix (white 1.6 %, black 27.8 %, blue 16.3 %), vans
    the palette's other shares; each palette colour is told apart after its +-15 % brightness draw
    (white's channels >= 0.72, black's <= 0.035, blue the only one with blue over twice green)."""
    rng = np.random.default_rng(3)
    n = 4000
    c = np.array([sample_recipe(cls, rng)["color"] for _ in range(n)])
    for share, hit in ((white, c.min(axis=1) >= 0.72), (black, c.max(axis=1) <= 0.035),
                       (blue, c[:, 2] > 2 * c[:, 1])):
        assert abs(hit.mean() - share) <= 4 * np.sqrt(share * (1 - share) / n), (hit.mean(), share)


def test_user_mesh_is_scaled_to_its_target_size(tmp_path):
    path = tmp_path / "blob.ply"
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    m.apply_scale([2.0, 1.0, 0.5])
    m.export(path)
    recipe = user_recipe(str(path), "Car", (1.5, 1.8, 4.2), "z", (0.2, 0.3, 0.4), 0.5)
    (part,) = build_actor_parts(recipe)
    np.testing.assert_allclose(part.mesh.bounds, [[-2.1, -0.9, 0.0], [2.1, 0.9, 1.5]], atol=1e-12)
    own = build_actor_parts(user_recipe(str(path), "Car", None, "z", (0.2, 0.3, 0.4), 0.5))[0]
    np.testing.assert_allclose(own.mesh.bounds[1] - own.mesh.bounds[0], [4.0, 2.0, 1.0], atol=1e-12)
    assert part.material.reflectivity == 0.5


def test_the_rear_window_has_body_coloured_pillars_on_its_plane():
    """Seen from behind, a car's glass is framed by two paint slabs: each lies on the rear glass
    face (within its 5 mm inside and 12 mm proud) and covers REAR_PILLAR of the face's width
    from its side edge."""
    from simgen.meshes import REAR_PILLAR

    rng = np.random.default_rng(3)
    for _ in range(10):
        recipe = sample_recipe("Car", rng)
        parts = build_actor_parts(recipe)
        glass = next(p.mesh for p in parts if p.material.name == "glass")
        back = glass.face_normals[:, 0] < -0.3  # the rear glass face: it looks backwards
        n = glass.face_normals[back][0]
        plane = glass.vertices[glass.faces[back][0][0]] @ n
        foot = glass.vertices[glass.faces[back]].reshape(-1, 3)
        foot = foot[np.isclose(foot[:, 2], foot[:, 2].min())]
        width = np.ptp(foot[:, 1])
        slabs = [p.mesh for p in parts if p.material.name == "paint"
                 and np.all(np.abs(p.mesh.vertices @ n - plane) <= 0.012 + 1e-9)]
        assert len(slabs) == 2
        for s in slabs:
            low = s.vertices[np.isclose(s.vertices[:, 2], s.vertices[:, 2].min(), atol=0.02)]
            assert np.ptp(low[:, 1]) == pytest.approx(REAR_PILLAR * width, rel=0.02)
            assert np.abs(low[:, 1]).max() == pytest.approx(width / 2, abs=0.01)


def _seen(parts, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """The material name each ray meets first ("" for none)."""
    from simgen.facets import shared
    from simgen.embree import embree_scene

    names = np.repeat([p.material.name for p in parts] + [""], [len(p.mesh.faces) for p in parts] + [1])
    return names[embree_scene(*shared(parts)).run(origins.astype(np.float32), dirs.astype(np.float32))]


def _seen_along_x(parts, origins: np.ndarray, sgn: float) -> np.ndarray:
    """The material name each ray from `origins` along -sgn x meets first ("" for none)."""
    return _seen(parts, origins, np.tile([-sgn, 0.0, 0.0], (len(origins), 1)))


def _first_hits(parts, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(N, 3) the point each ray meets first (NaN for none), at Embree's own hit distance."""
    from simgen.facets import shared
    from simgen.embree import embree_scene

    res = embree_scene(*shared(parts)).run(origins.astype(np.float32), dirs.astype(np.float32), output=1)
    return np.where((res["primID"] >= 0)[:, None], origins + res["tfar"][:, None] * dirs, np.nan)


def test_the_rear_floor_rises_to_the_departure_plane_and_shows_the_tyres():
    """The floor rises from the rear axle to the back end, where it stands at the height of the
    plane tangent to the rear tyres at the drawn departure angle (DEPARTURE_DEG): no part but the
    wheels reaches below the plane, the rear valance's lower edge stands 3 cm above the floor's
    end, a LiDAR at KITTI's 1.73 m, 8 m behind the car, finds nothing on the car's last 0.25 m
    below that (as the real dev frames' scans show), and a camera at 1.65 m sees both
    rear tyres' contact with the road (where the plane rises above the sill)."""
    from simgen.meshes import DEPARTURE_DEG

    rng = np.random.default_rng(8)
    for _ in range(20):
        recipe = sample_recipe("Car", rng)
        h, _, l = recipe["dims"]
        k = _car_layout(np.random.default_rng(recipe["seed"]), recipe["dims"])
        lo, hi = DEPARTURE_DEG["suv" if k.style == "suv" else "car"]
        assert lo <= np.degrees(k.departure) <= hi
        slope, axle = np.tan(k.departure), k.axles[1]
        # The plane touches the tyre (the axle lies r from it, below the axle): at the back end
        # it stands r + d tan - r / cos up, d the overhang; the floor takes it or the sill.
        at_back = k.r + (axle - k.back) * slope - k.r / np.cos(k.departure)
        assert k.tail == pytest.approx(max(k.sill, at_back), abs=1e-12)
        if k.tail == k.sill:  # a short overhang: the plane stays under the sill, and so does the body
            continue
        parts = build_actor_parts(recipe)
        body = np.concatenate([p.mesh.vertices for p in parts if p.material.name not in ("tyre", "rim")])
        behind = body[body[:, 0] < axle - k.r * np.sin(k.departure)]  # behind the tangent line
        plane = at_back - (behind[:, 0] - k.back) * slope
        assert np.all(behind[:, 2] >= plane - 0.005)  # fit_parts rescales by a few millimetres
        rise = (k.tail - k.sill) / (axle - k.back)  # the floor: from the axle at the sill's height
        floor = np.minimum(k.sill + (axle - body[:, 0]) * rise, k.tail)
        assert np.all(body[body[:, 0] < axle, 2] >= floor[body[:, 0] < axle] - 0.005)
        assert body[body[:, 0] < -l / 2 + 0.1, 2].min() == pytest.approx(k.tail, abs=0.005)
        rear_trim = [p.mesh.bounds for p in parts
                     if p.material.name == "trim" and p.mesh.bounds[0][0] < -l / 2 + 0.01]
        assert min(b[0][2] for b in rear_trim) == pytest.approx(k.tail + 0.03, abs=0.005)
        z = np.arange(0.0, 1.0, 0.002)  # heights at the back end, centre line: a column of beams
        lidar = np.array([-l / 2 - 8.0, 0.0, 1.73])
        d = np.c_[np.full_like(z, 8.0), np.zeros_like(z), z - 1.73]
        hits = _first_hits(parts, np.tile(lidar, (len(z), 1)), d / np.linalg.norm(d, axis=1, keepdims=True))
        last = hits[hits[:, 0] < -l / 2 + 0.25]
        if rise < (1.73 - k.tail) / 8.0:  # a floor rising less steeply than the beams descend
            assert len(last) and last[:, 2].min() >= k.tail - 0.005
        for side in (-1.0, 1.0):
            y = side * (k.body - 0.10)  # the tyre's middle
            target = np.array([axle + 0.05, y, 0.01])  # just behind the contact, 1 cm up
            eye = np.array([-l / 2 - 8.0, 0.0, 1.65])
            d = (target - eye) / np.linalg.norm(target - eye)
            assert _seen(parts, eye[None], d[None])[0] == "tyre"


def test_bumpers_show_the_body_colour_above_a_thin_black_valance():
    """A column of rays from behind (and one from in front), 0.3 m off the centre line (clear of
    the plate), read the car's end from the ground up: the black valance, VALANCE tall, with at
    most the body's bottom edge under it, and straight above it the bumper in the body's paint."""
    from simgen.meshes import VALANCE

    rng = np.random.default_rng(5)
    z = np.arange(0.0, 1.0, 0.002) + 0.001
    for _ in range(10):
        recipe = sample_recipe("Car", rng)
        parts = build_actor_parts(recipe)
        l = recipe["dims"][2]
        for sgn in (-1.0, 1.0):  # from behind, from in front
            origins = np.c_[np.full_like(z, sgn * (l / 2 + 1.0)), np.full_like(z, 0.3), z]
            seen = _seen_along_x(parts, origins, sgn)
            lowest = np.flatnonzero(seen == "trim")[0]
            # under it, at most the body's 4 cm bottom edge; behind, also the floor rising to it
            k = _car_layout(np.random.default_rng(recipe["seed"]), recipe["dims"])
            under = 0.0 if sgn > 0 else k.tail - k.sill
            assert np.sum(seen[:lowest] != "") <= 20 + under / 0.002
            black = np.flatnonzero(seen[lowest:] != "trim")[0]
            assert VALANCE[0] - 0.004 <= black * 0.002 <= VALANCE[1] + 0.004
            # the next 10 cm: a cover is at least 0.20 - 0.08 m tall, the grille overlaps its top 1 cm
            assert np.all(seen[lowest + black:lowest + black + 50] == "paint")


def test_a_van_shows_glass_from_behind_as_from_in_front():
    """Rays along the van's length at three-quarters of its height, across the middle half of its
    width, meet glass first from in front (the windscreen) and from behind (the rear glass,
    VAN_REAR_GLASS): the glass alone does not tell a van's front from its back."""
    from simgen.meshes import VAN_REAR_GLASS

    rng = np.random.default_rng(6)
    for _ in range(10):
        recipe = sample_recipe("Van", rng)
        parts = build_actor_parts(recipe)
        h, w, l = recipe["dims"]
        y = np.linspace(-w / 4, w / 4, 21)
        for sgn in (-1.0, 1.0):  # from behind, from in front
            z = (VAN_REAR_GLASS[0][1] + VAN_REAR_GLASS[1][0]) / 2 * h if sgn < 0 else 0.75 * h
            origins = np.c_[np.full_like(y, sgn * (l / 2 + 1.0)), y, np.full_like(y, z)]
            seen = _seen_along_x(parts, origins, sgn)
            assert np.all(seen == "glass"), (sgn, seen)


@pytest.mark.parametrize("cls", ["Pedestrian", "Cyclist"])
def test_a_person_shows_hair_from_behind_a_face_from_in_front_and_shoes_that_point_forward(cls):
    """Rays along the person's x axis through the head's centre meet hair from behind and skin
    from in front; each shoe reaches three times as far in front of its leg as behind it (FOOT:
    the ankle a quarter of the foot's length from the heel)."""
    rng = np.random.default_rng(8)
    for _ in range(10):
        parts = build_actor_parts(sample_recipe(cls, rng))
        head = next(p.mesh for p in parts if p.material.name == "skin").bounds.mean(axis=0)
        for sgn, first in ((-1.0, "hair"), (1.0, "skin")):  # from behind, from in front
            assert _seen_along_x(parts, (head + [sgn * 5.0, 0.0, 0.0])[None], sgn)[0] == first
        shoes = [p.mesh.bounds for p in parts if p.material.name == "shoes"]
        shins = [p.mesh for p in parts if p.material.name == "clothes"][:4:2]  # each leg's lower limb
        assert len(shoes) == 2
        shins = sorted(shins, key=lambda m: m.bounds[0][1])
        for (lo, hi), shin in zip(sorted(shoes, key=lambda b: b[0][1]), shins):
            ankle = shin.vertices[shin.vertices[:, 2] <= shin.vertices[:, 2].min() + 1e-9][:, 0].mean()
            assert hi[0] - ankle == pytest.approx(3 * (ankle - lo[0]), rel=1e-6)


def _numpy_hull(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """hull() in numpy: each face turned outward from the used points' mean, then renumbered."""
    faces = ConvexHull(pts).simplices
    used = np.zeros(len(pts), bool)
    used[faces] = True
    tri = pts[faces]
    (u0, u1, u2), (w0, w1, w2) = (tri[:, 1] - tri[:, 0]).T, (tri[:, 2] - tri[:, 0]).T
    normal = np.column_stack((u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0))
    inward = np.einsum("ij,ij->i", normal, tri.mean(axis=1) - pts[used].mean(axis=0)) < 0
    faces = np.where(inward[:, None], faces[:, ::-1], faces)
    return pts[used], (np.cumsum(used) - 1)[faces]


def test_hull_turns_every_face_as_numpy_does():
    """The compiled orientation gives numpy's faces to the bit, on prisms over profiles with
    collinear corners (qhull then triangulates coplanar facets) as on random points."""
    from simgen.meshes import hull

    rng = np.random.default_rng(0)
    for k in range(200):
        n = int(rng.integers(4, 20))
        if k % 2:
            profile = rng.standard_normal((n, 2))
            profile[: n // 2, 0] = profile[0, 0]
            pts = np.concatenate([np.c_[profile[:, 0], np.full(n, y), profile[:, 1]] for y in (-0.8, 0.8)])
        else:
            pts = rng.standard_normal((n, 3)) * 10.0 ** rng.uniform(-2, 2, 3)
        shape = hull(pts)
        ref_v, ref_f = _numpy_hull(pts)
        assert np.array_equal(shape.vertices, ref_v) and np.array_equal(shape.faces, ref_f)


def test_rear_lamps_wrap_round_the_corner_and_are_seen_from_80_degrees_outboard():
    """UN ECE R48 asks a car's rear position lamps to be seen from 80 deg outboard of straight
    behind and its stop lamps' inner edges to stand 600 mm apart: on each side the lamp's lens
    keeps that gap, reaches the body's side, and, seen along parallel rays 80 deg outboard (and
    straight behind), shows at least half the area its face on the back shows from straight
    behind (a lens on the back alone shows only its 12 mm proud edge there)."""
    from simgen.meshes import PLAN_CHAMFER, STOP_LAMP_GAP, TAIL_LAMP_INNER, TAIL_LAMP_Z

    rng = np.random.default_rng(9)
    step = 0.004
    for _ in range(10):
        recipe = sample_recipe("Car", rng)
        parts = build_actor_parts(recipe)
        k = _car_layout(np.random.default_rng(recipe["seed"]), recipe["dims"])
        lamps = np.concatenate([p.mesh.vertices for p in parts if p.material.name == "taillight"])
        zc = k.deck - sum(TAIL_LAMP_Z) / 2
        face = (min(TAIL_LAMP_INNER, k.body - STOP_LAMP_GAP / 2) - PLAN_CHAMFER) * (TAIL_LAMP_Z[0] - TAIL_LAMP_Z[1])
        for s in (-1.0, 1.0):
            side = lamps[lamps[:, 1] * s > 0]
            assert np.abs(side[:, 1]).min() >= STOP_LAMP_GAP / 2 - 1e-9  # inner edges 600 mm apart
            assert np.abs(side[:, 1]).max() >= k.body  # on round the corner
            for deg in (0.0, 80.0):
                a = np.radians(deg)
                d = np.array([np.cos(a), -s * np.sin(a), 0.0])  # towards the car
                u = np.array([np.sin(a), s * np.cos(a), 0.0])  # across the rays, level
                corner = np.array([k.back, s * k.body, zc])
                g = np.arange(-0.6, 0.6, step)
                du, dz = np.meshgrid(g, np.arange(-0.2, 0.2, step))
                origins = corner - 5.0 * d + du.reshape(-1, 1) * u + np.c_[0 * dz.ravel(), 0 * dz.ravel(),
                                                                           dz.ravel()]
                seen = _seen(parts, origins, np.tile(d, (len(origins), 1)))
                assert (seen == "taillight").sum() * step**2 >= 0.5 * face
