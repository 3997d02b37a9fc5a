"""`fit`'s box placement kernels against exact geometry: corner columns, the 2D-side misfit, the
translation from an object's face returns, and the length the 2D box chooses."""

import numpy as np
import pytest

from kitti.boxes import box_corners, lidar_upright_corners, project_boxes
from kitti.calib import Calibration
from lifter.mono import box_up_of
from lifter.pipeline import detection_side_sigma
from lifter.placement import (
    CAMERA_UP,
    SIGMA_LENGTH,
    corner_columns,
    length_from_sides,
    side_cost,
    translation,
)
from lifter.types import LABEL_SIDE_SIGMA_PX

CALIB = Calibration.kitti_default()
P = CALIB.P(2)
WIDTH = 1242
PLANE = np.array([0.0, -1.0, 0.0, 1.65])
SENSOR = CALIB.lidar_to_rect(np.zeros((1, 3)))[0]
CAR = np.array([3.0, 1.65, 15.0, 1.5, 1.8, 4.2, 0.4])  # on the road, 15 m ahead, three-quarter view
LIDAR_UP = box_up_of("box", CALIB)  # KITTI's 2D boxes project the box upright in the LiDAR's frame


def _face_returns(box: np.ndarray, step: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Returns on the vertical faces the sensor sees (bird's-eye x, z) and their image columns."""
    corners = box_corners(box[None])[0]
    foot = corners[:4][:, [0, 2]]  # bottom face, in order around the box
    centre = foot.mean(axis=0)
    xz, cols = [], []
    for k in range(4):
        a, b = foot[k], foot[(k + 1) % 4]
        mid = 0.5 * (a + b)
        if (mid - centre) @ (SENSOR[[0, 2]] - mid) <= 0:  # faces away from the sensor
            continue
        t = np.linspace(0.0, 1.0, int(np.linalg.norm(b - a) / step) + 1)[:, None]
        seg = a + t * (b - a)
        pts3 = np.column_stack([seg[:, 0], np.full(len(seg), box[1] - box[3] / 2), seg[:, 1]])
        xz.append(seg)
        cols.append(CALIB.rect_to_image(pts3)[0][:, 0])
    return np.concatenate(xz), np.concatenate(cols)


def test_corner_columns_are_the_projected_corners():
    u = CALIB.rect_to_image(box_corners(CAR[None])[0])[0][:, 0]
    np.testing.assert_allclose(corner_columns(*CAR, P, CAMERA_UP), u, atol=1e-9)


def test_corner_columns_on_the_lidars_up_are_those_of_kittis_box():
    """Stood on the LiDAR's z, the corners are `lidar_upright_corners`' (which turns the heading
    about that z; the kernel keeps its camera x-z direction: 1e-4 rad apart, 0.01 px here), and
    the top corners lie px away from the label box's own."""
    lidar = CALIB.rect_to_image(lidar_upright_corners(CAR[None], CALIB)[0])[0][:, 0]
    u = corner_columns(*CAR, P, LIDAR_UP)
    np.testing.assert_allclose(u, lidar, atol=0.02)
    assert np.abs(u - corner_columns(*CAR, P, CAMERA_UP)).max() > 0.5


def test_gaussian_side_cost_at_sigma_1_is_the_squared_pixel_distance_of_the_uncut_sides():
    bbox = project_boxes(CAR[None], CALIB, (WIDTH, 375))[0]
    assert side_cost(CAR[None], P, bbox, WIDTH, CAMERA_UP, 1.0, np.inf)[0] < 1e-18
    moved = bbox + np.array([-3.0, 0.0, 4.0, 0.0])  # 3 px left, 4 px right: 9 + 16
    assert abs(side_cost(CAR[None], P, moved, WIDTH, CAMERA_UP, 1.0, np.inf)[0] - 25.0) < 1e-9
    cut = moved.copy()
    cut[0] = 0.0  # the left side at the image border says nothing about the box
    assert abs(side_cost(CAR[None], P, cut, WIDTH, CAMERA_UP, 1.0, np.inf)[0] - 16.0) < 1e-9
    kitti = project_boxes(CAR[None], CALIB, (WIDTH, 375), upright="lidar")[0]
    assert side_cost(CAR[None], P, kitti, WIDTH, LIDAR_UP, 1.0, np.inf)[0] < 0.02 ** 2
    assert side_cost(CAR[None], P, kitti, WIDTH, CAMERA_UP, 1.0, np.inf)[0] > 0.1


# the 2D box as the label box's own projection, and as KITTI's (the box upright in the LiDAR's frame)
CONVENTIONS = pytest.mark.parametrize("upright, up", [("camera", CAMERA_UP), ("lidar", LIDAR_UP)])


@CONVENTIONS
def test_translation_recovers_the_bottom_centre_from_two_faces(upright, up):
    bbox = project_boxes(CAR[None], CALIB, (WIDTH, 375), upright=upright)[0]
    xz, u = _face_returns(CAR)
    start = xz.mean(axis=0)  # the centroid of the returns: on the near faces, not the centre
    T, dims, pinned, slide = translation(xz, u, np.zeros(len(xz)), *CAR[3:], bbox, SENSOR[[0, 2]],
                                         start, P, WIDTH, PLANE, True, up)
    # the only inconsistent row is the weak pull to the centroid (sigma 3 m against the faces'
    # 5 cm), which the faces hold to under a millimetre
    np.testing.assert_allclose(T, CAR[:3], atol=1e-3)
    np.testing.assert_allclose(dims, CAR[3:6], atol=1e-9)
    assert pinned == 2
    assert not slide.any()  # both ends of the length are seen: the returns measure it


@CONVENTIONS
def test_length_from_sides_corrects_a_long_prior_in_a_side_view(upright, up):
    car = CAR.copy()
    car[6] = 0.1  # almost broadside: the 2D box's width is mostly the car's length
    bbox = project_boxes(car[None], CALIB, (WIDTH, 375), upright=upright)[0]
    # a prior 0.5 m too long, anchored at the face nearer the sensor (the rear: the car heads
    # away from the sensor, to larger x)
    heading = np.array([np.cos(car[6]), -np.sin(car[6])])
    slide = 0.5 * heading  # the centre moves away from the kept rear as the length grows
    l_prior = car[5] + 0.5
    T_prior = car[:3].copy()
    T_prior[[0, 2]] += 0.5 * slide
    T, length = length_from_sides(T_prior, *car[3:5], l_prior, car[6], slide, bbox, P, WIDTH, PLANE,
                                  up, LABEL_SIDE_SIGMA_PX, np.inf)
    assert abs(length - car[5]) < 0.05
    np.testing.assert_allclose(T, car[:3], atol=0.03)



def test_length_from_sides_weighs_a_side_error_by_the_boxs_side_sigma():
    """A far car seen almost broadside, its 2D box's right side 6 px out (the shipped detector's
    Car sides lie 10.3 px RMS from the labels'): the chosen length is the least-squares optimum of the side's pull (k
    px a metre of length) against the prior's, dl = 6 k / (k^2 + (sigma / SIGMA_LENGTH)^2), to
    within one step of the length grid: 0.3 m weighed as a label's side (2 px), under 0.1 m as
    a detection's."""
    car = np.array([3.0, 1.65, 40.0, 1.5, 1.8, 4.2, 0.1])
    bbox = project_boxes(car[None], CALIB, (WIDTH, 375), upright="lidar")[0]
    longer = car.copy()
    longer[5] += 0.01
    longer[[0, 2]] += 0.005 * np.array([np.cos(car[6]), -np.sin(car[6])])  # the rear face kept
    k = (project_boxes(longer[None], CALIB, (WIDTH, 375), upright="lidar")[0][2] - bbox[2]) / 0.01
    bbox[2] += 6.0
    slide = 0.5 * np.array([np.cos(car[6]), -np.sin(car[6])])
    step = 0.01 * car[5]
    for sigma in (LABEL_SIDE_SIGMA_PX, detection_side_sigma(10.3)):
        length = length_from_sides(car[:3].copy(), *car[3:6], car[6], slide, bbox, P, WIDTH, PLANE,
                                   LIDAR_UP, sigma, np.inf)[1]
        expected = 6.0 * k / (k ** 2 + (sigma / SIGMA_LENGTH) ** 2)
        assert abs(length - car[5] - expected) <= step
    assert 6.0 * k / (k ** 2 + (LABEL_SIDE_SIGMA_PX / SIGMA_LENGTH) ** 2) > 0.25
    assert 6.0 * k / (k ** 2 + (detection_side_sigma(10.3) / SIGMA_LENGTH) ** 2) < 0.1


def test_side_cost_is_gaussian_near_and_heavy_tailed_far():
    """Student-t sides: (dof + 1) log(1 + (miss / sigma)^2 / dof) a side, (dof + 1) / dof times
    the Gaussian's (miss / sigma)^2 for a miss far under sigma, growing with the log of it far
    out, so a side 30 px off costs a ninth of the Gaussian's; sides cut by the border cost
    nothing either way."""
    bbox = project_boxes(CAR[None], CALIB, (WIDTH, 375), upright="camera")[0]
    sigma, dof = 3.0, 1.6
    for miss in (0.3, 30.0):
        moved = bbox + np.array([0.0, 0.0, miss, 0.0])
        t = side_cost(CAR[None], P, moved, WIDTH, CAMERA_UP, sigma, dof)[0]
        g = side_cost(CAR[None], P, moved, WIDTH, CAMERA_UP, sigma, np.inf)[0]
        assert g == pytest.approx((miss / sigma) ** 2, rel=1e-6)
        assert t == pytest.approx((dof + 1) * np.log1p((miss / sigma) ** 2 / dof), rel=1e-6)
        if miss < sigma:
            assert t == pytest.approx(g * (dof + 1) / dof, rel=0.01)
        else:
            assert t < g / 9
    cut = bbox.copy()
    cut[0], cut[2] = 0.0, WIDTH - 1.0
    assert side_cost(CAR[None], P, cut, WIDTH, CAMERA_UP, sigma, dof)[0] == 0.0
