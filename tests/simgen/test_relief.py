"""Roads that rise and fall and are crowned across: the geometry, hand-computed, and a world laid
onto it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simgen.relief import MAX_EDGE, drape_mesh
from simgen.road import RoadLayout, VerticalProfile
from simgen.sample import sample_world
from simgen.spec import load_spec, spec_from_dict

ROOT = Path(__file__).resolve().parents[2]


def test_profile_heights_and_grades_by_hand():
    # Ahead: level for 10 m, then -5 % reached over L = K x 5 = 50 m; behind: +3 % over 30 m.
    p = VerticalProfile(grade_ahead=-0.05, grade_behind=0.03, k=10.0, start=10.0)
    z, g = p.height_and_grade([0.0, 10.0, 35.0, 60.0, 70.0, -25.0, -40.0, -50.0])
    np.testing.assert_allclose(z, [0.0, 0.0, -0.05 * 25**2 / 100, -1.25, -1.75,
                                   0.03 * 15**2 / 60, 0.45, 0.75], atol=1e-12)
    # Going backwards the road rises at 3 %: dz/ds = -0.03 once the curve behind is done.
    np.testing.assert_allclose(g, [0.0, 0.0, -0.025, -0.05, -0.05, -0.015, -0.03, -0.03], atol=1e-12)


def test_grade_is_the_derivative_of_height():
    p = VerticalProfile(0.04, -0.06, 15.0, 5.0)
    s = np.linspace(-100.0, 150.0, 2001)
    z, g = p.height_and_grade(s)
    np.testing.assert_allclose(np.gradient(z, s)[1:-1], g[1:-1], atol=2e-4)


def _curved(profile=None, crown=0.0, curvature=0.004):
    return RoadLayout(curvature, 2, 3.5, 0, 3.0, 0.15, True, -60.0, 160.0, profile=profile,
                      crown=crown)


def test_crown_heights_by_hand():
    # 2 lanes of 3.5 m each way, ego in the right lane, parking strips of 2.3 m: the divider at
    # d = -1.75 + 7 = 5.25, the far curb at 5.25 + 7 + 2.3 = 14.55. At 2 % each side of the crown
    # the far side falls at 4 % in the ego's frame; the ego's side and beyond the curbs are level.
    for k in (0.0, 0.004, -0.006):
        road = _curved(crown=0.02, curvature=k)
        d = np.array([-8.0, -4.05, 0.0, 5.25, 10.0, 14.55, 20.0])
        for s in (-40.0, 0.0, 75.0):
            x, y = road.xy(np.full(len(d), s), d).T
            np.testing.assert_allclose(road.d_of(x, y), d, atol=1e-9)
            np.testing.assert_allclose(road.height(x, y),
                                       [0, 0, 0, 0, -0.04 * 4.75, -0.04 * 9.3, -0.04 * 9.3],
                                       atol=1e-9)


def test_arc_length_of_a_point_on_a_curved_road():
    road = _curved()
    s = np.array([-50.0, 0.0, 33.0, 120.0])
    for d in (-9.0, 0.0, 12.0):
        np.testing.assert_allclose(road.s_of(*road.xy(s, d).T), s, atol=1e-9)


@pytest.mark.parametrize("crown", [0.0, 0.025])
@pytest.mark.parametrize("curvature", [0.0, 0.004, -0.005])
def test_surface_normal_matches_the_height_field(crown, curvature):
    road = _curved(VerticalProfile(-0.05, 0.02, 12.0, 8.0), crown, curvature)
    h = 1e-4
    for x, y in [(30.0, 2.0), (55.0, 9.0), (-30.0, -4.0), (20.0, 11.0)]:
        gx = (road.height(x + h, y) - road.height(x - h, y)) / (2 * h)
        gy = (road.height(x, y + h) - road.height(x, y - h)) / (2 * h)
        n = np.array([-gx, -gy, 1.0]) / np.linalg.norm([gx, gy, 1.0])
        np.testing.assert_allclose(road.surface_normal(x, y), n, atol=1e-7)


def test_a_road_level_where_the_plane_is_fitted_gives_the_flat_plane():
    road = RoadLayout(0.0, 2, 3.5, 0, 3.0, 0.15, False, -20.0, 160.0,
                      profile=VerticalProfile(0.05, -0.05, 20.0, 60.0))
    np.testing.assert_allclose(road.fitted_plane(0.0, 40.0), [0, 0, 1, 0], atol=1e-12)
    # On a constant 4 % grade (a curve of K = 1 m/%: 4 m long, from s = 0) the plane is the grade.
    steep = RoadLayout(0.0, 2, 3.5, 0, 3.0, 0.15, False, -20.0, 160.0,
                       profile=VerticalProfile(0.04, 0.0, 1.0, 0.0))
    a, b, c, _ = steep.fitted_plane(4.0, 40.0)
    assert -a / c == pytest.approx(0.04, abs=1e-12) and b == pytest.approx(0.0, abs=1e-12)


def test_draped_mesh_follows_the_road_and_keeps_walls_vertical():
    import trimesh

    road = RoadLayout(0.0, 2, 3.5, 0, 3.0, 0.15, False, -20.0, 160.0,
                      profile=VerticalProfile(-0.05, 0.0, 10.0, 0.0))
    wall = trimesh.creation.box(extents=(30.0, 0.2, 10.0))
    wall.apply_translation([40.0, 8.0, 5.0])
    out = drape_mesh(wall, road)
    v = np.asarray(out.vertices)
    e = v[out.edges_unique]
    assert np.hypot(*(e[:, 0, :2] - e[:, 1, :2]).T).max() <= MAX_EDGE + 1e-9
    # Each vertex rose by the road's height under it: heights above the road stay within 0-10 m,
    # the bottom on the road; the walls stay vertical (side faces keep horizontal normals).
    above = v[:, 2] - road.height(v[:, 0], v[:, 1])
    assert above.min() == pytest.approx(0.0, abs=1e-9) and above.max() == pytest.approx(10.0, abs=1e-9)
    nz = np.abs(out.face_normals[:, 2])
    assert np.all((nz < 1e-9) | (nz > 0.99)) and (nz < 1e-9).any() and (nz > 0.99).any()


def test_flat_specs_build_the_flat_world():
    spec = spec_from_dict({"name": "flat"})
    world = sample_world(spec, 0, 0)
    assert "profile" not in world.scenery["road"] and "crown" not in world.scenery["road"]
    assert all(np.asarray(p.mesh.vertices)[:, 2].min() >= -1e-9 for p in world.static)


def test_road_surface_under_a_graded_world_is_where_the_camera_sees_it():
    """The rendered depth of road pixels ahead meets the profile: the camera sees the draped mesh."""
    from simgen.render import render

    spec = load_spec(ROOT / "scenes/golden/street.yaml")
    d = spec.model_dump()
    d["road"].update(grade_ahead=-0.05, vertical_k=10.0, vertical_start=5.0)
    d["traffic"].update(vehicles_per_100m=0.0, parking_occupancy=0.0, pedestrians_per_100m=0.0,
                        cyclists_per_100m=0.0)
    world = sample_world(type(spec).model_validate(d), 0, 0)
    road = RoadLayout(**world.scenery["road"])
    out = render(world)
    calib = world.rig.calib
    world_from_rect = world.rig.reference_pose @ np.linalg.inv(calib.velo_to_rect)
    checked = 0
    for v in range(200, 260, 6):  # image rows from the horizon down, along the ego lane
        depth = float(out.depth[v, 560])
        if not 0 < depth < 80:
            continue
        p = calib.image_to_rect(np.array([[560.0, v]]), np.array([depth]))[0]
        x, y, z = (world_from_rect @ np.append(p, 1.0))[:3]
        if x > 12:
            assert z == pytest.approx(float(road.height(x, y)), abs=0.03)
            checked += 1
    assert checked >= 4


def test_the_camera_sees_the_far_side_of_a_crowned_road_fall_away():
    """Rendered depth of the oncoming half of the carriageway meets the crown's heights (down to
    0.2-0.4 m below the ego's lane plane): the camera sees the draped asphalt."""
    from simgen.render import render

    spec = load_spec(ROOT / "scenes/golden/street.yaml")
    d = spec.model_dump()
    d["road"].update(crown=0.025)
    d["traffic"].update(vehicles_per_100m=0.0, parking_occupancy=0.0, pedestrians_per_100m=0.0,
                        cyclists_per_100m=0.0)
    world = sample_world(type(spec).model_validate(d), 0, 0)
    road = RoadLayout(**world.scenery["road"])
    depth = render(world).depth
    calib = world.rig.calib
    world_from_rect = world.rig.reference_pose @ np.linalg.inv(calib.velo_to_rect)
    v, u = np.mgrid[185:375:3, 0:1242:6]
    z_cam = depth[v, u]
    ok = (z_cam > 0) & (z_cam < 80)
    p = calib.image_to_rect(np.c_[u[ok], v[ok]].astype(float), z_cam[ok])
    x, y, z = (np.c_[p, np.ones(len(p))] @ world_from_rect.T)[:, :3].T
    across = road.d_of(x, y)
    far = (across > road.divider + 0.3) & (across < road.left_curb - 0.3) & (x > 8) & (x < 50)
    assert far.sum() > 100
    np.testing.assert_allclose(z[far], road.height(x[far], y[far]), atol=0.03)
    assert road.height(x[far], y[far]).min() < -0.15


