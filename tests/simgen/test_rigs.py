"""Camera rigs: the KITTI onboard rig, the 004 gantry model and the 003 orbit camera."""

from __future__ import annotations

import numpy as np
import pytest

from kitti.calib import Calibration
from simgen.rigs import gantry_rig, onboard_rig, orbit_rig


def test_onboard_rig_puts_camera_2_where_kitti_has_it():
    rig = onboard_rig()
    cam = np.linalg.inv(rig.cam2_from_world())[:3, 3]
    # Camera 0 is 0.27 m ahead of the LiDAR and 1.65 m above the road; camera 2 sits 6 cm to its left.
    assert cam[0] == pytest.approx(0.27, abs=0.01) and cam[2] == pytest.approx(1.65, abs=0.02)
    assert cam[1] == pytest.approx(0.06, abs=0.01)
    a, b, c, d = rig.road_plane_rect()
    assert b < -0.999 and d == pytest.approx(1.65, abs=0.02)


@pytest.mark.parametrize("h,pan,tilt,f", [(6.5, 0.0, 20.0, 1000.0), (7.2, 8.0, 27.0, 1300.0),
                                          (5.0, -12.0, 10.0, 800.0)])
def test_gantry_rig_is_the_004_camera_model(h, pan, tilt, f):
    W, H = 1280, 720
    rig = gantry_rig(h, pan, tilt, f, (3.0, -2.0), W, H)
    t, p = np.radians(pan), np.radians(tilt)
    R = np.array([[np.cos(t), -np.sin(t), 0.0],
                  [-np.sin(p) * np.sin(t), -np.sin(p) * np.cos(t), -np.cos(p)],
                  [np.cos(p) * np.sin(t), np.cos(p) * np.cos(t), -np.sin(p)]])
    K = np.array([[f, 0, W / 2], [0, f, H / 2], [0, 0, 1]])
    T = np.array([[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -h]])
    rng = np.random.default_rng(0)
    world = np.c_[rng.uniform(10, 60, 20) + 3.0, rng.uniform(-8, 8, 20) - 2.0, rng.uniform(0, 3, 20)]
    # 004's world: x right, y along the road, z up, origin on the road under the camera.
    w004 = np.c_[-(world[:, 1] + 2.0), world[:, 0] - 3.0, world[:, 2], np.ones(20)]
    uvw = (K @ R @ T @ w004.T).T
    ref = (np.linalg.inv(rig.reference_pose) @ np.c_[world, np.ones(20)].T).T[:, :3]
    uv, depth = rig.calib.lidar_to_image(ref)
    np.testing.assert_allclose(uv, uvw[:, :2] / uvw[:, 2:], atol=1e-9)
    np.testing.assert_allclose(depth, uvw[:, 2], atol=1e-9)
    assert rig.road_plane_rect()[3] == pytest.approx(h)


def test_orbit_rig_looks_at_its_target_from_the_asked_distance():
    target = np.array([0.0, 0.0, 0.76])
    rig = orbit_rig(target, 35.0, 32.0, 120.0, 721.5, 1242, 375)
    cam = np.linalg.inv(rig.cam2_from_world())[:3, 3]
    assert np.linalg.norm(cam - target) == pytest.approx(35.0)
    assert np.degrees(np.arcsin((cam - target)[2] / 35.0)) == pytest.approx(32.0)
    assert np.degrees(np.arctan2(cam[1], cam[0])) == pytest.approx(120.0)
    uv, depth = rig.calib.lidar_to_image((np.linalg.inv(rig.reference_pose) @ np.append(target, 1))[None, :3])
    np.testing.assert_allclose(uv[0], [621.0, 187.5], atol=1e-9)
    assert depth[0] == pytest.approx(35.0)


def test_onboard_lidar_is_tilted_as_kittis_calibration_says_and_the_camera_is_level():
    rig = onboard_rig()
    # World vertical in the rectified camera is exactly its -y axis (labels' yaw-only boxes).
    rect = rig.calib.velo_to_rect @ np.linalg.inv(rig.reference_pose)
    np.testing.assert_allclose(rect[:3, :3], [[0, -1, 0], [0, 0, -1], [1, 0, 0]], atol=1e-12)
    # KITTI's 2011_09_26 numbers (Calibration.kitti_default): A^-1 R0_rect Tr_velo_to_cam, A the
    # axis swap, takes the LiDAR's forward axis 0.599 deg and its left axis 0.605 deg below the
    # rectified camera's horizon (the arcsines of its bottom row), so world up leans that far.
    up_in_lidar = np.linalg.inv(rig.reference_pose)[:3, :3] @ [0.0, 0.0, 1.0]
    assert np.degrees(np.arcsin(-up_in_lidar[0])) == pytest.approx(0.599, abs=5e-4)
    assert np.degrees(np.arcsin(-up_in_lidar[1])) == pytest.approx(0.605, abs=5e-4)
    # The written calibration is KITTI's, made exactly rigid (its printed numbers are rigid to 2e-8).
    kitti = Calibration.kitti_default()
    np.testing.assert_allclose(rig.calib.Tr_velo_to_cam, kitti.Tr_velo_to_cam, atol=3e-8)
    assert rig.reference_pose[2, 3] == 1.73
