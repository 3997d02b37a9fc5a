"""Labels against geometry, on small worlds built by hand: 2D boxes, occlusion, truncation,
angles, depth, the road plane."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from kitti.boxes import alpha_from_rotation_y, box_corners, project_boxes, wrap_angle
from kitti.dataset import KittiDataset
from kitti.labels import parse_label_line
from simgen.labels import derive
from simgen.meshes import build_actor_parts
from simgen.render import render
from simgen.rigs import onboard_rig
from simgen.spec import LabelRules
from simgen.world import Actor, Light, Weather, World
from fidelity.labels import box_projections

CAR = {"kind": "car", "dims": [1.53, 1.63, 3.88], "color": [0.55, 0.04, 0.03], "seed": 7}


def pose(x: float, y: float, yaw: float = 0.0, z: float = 0.0) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = [x, y, z]
    return T


def world_of(placements: list[tuple[dict, np.ndarray]], cls: str = "Car") -> World:
    """Actors (recipe, pose) on the KITTI onboard rig, no static scenery, plain daylight."""
    rig = onboard_rig()
    actors = [Actor(i + 1, cls, build_actor_parts(r), p, recipe=r) for i, (r, p) in enumerate(placements)]
    return World(actors=actors, static=[], weather=Weather(), lidar_pose=rig.reference_pose.copy(),
                 rig=rig, light=Light())


def mask_box(instance: np.ndarray, actor_id: int) -> np.ndarray:
    """Continuous extent of the actor's pixels: pixel i spans [i - 0.5, i + 0.5], clipped to the image
    the way labels are (0 .. size - 1)."""
    ys, xs = np.nonzero(instance == actor_id)
    h, w = instance.shape
    return np.array([max(xs.min() - 0.5, 0), max(ys.min() - 0.5, 0), min(xs.max() + 0.5, w - 1),
                     min(ys.max() + 0.5, h - 1)], float)


def written(row) -> np.ndarray:
    """The row's 3D box as its label line states it."""
    return parse_label_line(row.to_line()).box7


RULES = LabelRules(min_height_px=0, max_distance=1000, min_visible_share=0.0)


def _label(world, actor_id=1, rules=RULES):
    out = render(world)
    rows, truths = derive(world, out.instance, rules)
    t = next(t for t in truths if t.id == actor_id)
    return out, rows, t


@pytest.mark.parametrize("x,y,yaw", [(20.0, 1.0, 0.4), (12.0, -3.0, -1.2), (35.0, 4.0, 2.5)])
def test_lone_car_label_box_is_the_projected_3d_box_and_the_mask_box_its_silhouette(x, y, yaw):
    world = world_of([(CAR, pose(x, y, yaw))])
    out, rows, t = _label(world)
    (row,) = rows
    assert row.type == "Car" and row.occluded == 0 and row.truncated == 0.0
    size = (world.rig.width, world.rig.height)
    calib = world.rig.calib
    np.testing.assert_allclose(row.bbox, project_boxes(written(row)[None], calib, size, upright="lidar")[0],
                               atol=1e-6)  # KITTI's convention, exactly
    mb = mask_box(out.instance, 1)
    np.testing.assert_allclose(t.silhouette_bbox, mb, atol=1.0)
    # the silhouette lies inside the label box's own projection: that box is the larger one
    own = project_boxes(row.box7[None], calib, size)[0]
    assert np.all(own[:2] <= t.silhouette_bbox[:2] + 1e-9)
    assert np.all(own[2:] >= t.silhouette_bbox[2:] - 1e-9)
    # KITTI's 2D box differs from it by the LiDAR's tilt only: 0.85 deg over a corner's reach of
    # at most half the box's diagonal (2.3 m for this car) moves a corner 3.4 cm
    reach_px = calib.P2[0, 0] * 0.034 / np.hypot(x, y)
    assert 0 < np.abs(row.bbox - own).max() < reach_px * 1.5
    assert t.visible_share > 0.95
    uv, depth = world.rig.calib.rect_to_image(box_corners(row.box7[None])[0])
    assert np.all(depth > 0)
    assert uv[:, 0].min() <= mb[0] + 1 and uv[:, 1].min() <= mb[1] + 1
    assert uv[:, 0].max() >= mb[2] - 1 and uv[:, 1].max() >= mb[3] - 1


