"""Image-only lifting: with the true size and orientation and the exact 2D box, the Deep3DBox
constraints give back the translation."""

import numpy as np
import pytest

from kitti.boxes import alpha_from_rotation_y, project_boxes
from kitti.calib import Calibration
from lifter.mono import box_up_of, solve_from_alpha, solve_translation, standing_corners
from lifter.roadside import ground_point, lift_roadside
from lifter.types import Box2D, Prior

SIZE = (1242, 375)


def _random_boxes(n, seed):
    rng = np.random.default_rng(seed)
    calib = Calibration.kitti_default()
    out = []
    while len(out) < n:
        b = np.array([rng.uniform(-10, 10), rng.uniform(1.4, 1.9), rng.uniform(5, 60),
                      rng.uniform(1.3, 2.2), rng.uniform(1.4, 2.0), rng.uniform(3.2, 5.5),
                      rng.uniform(-np.pi, np.pi)])
        bb = project_boxes(b[None], calib, SIZE)[0]
        if bb[0] > 2 and bb[1] > 2 and bb[2] < SIZE[0] - 3 and bb[3] < SIZE[1] - 3:
            out.append((b, bb))
    return calib, out


def test_mono_recovers_translation_from_alpha_to_1cm():
    calib, boxes = _random_boxes(40, seed=7)
    for b, bb in boxes:
        alpha = float(alpha_from_rotation_y(b[6], b[0], b[2]))
        sol = solve_from_alpha(b[3:6], alpha, bb, calib, SIZE)
        assert np.abs(sol.location - b[:3]).max() < 0.01
        assert abs(sol.rotation_y - b[6]) < 1e-4 or abs(abs(sol.rotation_y - b[6]) - 2 * np.pi) < 1e-4
        assert sol.box_error_px < 0.01


def test_mono_with_rotation_y_is_exact():
    calib, boxes = _random_boxes(10, seed=8)
    for b, bb in boxes:
        sol = solve_translation(b[3:6], b[6], bb, calib, SIZE)
        np.testing.assert_allclose(sol.location, b[:3], atol=1e-6)


def test_kitti_2d_boxes_are_lifted_back_to_their_label_boxes_with_the_lidars_up():
    """KITTI's 2D box is the projection of the label's box stood upright in the LiDAR's frame
    (0.85 deg off the camera's up in its calibration). With that up, mono gives the label box back
    to 1 cm with the road plane and without; taking the 2D box for the label box's own projection
    puts it centimetres off (decimetres far away)."""
    plane = np.array([0.0, -1.0, 0.0, 1.65])
    calib, boxes = _random_boxes(30, seed=10)
    up = box_up_of("box", calib)
    assert box_up_of("silhouette", calib) is None
    assert np.degrees(np.arccos(-up[1])) == pytest.approx(0.85, abs=0.01)
    off = []
    for b, _ in boxes:
        b = b.copy()
        b[1] = 1.65  # on the road
        bb = project_boxes(b[None], calib, SIZE, upright="lidar")[0]
        if bb[3] >= SIZE[1] - 3:
            continue
        alpha = float(alpha_from_rotation_y(b[6], b[0], b[2]))
        for road in (plane, None):
            sol = solve_from_alpha(b[3:6], alpha, bb, calib, SIZE, road, box_up=up)
            assert np.abs(sol.location - b[:3]).max() < 0.01
        off.append(np.abs(solve_from_alpha(b[3:6], alpha, bb, calib, SIZE, plane).location - b[:3]).max())
    assert len(off) > 20 and np.median(off) > 0.03