# (road, where the car stands, its climb at 10 m/s along +x): 25 m into a vertical curve to -6 %
# over 60 m the grade is -2.5 %, so the car pitches and falls 0.25 m/s; on the far side of a 2 %
# crown (4 % in the ego's frame) it rolls and stays level.
_TILTS = {
    "grade": (RoadLayout(0.0, 2, 3.5, 0, 3.0, 0.15, False, -20.0, 160.0,
                         profile=VerticalProfile(-0.06, 0.0, 10.0, 0.0)), (25.0, 1.5), -0.25),
    "crown": (RoadLayout(0.0, 2, 3.5, 0, 3.0, 0.15, False, -20.0, 160.0, crown=0.02),
              (25.0, 8.5), 0.0),
}


@pytest.mark.parametrize("tilt", sorted(_TILTS))
def test_a_tilted_car_is_labelled_by_its_upright_box_on_the_road(tilt):
    """KITTI's label holds a yaw only: the tilted car's label is the upright box of its size about
    its bottom centre on the road, and the 2D box is that box's projection, as in KITTI."""
    from kitti.boxes import project_boxes
    from simgen.labels import derive
    from simgen.meshes import build_actor_parts
    from simgen.relief import drape_actor
    from simgen.rigs import onboard_rig
    from simgen.spec import LabelRules
    from simgen.world import Actor, Light, Weather, World

    road, (x0, y0), climb = _TILTS[tilt]
    recipe = {"kind": "car", "dims": [1.53, 1.63, 3.88], "color": [0.5, 0.5, 0.5], "seed": 3}
    T = np.eye(4)
    T[:3, 3] = [x0, y0, 0.0]
    car = Actor(1, "Car", build_actor_parts(recipe), T, velocity=np.array([10.0, 0.0, 0.0]), recipe=recipe)
    drape_actor(car, road)
    assert car.velocity[2] == pytest.approx(climb, abs=1e-12)  # moves along the road
    np.testing.assert_allclose(car.pose[:3, 2], road.surface_normal(x0, y0), atol=1e-12)
    rig = onboard_rig()
    world = World(actors=[car], static=[], weather=Weather(), lidar_pose=rig.reference_pose.copy(),
                  rig=rig, light=Light())
    from simgen.render import render

    rows, _ = derive(world, render(world).instance,
                          LabelRules(min_height_px=0, max_distance=1000, min_visible_share=0.0))
    (row,) = rows
    h, w, l = row.box7[3:6]
    assert (h, w, l) == pytest.approx((1.53, 1.63, 3.88), abs=1e-9)
    assert row.box7[6] == pytest.approx(-np.pi / 2, abs=1e-9)  # heading +x, as on a flat road
    # The bottom centre (rect coords) back in the world lies on the road under it.
    world_from_rect = rig.reference_pose @ np.linalg.inv(rig.calib.velo_to_rect)
    x, y, z = (world_from_rect @ np.append(row.box7[:3], 1.0))[:3]
    assert z == pytest.approx(float(road.height(x, y)), abs=1e-9)
    size = (rig.width, rig.height)
    # KITTI's 2D box: the box upright in the LiDAR's frame; from the label alone to 0.05 px (the
    # heading's climb leaves the LiDAR's and the camera's horizontal planes at slightly different
    # yaws, a second-order difference)
    np.testing.assert_allclose(row.bbox, project_boxes(row.box7[None], rig.calib, size, upright="lidar")[0],
                               atol=0.05)