def test_car_exactly_behind_another_is_largely_occluded():
    world = world_of([(CAR, pose(15.0, 0.0)), (CAR, pose(30.0, 0.0))])
    out, rows, t = _label(world, actor_id=2)
    assert t.occluded == 2 and t.visible_share < 0.3
    front = next(r for r in rows if abs(r.location[2] - 15.0 - 0.27) < 2.5)
    assert front.occluded == 0


def test_car_half_out_of_the_image_is_truncated_by_half():
    probe = world_of([(CAR, pose(15.0, 0.0))])
    K_cam = probe.rig.cam2_from_world()
    P = probe.rig.intrinsics()

    def u_of_centre(y):
        c = K_cam @ np.array([15.0, y, CAR["dims"][0] / 2, 1.0])
        uvw = P @ c[:3]
        return uvw[0] / uvw[2] + 0.5  # the image's left edge is at u = -0.5

    y = brentq(u_of_centre, 0.0, 30.0)
    # Facing straight away from the camera, its silhouette is nearly symmetric about its centre.
    world = world_of([(CAR, pose(15.0, y, np.arctan2(y, 15.0)))])
    _, rows, t = _label(world)
    assert abs(t.truncation - 0.5) < 0.05
    assert t.bbox[0] == 0.0
    assert rows[0].truncated == round(t.truncation, 2)


@pytest.mark.parametrize("yaw", [0.0, 0.5, np.pi / 2, -2.0, np.pi])
def test_rotation_y_alpha_and_location_agree_with_the_pose(yaw):
    world = world_of([(CAR, pose(18.0, -2.0, yaw))])
    _, (row,), _ = _label(world)
    # World yaw theta (x forward, y left) is ry = -pi/2 - theta in the (levelled) camera.
    assert abs(wrap_angle(row.rotation_y - (-np.pi / 2 - yaw))) < 1e-9
    x, _, z = row.location
    assert row.alpha == pytest.approx(float(alpha_from_rotation_y(row.rotation_y, x, z)), abs=1e-12)
    rect = world.rig.calib.velo_to_rect @ np.linalg.inv(world.rig.reference_pose)
    np.testing.assert_allclose(row.location, (rect @ np.array([18.0, -2.0, 0.0, 1.0]))[:3], atol=1e-9)
    assert (row.h, row.w, row.l) == pytest.approx(CAR["dims"], abs=1e-9)
    # Every mesh vertex lies in the label box.
    verts = np.concatenate([p.mesh.vertices for p in world.actors[0].parts])
    vr = (rect @ (world.actors[0].pose @ np.c_[verts, np.ones(len(verts))].T)).T[:, :3]
    local = (vr - row.location) @ np.array([[np.cos(row.rotation_y), 0, -np.sin(row.rotation_y)],
                                            [0, 1, 0],
                                            [np.sin(row.rotation_y), 0, np.cos(row.rotation_y)]]).T
    assert np.all(np.abs(local[:, 0]) <= row.l / 2 + 1e-9)
    assert np.all(np.abs(local[:, 2]) <= row.w / 2 + 1e-9)
    assert np.all((local[:, 1] <= 1e-9) & (local[:, 1] >= -row.h - 1e-9))
    assert np.abs(local[:, 0]).max() == pytest.approx(row.l / 2, abs=1e-9)  # and touch it
    assert local[:, 1].min() == pytest.approx(-row.h, abs=1e-9)


