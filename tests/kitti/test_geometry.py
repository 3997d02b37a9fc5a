"""Frames, box geometry and exact IoU against hand-computed values and shapely."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
import shapely
from shapely.geometry import Polygon

from kitti import (
    Calibration,
    alpha_from_rotation_y,
    box_corners,
    iou_2d,
    iou_3d,
    iou_bev,
    lidar_upright_corners,
    points_in_boxes,
    project_boxes,
    rotation_y_from_alpha,
)
from kitti.iou import bev_corners

KITTI = Calibration.kitti_default()


def test_rect_to_image_hand_computed():
    # u = (fu x + cu z + 44.85728) / (z + 0.002745884), v = (fv y + cv z + 0.2163791) / (z + 0.002745884)
    uv, depth = KITTI.rect_to_image(np.array([[1.0, 1.5, 20.0]]))
    w = 20.0 + 2.745884e-03
    assert uv[0, 0] == pytest.approx((721.5377 + 609.5593 * 20 + 44.85728) / w, abs=1e-9)
    assert uv[0, 1] == pytest.approx((721.5377 * 1.5 + 172.854 * 20 + 0.2163791) / w, abs=1e-9)
    assert depth[0] == 20.0


def test_lidar_to_image_is_the_kitti_formula_with_real_r0():
    assert not np.allclose(KITTI.R0_rect, np.eye(3))
    pts = np.array([[10.0, 2.0, -1.0], [35.0, -4.0, 0.5], [5.0, 0.0, -1.7]])
    r0 = np.eye(4)
    r0[:3, :3] = KITTI.R0_rect
    tr = np.vstack([KITTI.Tr_velo_to_cam, [0, 0, 0, 1]])
    hom = (KITTI.P2 @ r0 @ tr @ np.c_[pts, np.ones(3)].T).T
    uv, depth = KITTI.lidar_to_image(pts)
    np.testing.assert_allclose(uv, hom[:, :2] / hom[:, 2:], atol=1e-9)
    # a point 10 m straight ahead of the LiDAR is ~0.27 m nearer the camera and near the image centre
    assert depth[0] == pytest.approx((r0 @ tr @ [10, 2, -1, 1])[2])
    uv0, d0 = KITTI.lidar_to_image(np.array([[10.0, 0, 0]]))
    assert d0[0] == pytest.approx(10 - 0.2718 - 0.0004, abs=0.01)
    assert abs(uv0[0, 0] - 609.56 - 44.857 / 10) < 12 and abs(uv0[0, 1] - 172.85) < 12


def test_non_identity_r0_rotates_the_rectified_frame():
    th = np.deg2rad(5.0)
    ry = np.array([[np.cos(th), 0, np.sin(th)], [0, 1, 0], [-np.sin(th), 0, np.cos(th)]])
    p = np.array([[500.0, 0, 600, 0], [0, 500, 200, 0], [0, 0, 1, 0]])
    c = Calibration(p, p, p, p, ry, np.eye(4)[:3], np.eye(4)[:3])
    rect = c.ref_to_rect(np.array([[0.0, 0.0, 10.0]]))
    np.testing.assert_allclose(rect, [[10 * np.sin(th), 0, 10 * np.cos(th)]], atol=1e-12)
    uv, _ = c.rect_to_image(rect)
    np.testing.assert_allclose(uv, [[600 + 500 * np.tan(th), 200]], atol=1e-9)


def test_frame_round_trips():
    rng = np.random.default_rng(3)
    pts = rng.uniform([-20, -20, -3], [80, 20, 3], size=(500, 3))
    np.testing.assert_allclose(KITTI.rect_to_lidar(KITTI.lidar_to_rect(pts)), pts, atol=1e-9)
    np.testing.assert_allclose(KITTI.ref_to_lidar(KITTI.lidar_to_ref(pts)), pts, atol=1e-9)
    np.testing.assert_allclose(KITTI.rect_to_ref(KITTI.ref_to_rect(pts)), pts, atol=1e-9)
    rect = KITTI.lidar_to_rect(pts[pts[:, 0] > 1])
    for cam in (0, 2, 3):
        uv, depth = KITTI.rect_to_image(rect, cam)
        np.testing.assert_allclose(KITTI.image_to_rect(uv, depth, cam), rect, atol=1e-9)


def test_box_corners_hand_computed():
    c = box_corners(np.array([[1, 2, 10, 1.5, 2, 4, 0.0], [1, 2, 10, 1.5, 2, 4, np.pi / 2]]))
    np.testing.assert_allclose(c[0, 0], [3, 2, 11])
    np.testing.assert_allclose(c[0, 4], [3, 0.5, 11])
    np.testing.assert_allclose(c[0, 2], [-1, 2, 9])
    # ry = pi/2 faces the camera (-z): the front-left corner (l/2, 0, w/2) goes to (x+w/2, y, z-l/2)
    np.testing.assert_allclose(c[1, 0], [2, 2, 8], atol=1e-12)
    assert c.shape == (2, 8, 3)


def test_alpha_and_rotation_y():
    assert alpha_from_rotation_y(0.0, 5.0, 5.0) == pytest.approx(-np.pi / 4)
    assert alpha_from_rotation_y(-np.pi / 2, 0.0, 10.0) == pytest.approx(-np.pi / 2)
    rng = np.random.default_rng(0)
    ry, x, z = rng.uniform(-np.pi, np.pi, 200), rng.uniform(-30, 30, 200), rng.uniform(1, 70, 200)
    a = alpha_from_rotation_y(ry, x, z)
    assert np.all((a >= -np.pi) & (a < np.pi))
    back = rotation_y_from_alpha(a, x, z)
    np.testing.assert_allclose(np.cos(back - ry), 1.0, atol=1e-12)


def test_project_boxes_encloses_the_projected_corners_and_clips():
    box = np.array([[2.0, 1.6, 15.0, 1.5, 1.6, 4.0, 0.4]])
    uv, _ = KITTI.rect_to_image(box_corners(box)[0])
    np.testing.assert_allclose(project_boxes(box, KITTI, (1242, 375))[0],
                               [uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
    # a box straddling the camera plane: compare with densely sampled surface points in front
    long_box = np.array([[3.0, 1.6, 0.5, 1.5, 1.8, 8.0, np.pi / 2]])
    got = project_boxes(long_box, KITTI, (1242, 375))[0]
    g = np.linspace(0, 1, 60)
    corners = box_corners(long_box)[0]
    samples = np.concatenate([corners[i] + g[:, None] * (corners[j] - corners[i])
                              for i, j in [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7),
                                           (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]])
    front = samples[samples[:, 2] >= 0.1]
    suv, _ = KITTI.rect_to_image(front)
    suv = np.clip(suv, 0, [1241, 374])
    ref = [suv[:, 0].min(), suv[:, 1].min(), suv[:, 0].max(), suv[:, 1].max()]
    assert got[0] <= ref[0] + 1e-6 and got[1] <= ref[1] + 1e-6
    assert got[2] >= ref[2] - 1e-6 and got[3] >= ref[3] - 1e-6
    np.testing.assert_allclose(got, ref, atol=3.0)
    assert got[3] == 374  # runs off the bottom of the image
    assert np.isnan(project_boxes(np.array([[0, 1.6, -10, 1.5, 1.6, 4, 0]]), KITTI, (1242, 375))).all()


def test_points_in_boxes():
    box = np.array([[0.0, 1.0, 10.0, 2.0, 2.0, 4.0, np.pi / 2]])  # length along z after rotation
    pts = np.array([[0, 0.5, 11.9], [0, 0.5, 12.1], [0.9, 0.5, 10], [1.1, 0.5, 10],
                    [0, -0.9, 10], [0, -1.1, 10], [0, 1.1, 10]])
    assert points_in_boxes(pts, box)[0].tolist() == [True, False, True, False, True, False, False]


def test_iou_2d_hand_computed():
    a = np.array([[0, 0, 10, 10]])
    b = np.array([[5, 0, 15, 10], [10, 0, 20, 10], [0, 0, 10, 10], [2, 2, 4, 4]])
    np.testing.assert_allclose(iou_2d(a, b)[0], [50 / 150, 0, 1, 4 / 100])


def test_iou_identical_touching_disjoint():
    rng = np.random.default_rng(5)
    boxes = np.column_stack([rng.uniform(-30, 30, 300), rng.uniform(0, 2, 300), rng.uniform(0, 70, 300),
                             rng.uniform(0.5, 4, (300, 3)), rng.uniform(-np.pi, np.pi, 300)])
    np.testing.assert_allclose(np.diag(iou_bev(boxes, boxes)), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.diag(iou_3d(boxes, boxes)), 1.0, atol=1e-9)
    a = np.array([[0, 1.0, 10, 1.5, 2, 4, 0.3]])
    heading = np.array([np.cos(0.3), 0, -np.sin(0.3)])
    touching = a.copy()
    touching[0, :3] += 4 * heading
    assert iou_bev(a, touching)[0, 0] == pytest.approx(0, abs=1e-12)
    stacked = a.copy()
    stacked[0, 1] -= 1.5  # directly on top: bird's-eye identical, no 3D overlap
    assert iou_bev(a, stacked)[0, 0] == pytest.approx(1, abs=1e-9)
    assert iou_3d(a, stacked)[0, 0] == 0
    far = a.copy()
    far[0, 0] += 50
    assert iou_3d(a, far)[0, 0] == 0


def test_iou_3d_hand_computed():
    a = np.array([[0, 0, 10, 2, 2, 4, 0.0]])
    shifted = np.array([[2, 0, 10, 2, 2, 4, 0.0]])  # half the length: 8/(16+16-8)
    lifted = np.array([[0, -1, 10, 2, 2, 4, 0.0]])  # half the height
    rotated = np.array([[0, 0, 10, 2, 2, 2, np.pi / 4]])  # square turned 45 deg, BEV inter = 8(sqrt2-1)
    assert iou_3d(a, shifted)[0, 0] == pytest.approx(1 / 3, abs=1e-12)
    assert iou_3d(a, lifted)[0, 0] == pytest.approx(1 / 3, abs=1e-12)
    sq = np.array([[0, 0, 10, 2, 2, 2, 0.0]])
    inter = 8 * (np.sqrt(2) - 1)
    assert iou_bev(sq, rotated)[0, 0] == pytest.approx(inter / (8 - inter), abs=1e-12)


box_st = st.tuples(st.floats(-4, 4), st.floats(-1, 1), st.floats(-4, 4), st.floats(0.2, 3),
                   st.floats(0.2, 4), st.floats(0.2, 6), st.floats(-np.pi, np.pi))


@settings(max_examples=200, deadline=None)
@given(st.lists(box_st, min_size=1, max_size=12), st.lists(box_st, min_size=1, max_size=12))
@example([(0.5, 0.0, 1.0, 1.0, 2.0, 2.5, -2.75)], [(0.5, 0.0, 1.0, 1.0, 3.0, 2.5, -2.75)])  # nested
def test_iou_matches_shapely(boxes_a, boxes_b):
    a, b = np.array(boxes_a), np.array(boxes_b)
    bev, i3 = iou_bev(a, b), iou_3d(a, b)
    ca, cb = bev_corners(a), bev_corners(b)
    for i in range(len(a)):
        pa = Polygon(ca[i])
        for j in range(len(b)):
            pb = Polygon(cb[j])
            # GEOS's floating-point overlay can lose a whole intersection where edges overlap
            # collinearly (hypothesis found nested boxes sharing two edges: area 0 instead of 5);
            # its snap-rounding overlay on a 1e-12 m grid is robust and exact to ~1e-11.
            inter = shapely.intersection(pa, pb, grid_size=1e-12).area
            assert bev[i, j] == pytest.approx(inter / (pa.area + pb.area - inter), abs=1e-9)
            dy = max(0.0, min(a[i, 1], b[j, 1]) - max(a[i, 1] - a[i, 3], b[j, 1] - b[j, 3]))
            vi = inter * dy
            ref3 = vi / (a[i, 3] * pa.area + b[j, 3] * pb.area - vi)
            assert i3[i, j] == pytest.approx(ref3, abs=1e-9)


def test_lidar_upright_corners_stand_on_the_lidars_z_and_keep_the_box():
    boxes = np.array([[2.0, 1.6, 15.0, 1.5, 1.6, 4.0, 0.4], [-4.0, 1.7, 30.0, 1.8, 0.7, 0.9, -2.2]])
    got, own = lidar_upright_corners(boxes, KITTI), box_corners(boxes)
    up = KITTI.lidar_to_rect(np.array([[0.0, 0.0, 1.0]])) - KITTI.lidar_to_rect(np.zeros((1, 3)))
    for g, o, b in zip(got, own, boxes):
        # the same bottom-face centre and the same edge lengths (a rigid turn of the label's box)
        np.testing.assert_allclose(g[:4].mean(axis=0), b[:3], atol=1e-9)
        edges = [(0, 1), (1, 2), (0, 4)]
        np.testing.assert_allclose([np.linalg.norm(g[i] - g[j]) for i, j in edges],
                                   [np.linalg.norm(o[i] - o[j]) for i, j in edges], atol=1e-9)
        # its vertical edges run along the LiDAR's z, h long
        np.testing.assert_allclose(g[4] - g[0], up[0] * b[3], atol=1e-9)
        # the heading, seen from above in the LiDAR's frame, is the label's
        base = KITTI.rect_to_lidar(b[None, :3])
        front = KITTI.rect_to_lidar(g[[0, 1]].mean(axis=0, keepdims=True))  # the front face's foot
        head = KITTI.rect_to_lidar(b[None, :3] + [[np.cos(b[6]), 0, -np.sin(b[6])]])
        u, v = (front - base)[0, :2], (head - base)[0, :2]
        assert u[0] * v[1] - u[1] * v[0] == pytest.approx(0.0, abs=1e-9) and u @ v > 0
        # KITTI's calibration tilts the two boxes apart by centimetres, not more
        assert 0.005 < np.abs(g - o).max() < 0.05
    # a LiDAR whose axes are the camera's own (x ahead = z, y left = -x, z up = -y) changes nothing
    aligned = replace(KITTI, R0_rect=np.eye(3),
                      Tr_velo_to_cam=np.array([[0, -1, 0, 0.1], [0, 0, -1, -0.2], [1, 0, 0, 0.3]]))
    np.testing.assert_allclose(lidar_upright_corners(boxes, aligned), own, atol=1e-12)
    with pytest.raises(ValueError, match="upright"):
        project_boxes(boxes, KITTI, (1242, 375), upright="world")