def test_a_draped_wall_wears_one_continuous_facade():
    """Every vertex of a draped building gets one texture coordinate, whichever of its triangles
    is drawn: windows run on across the split wall and storeys stay level above its lowest point
    (per-triangle extents cut the windows apart along the diagonals)."""
    import trimesh

    from simgen.texture_layout import facade_uv
    from simgen.textures import BAY_M

    road = RoadLayout(0.0, 2, 3.5, 0, 3.0, 0.15, False, -20.0, 160.0,
                      profile=VerticalProfile(-0.05, 0.0, 10.0, 0.0))
    house = trimesh.creation.box(extents=(29.0, 12.0, 10.0))
    house.apply_translation([40.0, 14.0, 5.0])
    out = drape_mesh(house, road)
    walls = np.abs(out.face_normals[:, 2]) < 0.7
    faces = np.asarray(out.faces)[walls]
    tris = np.asarray(out.vertices)[faces]
    tile = (6.0, 3.2)
    uv = facade_uv(tris, out.face_normals[walls], tile, 0.5)
    assert len(faces) > 8  # the long walls were split
    for vertex in np.unique(faces):
        at = faces == vertex
        for n in np.unique(np.round(out.face_normals[walls][at.any(axis=1)], 6), axis=0):
            same = at & np.all(np.isclose(out.face_normals[walls], n, atol=1e-6), axis=1)[:, None]
            assert np.ptp(uv[same], axis=0).max() < 1e-9  # one (u, v) per vertex and wall
    # The 29 m wall carries round(29 / BAY_M) whole bays: u spans that many bay widths.
    front = np.isclose(out.face_normals[walls][:, 1], -1.0)
    span = np.ptp(uv[front][..., 0]) * tile[0]
    assert span == pytest.approx(round(29.0 / BAY_M) * BAY_M)
    lowest = tris[front][..., 2].min()
    assert uv[front][..., 1].min() == pytest.approx(0.0, abs=1e-12)
    assert np.allclose(uv[front][..., 1], (tris[front][..., 2] - lowest) / tile[1])