def test_depth_of_road_pixels_matches_the_ray_plane_intersection():
    from simgen.road import RoadLayout
    from simgen.scenery import build_scenery

    world = world_of([])
    road = RoadLayout(0.0, 2, 3.5, 0, 3.0, 0.15, False, -10.0, 200.0)
    world.static, _ = build_scenery({"road": road.to_dict(), "seed": 0, "clutter": {
        "buildings": False, "building_setback": 0.0, "trees_per_100m": 0.0, "pole_spacing": 0.0,
        "fences": False}})
    out = render(world)
    a, b, c, d = world.rig.road_plane_rect()
    assert d == pytest.approx(1.65, abs=0.02)  # KITTI's camera height
    calib = world.rig.calib
    for u, v in [(600, 300), (450, 330), (560, 290), (620, 200)]:  # asphalt, not markings
        # The pixel's ray in rect coords: points image_to_rect(uv, depth) for two depths.
        p1 = calib.image_to_rect(np.array([[u, v]], float), np.array([1.0]))[0]
        p2 = calib.image_to_rect(np.array([[u, v]], float), np.array([2.0]))[0]
        # depth here is camera-2 z; rect z differs from it by P2's tiny z offset only.
        n = np.array([a, b, c])
        s = -(n @ p1 + d) / (n @ (p2 - p1))
        hit = p1 + s * (p2 - p1)
        z_cam2 = hit[2] + calib.P2[2, 3]
        assert out.depth[v, u] == pytest.approx(z_cam2, rel=1e-4), (u, v)
        assert out.instance[v, u] == 0


@pytest.mark.parametrize("x,y,yaw", [(6.0, 1.5, 0.7), (0.5, -3.0, 0.0)])  # 2nd: cut by the near plane
def test_convex_part_silhouette_equals_the_union_of_projected_triangles(x, y, yaw):
    from simgen.labels import silhouette

    world = world_of([(CAR, pose(x, y, yaw))])
    actor = world.actors[0]
    cam, K = world.rig.cam2_from_world(), world.rig.intrinsics()
    fast = silhouette(actor, cam, K)
    actor.recipe = {"kind": "user"}  # forces the triangle path
    slow = silhouette(actor, cam, K)
    assert fast.area == pytest.approx(slow.area, rel=1e-9)
    assert fast.symmetric_difference(slow).area < 1e-6 * slow.area


def test_user_mesh_actor_is_labelled_from_its_own_geometry(tmp_path):
    import trimesh

    from simgen.usermesh import user_recipe

    # A non-convex mesh: two boxes in an L, written as OBJ.
    m = trimesh.util.concatenate([trimesh.creation.box(bounds=[[0, 0, 0], [4, 1, 1]]),
                                  trimesh.creation.box(bounds=[[0, 0, 1], [1, 1, 2]])])
    path = tmp_path / "ell.obj"
    m.export(path)
    recipe = user_recipe(str(path), "Misc", None, "z", (0.6, 0.6, 0.2), 0.4)
    world = world_of([(recipe, pose(14.0, 0.5, 0.3))], cls="Misc")
    assert len(world.actors[0].parts) == len(build_actor_parts(recipe)) == 1
    out, (row,), t = _label(world)
    assert row.type == "Misc" and (row.h, row.w, row.l) == pytest.approx((2.0, 1.0, 4.0))
    np.testing.assert_allclose(t.silhouette_bbox, mask_box(out.instance, 1), atol=1.0)
    size = (world.rig.width, world.rig.height)
    kitti_box = project_boxes(written(row)[None], world.rig.calib, size, upright="lidar")[0]
    np.testing.assert_allclose(row.bbox, kitti_box, atol=1e-6)
    assert t.visible_share > 0.95 and row.occluded == 0


def test_car_beside_the_camera_is_cut_at_the_near_plane_and_truncated():
    world = world_of([(CAR, pose(2.2, -2.2))])  # its rear is behind the camera plane
    out, rows, t = _label(world)
    (row,) = rows
    # Cut at a 5 cm near plane, the part beside the camera projects far outside the image.
    assert t.truncation > 0.9 and row.bbox[2] == world.rig.width - 1
    np.testing.assert_allclose(t.silhouette_bbox, mask_box(out.instance, 1), atol=1.0)