def test_ground_contact_inside_the_footprint_gives_the_depth():
    """A vehicle on its tyres: the 2D box's sides and top come from the 3D box, its bottom from the
    contact points (64 % of the length, 92 % of the width). With the road plane, mono puts the box
    back to 1 cm; assuming the corners touch the road instead puts it measurably too far."""
    plane = np.array([0.0, -1.0, 0.0, 1.65])
    calib, boxes = _random_boxes(30, seed=9)
    far = []
    for b, _ in boxes:
        b = b.copy()
        b[1] = 1.65  # on the road
        bb = project_boxes(b[None], calib, SIZE)[0]
        feet = b.copy()
        feet[4], feet[5] = 0.92 * b[4], 0.64 * b[5]
        bb[3] = project_boxes(feet[None], calib, SIZE)[0][3]  # lowest contact point
        if bb[3] >= SIZE[1] - 3:
            continue
        alpha = float(alpha_from_rotation_y(b[6], b[0], b[2]))
        sol = solve_from_alpha(b[3:6], alpha, bb, calib, SIZE, plane, contact=(0.64, 0.92))
        assert np.abs(sol.location - b[:3]).max() < 0.01
        assert sol.box_error_px < 0.05
        corners = solve_from_alpha(b[3:6], alpha, bb, calib, SIZE, plane)
        far.append(corners.location[2] - b[2])
    assert len(far) > 20 and np.median(far) > 0.3


def test_truncated_box_needs_the_road():
    calib = Calibration.kitti_default()
    b = np.array([-4.0, 1.65, 4.0, 1.5, 1.6, 4.0, 0.3])  # cut by the left and bottom borders
    bb = project_boxes(b[None], calib, SIZE)[0]
    assert bb[0] == 0 and bb[3] == SIZE[1] - 1
    with pytest.raises(ValueError, match="constraints"):
        solve_translation(b[3:6], b[6], bb, calib, SIZE)
    plane = np.array([0.0, -1.0, 0.0, 1.65])
    sol = solve_translation(b[3:6], b[6], bb, calib, SIZE, plane=plane)
    np.testing.assert_allclose(sol.location, b[:3], atol=1e-6)


def test_roadside_back_projection_on_a_tilted_gantry_camera(monkeypatch):
    """004: a camera 6 m up, tilted 20 degrees down: the bottom-centre ray meets the road where the
    geometry says, and a box standing upright on the road (tilted in the camera frame) is put back
    from its 2D box."""
    monkeypatch.setattr("lifter.mono.CONTACT", {})  # a plain box: it touches the road at its corners
    base = Calibration.kitti_default()
    tilt = np.deg2rad(20.0)
    c, s = np.cos(tilt), np.sin(tilt)
    r = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])  # world (x right, y down, z ahead) -> camera
    height = 6.0
    # road y_world = height -> in the camera: n_cam = r @ (0, -1, 0), d = height
    plane = np.append(r @ np.array([0.0, -1.0, 0.0]), height)
    calib = Calibration(base.P0, base.P1, base.P0, base.P3, np.eye(3),  # camera 2 = camera 0
                        base.Tr_velo_to_cam, base.Tr_imu_to_velo)
    centre_w = np.array([1.0, height, 25.0])
    loc = r @ centre_w
    ry = 0.4  # yaw about the camera's y axis
    b = np.array([*loc, 1.5, 1.7, 4.2, ry])
    g = ground_point(700.0, 300.0, calib, plane)
    assert abs(g @ plane[:3] + plane[3]) < 1e-9
    uv, _ = calib.rect_to_image(g[None])
    np.testing.assert_allclose(uv[0], [700.0, 300.0], atol=1e-9)
    corners = loc + standing_corners(1.5, 1.7, 4.2, ry, plane[:3])
    assert np.allclose((corners[:4] @ plane[:3]) + plane[3], 0) and np.allclose((corners[4:] @ plane[:3]) + plane[3], 1.5)
    uv, _ = calib.rect_to_image(corners)
    bb = np.array([*uv.min(axis=0), *uv.max(axis=0)])
    alpha = float(alpha_from_rotation_y(ry, loc[0], loc[2]))
    out = lift_roadside([Box2D("Car", bb, 1.0)], [Prior(b[3:6], alpha)], calib, SIZE, plane)[0]
    assert abs(out.location @ plane[:3] + plane[3]) < 1e-6
    np.testing.assert_allclose(out.location, loc, atol=1e-3)