def test_subdivision_is_trimeshs_to_the_bit():
    """The compiled subdivision gives trimesh.remesh.subdivide_to_size's vertices and faces."""
    import trimesh

    from simgen.relief import _subdivide

    rng = np.random.default_rng(0)
    for _ in range(10):
        box = trimesh.creation.box(extents=rng.uniform(1.0, 40.0, 3))
        box.apply_translation(rng.uniform(-50.0, 50.0, 3))
        v, f = np.asarray(box.vertices), np.asarray(box.faces, dtype=np.int64)
        ref_v, ref_f = trimesh.remesh.subdivide_to_size(v, f, MAX_EDGE)
        new_v, new_f = _subdivide(v.copy(), f, MAX_EDGE)
        assert np.array_equal(new_v, ref_v) and np.array_equal(new_f, ref_f)


@pytest.mark.parametrize("curvature", [0.0, 0.004])
def test_one_point_lies_where_the_arrays_put_it(curvature):
    """xy() of single points (the scalar path) gives the bits of the same points in arrays."""
    road = RoadLayout(curvature=curvature, lanes=1, lane_width=3.0, ego_lane=0, sidewalk_width=2.0,
                      curb_height=0.15, parking=False, s_min=-100.0, s_max=100.0)
    s, d = np.random.default_rng(1).uniform(-150.0, 150.0, (2, 50))
    points = np.array([road.xy(a, b) for a, b in zip(s, d)])
    assert points.tobytes() == road.xy(s, d).tobytes()