def _tilted(T: np.ndarray, pitch: float, roll: float) -> np.ndarray:
    """T with its body pitched (nose up) and rolled, as on a graded, crowned road."""
    cp, sp, cr, sr = np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    out = T.copy()
    out[:3, :3] = T[:3, :3] @ np.array([[cp, 0, -sp], [0, 1, 0], [sp, 0, cp]]) @ np.array(
        [[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return out


@pytest.mark.parametrize("T", [
    _tilted(pose(14.0, 2.0, 0.3), 0.06, 0.03),   # on a 6 % grade, rolled by a 3 % crown
    _tilted(pose(6.0, 4.2, -0.2), -0.05, -0.04),  # near, tilted the other way, cut by the image side
    pose(2.2, -2.2),                              # beside the camera, reaching behind it
    _tilted(pose(9.0, -5.5, 0.1), 0.04, 0.025),   # cut by the right side, tilted
], ids=["graded", "near-cut", "beside", "cut-right"])
def test_every_2d_box_is_the_projection_of_its_written_label_row(T):
    """KITTI's convention for every row, tilted or truncated: the 2D box is the projection of the
    3D box the row states (as read back from its text), stood upright in the LiDAR's frame, its
    bounds clamped to the image; the tilted mesh's own silhouette does not set it."""
    world = world_of([(CAR, T)])
    _, (row,), t = _label(world)
    back = parse_label_line(row.to_line())
    proj = project_boxes(written(row)[None], world.rig.calib, (world.rig.width, world.rig.height),
                         upright="lidar")[0]
    np.testing.assert_allclose(back.bbox, proj, atol=1e-4)  # four decimals written
    assert t.truncation > 0.0 or T[2, 0] != 0.0  # each case is tilted or cut


PED = {"kind": "pedestrian", "dims": [1.76, 0.66, 0.84], "color": [0.2, 0.25, 0.4], "seed": 11}


@pytest.mark.parametrize("x,y,yaw", [(9.0, 1.0, 0.3), (18.0, -2.5, 1.9)])
def test_pedestrian_box_takes_its_sides_from_the_silhouette_and_its_top_and_bottom_from_the_3d_box(
        x, y, yaw):
    world = world_of([(PED, pose(x, y, yaw))], cls="Pedestrian")
    out, (row,), t = _label(world)
    size = (world.rig.width, world.rig.height)
    proj = project_boxes(written(row)[None], world.rig.calib, size, upright="lidar")[0]
    np.testing.assert_allclose(row.bbox[[1, 3]], proj[[1, 3]], atol=1e-6)
    np.testing.assert_array_equal(row.bbox[[0, 2]], t.silhouette_bbox[[0, 2]])
    np.testing.assert_allclose(row.bbox[[0, 2]], mask_box(out.instance, 1)[[0, 2]], atol=1.0)
    assert row.bbox[2] - row.bbox[0] < 0.95 * (proj[2] - proj[0])  # the body inside its box
    # With no class named, the pedestrian's box is the projection, as every other class's.
    _, (plain,), _ = _label(world, rules=RULES.model_copy(update={"silhouette_sides": ()}))
    np.testing.assert_allclose(plain.bbox, proj, atol=1e-6)


def test_silhouette_sides_refuses_a_class_the_generator_does_not_build():
    with pytest.raises(ValueError, match="silhouette_sides"):
        LabelRules(silhouette_sides=("Tram",))


REAL = Path(__file__).resolve().parents[3] / "shared" / "kitti_real_dev"  # beside the repository


@pytest.mark.skipif(not (REAL / "training" / "label_2").is_dir(),
                    reason=f"the real KITTI dev frames are not at {REAL}")
def test_real_kitti_2d_boxes_are_the_lidar_upright_projection_except_pedestrians_sides():
    """The convention the generator copies, on real frames: untruncated vehicles' and cyclists'
    2D boxes lie within 1.1 px of their 3D boxes stood upright in the LiDAR's frame, nearer than
    to the label boxes' own projection in 39 of 40 cases; pedestrians' are narrower than either
    projection, their tops and bottoms within 1 px of it."""
    ped, other = [], []
    for o, pc, pl in box_projections(KittiDataset(REAL), ("Pedestrian", "Car", "Van", "Truck", "Cyclist")):
        bb = np.asarray(o.bbox)
        if o.type == "Pedestrian":
            ped.append(((bb[2] - bb[0]) / (pl[2] - pl[0]), *np.abs(bb - pl)[[1, 3]]))
        else:
            other.append((np.abs(bb - pc).max(), np.abs(bb - pl).max()))
    ped, other = np.array(ped), np.array(other)
    assert len(ped) == 3 and len(other) == 40
    assert np.all(ped[:, 0] < 0.9) and np.all(ped[:, 1:] < 1.0)
    assert other[:, 1].max() < 1.1 and np.sum(other[:, 1] < other[:, 0]) == 39
    assert np.median(other[:, 1]) < 0.3 < 0.5 < np.median(other[:, 0])
