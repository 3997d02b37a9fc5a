"""The thesis's lifting (000): the Table 5.1 offset against ray/box geometry, and the occlusion rule."""

import numpy as np
import pytest

from kitti.boxes import rot_y
from lifter import frustum
from lifter.frustum import lift_frustum, thesis_depth_offset
from lifter.points import MIN_DEPTH, frame_points
from lifter.types import Box2D, Prior
from tests.lifter.synth import make_frame


def _entry(centre, ry, h, w, l):
    """Distance from the camera to where the ray through the box centre enters the box, and the
    entry face ('side' or 'front/back'), by slab intersection in the box frame."""
    d = centre / np.linalg.norm(centre)
    r = rot_y(ry)[0]
    o_l, d_l = r.T @ -centre, r.T @ d  # box frame: x along l, y down, z along w
    half = np.array([l, h, w]) / 2
    with np.errstate(divide="ignore"):
        t1, t2 = (-half - o_l) / d_l, (half - o_l) / d_l
    tn = np.minimum(t1, t2)
    axis = int(np.nanargmax(tn))
    return float(tn[axis]), ("front/back" if axis == 0 else "side")


@pytest.mark.parametrize("alpha_deg", [10, 35, 60, 80, 100, 125, 150, 170,
                                       -10, -35, -60, -80, -100, -125, -150, -170])
def test_thesis_offset_matches_geometry_in_every_quadrant(alpha_deg):
    h, w, l = 1.5, 1.7, 4.2
    alpha = np.deg2rad(alpha_deg)
    for x, z in ((0.0, 20.0), (-6.0, 15.0), (8.0, 30.0)):
        centre = np.array([x, 0.0, z])  # ray in the horizontal plane, as in the thesis's top view
        ry = alpha + np.arctan2(x, z)
        t_in, face = _entry(centre, ry, h, w, l)
        pose, offset = thesis_depth_offset(alpha, w, l)
        assert pose == face
        assert offset == pytest.approx(np.linalg.norm(centre) - t_in, abs=1e-9)


def test_hidden_car_gets_the_occlusion_rules_depth():
    a = [0.3, 1.65, 10.0, 1.5, 1.7, 4.2, 0.05]    # side-on, in front
    b = [-0.8, 1.65, 17.0, 1.5, 1.7, 4.2, 0.40]   # behind it, its centre column hidden by it
    fr = make_frame([a, b])
    pts = frame_points(fr.velodyne, fr.calib, None)
    in_front = fr.calib.lidar_to_rect(fr.velodyne[:, :3].astype(float))[:, 2] > MIN_DEPTH
    hit = fr.hit_id[in_front]  # the box each kept return came from
    boxes = [Box2D("Car", o.bbox, 1.0) for o in fr.objects]
    priors = [Prior(np.array([o.h, o.w, o.l]), o.alpha) for o in fr.objects]
    above = pts.sensor[1] + frustum.LIDAR_HEIGHT - pts.rect[:, 1] > frustum.GROUND_CUT
    depth = pts.rect[:, 2]

    def in_box(k):
        return np.isin(np.arange(len(depth)), pts.in_box(boxes[k].bbox)) & above

    # B's centre column hits A: the precondition of the rule
    tx_b = boxes[1].centre[0]
    col_b = in_box(1) & (np.abs(pts.uv[:, 0] - tx_b) <= 3)
    assert (hit[col_b][np.argmin(depth[col_b])]) == 0
    # A (visible): surface depth on its centre column + |offset|
    x1, _, x2, _ = boxes[0].bbox
    half = max(frustum.CENTRE_COL_PX, frustum.CENTRE_COL_FRAC * (x2 - x1))
    col_a = in_box(0) & (np.abs(pts.uv[:, 0] - boxes[0].centre[0]) <= half)
    c_depth_a = depth[col_a].min() + thesis_depth_offset(fr.objects[0].alpha, 1.7, 4.2)[1]
    closest_a = depth[in_box(0) & (hit == 0)].min()
    closest_b = depth[in_box(1) & (hit == 1)].min()
    out = lift_frustum(boxes, priors, pts, fr.calib)
    assert out[0].location[2] == pytest.approx(c_depth_a, abs=1e-9)
    assert out[1].location[2] == pytest.approx(c_depth_a + (closest_b - closest_a), abs=1e-9)
    # the printed formula (gap reversed) would put B in front of A
    assert c_depth_a + (closest_a - closest_b) < out[0].location[2]


def test_box_without_returns_is_left_to_the_fallback():
    fr = make_frame([[0.0, 1.65, 12.0, 1.5, 1.7, 4.2, 0.0]])
    pts = frame_points(fr.velodyne, fr.calib, None)
    empty_sky = Box2D("Car", np.array([600.0, 5.0, 640.0, 30.0]), 1.0)
    out = lift_frustum([empty_sky], [Prior(np.array([1.5, 1.7, 4.2]), 0.0)], pts, fr.calib)
    assert out == [None]
