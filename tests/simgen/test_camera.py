"""The colour camera (simgen.camera): metering, vignetting, noise, demosaicing and KITTI's
rectification against the values their definitions and KITTI's calibration give."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from simgen.camera import (BALANCE, CROSSTALK, GAMMA, KEY, LOG_FLOOR, LUMA, _noisy, _vignetting,
                           distort, expose, rectification, undistort)
from simgen.world import CameraResponse

K = np.array([[721.5, 0.0, 609.6], [0.0, 721.5, 172.9], [0.0, 0.0, 1.0]])
CLEAN = CameraResponse(white_balance_sd=0.0, corner_illumination=1.0, blur_sigma_px=0.0,
                       full_well_e=0.0, bayer=False)
NEUTRAL = (1.0, 1.0, 1.0)  # no colour balance: the other steps alone


def _linear(img8: np.ndarray, gamma: float = GAMMA) -> np.ndarray:
    return (img8.astype(np.float64) / 255.0) ** gamma


@pytest.mark.parametrize("ev, gamma", [(-1.0, 2.2), (0.0, 2.2), (0.5, 2.2), (0.0, 1.0), (0.0, 1.2)])
def test_auto_exposure_brings_the_log_average_luminance_to_the_key(ev, gamma):
    rng = np.random.default_rng(0)
    lin = rng.uniform(0.02, 0.3, (120, 160, 3))
    out = expose(lin, K, CameraResponse(**{**CLEAN.__dict__, "exposure_ev": ev, "gamma": gamma}), rng,
                 balance=NEUTRAL)
    w = np.array([0.2126, 0.7152, 0.0722])
    lum = _linear(out, gamma) @ w
    # The meter reads every 4th pixel of every 4th row.
    gain = KEY / np.exp(np.log(LOG_FLOOR + lin[::4, ::4] @ w).mean()) * 2.0 ** ev
    # 8-bit quantisation of a gamma-encoded value moves the linear mean by well under 1 %.
    assert lum.mean() == pytest.approx(gain * (lin @ w).mean(), rel=0.005)


def test_vignetting_is_one_on_the_axis_and_the_set_value_at_the_farthest_corner():
    v = _vignetting(375, 1242, K, 0.7)
    assert v.max() == pytest.approx(1.0, abs=1e-5)
    assert v.min() == pytest.approx(0.7, abs=1e-12)
    # The farthest corner from the principal point (609.6, 172.9) is the bottom right.
    assert v[374, 1241] == pytest.approx(0.7, abs=1e-12)
    assert np.unravel_index(v.argmax(), v.shape) == (173, 610)


def test_noise_has_the_shot_plus_read_variance_of_the_signal():
    cam = CameraResponse(full_well_e=5000.0, read_noise_e=20.0)
    signal = np.full((400, 400), 0.3, np.float32)
    out = _noisy(signal, cam, np.random.default_rng(1))
    expected_sd = np.sqrt(0.3 * 5000.0 + 20.0 ** 2) / 5000.0
    # 160,000 samples: the sample sd is within 1 % of the true one (its relative sd is 0.18 %).
    assert out.std() == pytest.approx(expected_sd, rel=0.01)
    assert out.mean() == pytest.approx(0.3, abs=4 * expected_sd / 400)


def test_demosaicing_a_uniform_colour_gives_back_its_mix_through_the_colour_filters():
    c = np.array([0.05, 0.10, 0.20])
    lin = np.broadcast_to(c, (64, 96, 3)).copy()
    cam = CameraResponse(**{**CLEAN.__dict__, "bayer": True})
    out = expose(lin, K, cam, np.random.default_rng(0), balance=NEUTRAL)
    inner = out[2:-2, 2:-2].reshape(-1, 3)
    assert np.ptp(inner, axis=0).max() <= 1  # one grey level of rounding
    # Each channel keeps 1 - 2 s of its own light and s of each other's (s = CROSSTALK), then
    # the exposure scales all three alike: by hand, 0.7 R + 0.15 (G + B) and so on.
    mixed = (1 - 2 * CROSSTALK) * c + CROSSTALK * (c.sum() - c)
    gain = KEY / np.exp(np.log(LOG_FLOOR + c @ np.array([0.2126, 0.7152, 0.0722])))
    expected = np.round((gain * mixed) ** (1 / cam.gamma) * 255)
    assert np.abs(inner.mean(axis=0) - expected).max() <= 0.5


def test_grey_stays_grey_through_the_colour_filters_and_a_primary_is_desaturated():
    cam = CameraResponse(**{**CLEAN.__dict__, "bayer": True, "gamma": 1.0, "exposure_ev": -1.0})
    grey = expose(np.full((32, 32, 3), 0.2), K, cam, np.random.default_rng(0),
                  balance=NEUTRAL)[4:-4, 4:-4]
    assert np.ptp(grey.reshape(-1, 3).mean(axis=0)) == 0
    red = np.zeros((32, 32, 3))
    red[..., 0] = 0.2
    out = expose(red, K, cam, np.random.default_rng(0), balance=NEUTRAL)[4:-4, 4:-4]
    out = out.reshape(-1, 3).mean(axis=0)
    # Linear output: green and blue each get CROSSTALK / (1 - 2 CROSSTALK) of red's signal.
    assert out[1] == out[2]
    assert out[1] / out[0] == pytest.approx(CROSSTALK / (1 - 2 * CROSSTALK), abs=0.01)


@pytest.mark.parametrize("bayer", [True, False])
def test_colour_balance_tints_a_grey_by_its_gains_keeps_its_luminance_and_clips_white_white(bayer):
    cam = CameraResponse(**{**CLEAN.__dict__, "bayer": bayer, "gamma": 1.0, "exposure_ev": 1.0})
    out = expose(np.full((32, 32, 3), 0.2), K, cam, np.random.default_rng(0))[4:-4, 4:-4]
    out = out.reshape(-1, 3).mean(axis=0)
    # Linear output: the exposed grey (key over the log average, one stop up) times each
    # channel's gain over the gains' luminance (the meter reads the balanced image), by hand.
    level = 255.0 * KEY / (LOG_FLOOR + 0.2) * 2.0 * 0.2
    expected = level * np.asarray(BALANCE) / float(LUMA @ np.asarray(BALANCE))
    assert np.abs(out - expected).max() <= 0.5 + 1e-9  # 8-bit rounding
    assert float(LUMA @ out) == pytest.approx(level, abs=0.5)
    assert min(out[1], out[2]) > out[0]  # KITTI's blue-green cast: green and blue above red
    # A pixel that saturates the sensor comes out white, as KITTI's skies do.
    scene = np.full((32, 32, 3), 0.05)
    scene[8:24] = 50.0
    assert (expose(scene, K, cam, np.random.default_rng(0))[10:22, 4:-4] == 255).all()


def test_same_generator_same_image_and_noise_changes_it():
    lin = np.random.default_rng(3).uniform(0.0, 0.5, (50, 70, 3))
    cam = CameraResponse()
    a = expose(lin, K, cam, np.random.default_rng(9))
    b = expose(lin, K, cam, np.random.default_rng(9))
    c = expose(lin, K, cam, np.random.default_rng(10))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


# KITTI's raw colour camera 02 (calib_cam_to_cam.txt of 2011_09_26) and its rectified image.
KITTI = np.array([[721.5377, 0.0, 609.5593], [0.0, 721.5377, 172.854], [0.0, 0.0, 1.0]])
RAW_FX, RAW_FY = 959.7910, 956.9251
D02 = (-0.3691481, 0.1968681, 0.001353473, 0.0005677587, -0.06770705)


def _raw_u(u: float, v: float) -> float:
    """A rectified pixel's raw column, by OpenCV's distortion model written out (up to the raw
    frame's offset)."""
    k1, k2, p1, p2, k3 = D02
    x, y = (u - KITTI[0, 2]) / KITTI[0, 0], (v - KITTI[1, 2]) / KITTI[1, 1]
    r2 = x * x + y * y
    return RAW_FX * (x * (1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3) + 2 * p1 * x * y + p2 * (r2 + 2 * x * x))


def _forward(rect) -> tuple[np.ndarray, np.ndarray]:
    return cv2.convertMaps(*rect.output_from_raw, cv2.CV_32FC1)


def test_the_raw_frame_is_kittis_sensor_seen_through_its_lens():
    rect = rectification(375, 1242, tuple(KITTI[[0, 1, 0, 1], [0, 1, 2, 2]]))
    # The rectified frame comes from within the Flea2's 1392 x 512 raw frame.
    raw_h, raw_w = rect.raw_from_output[0].shape[:2]
    assert raw_h <= 512 and raw_w <= 1392
    mx, _ = _forward(rect)
    # Raw pixels per output pixel along the row through the principal point: 1.33 at the centre,
    # where the distortion is nil; 0.72 at the left edge and 0.69 at the right, where the barrel
    # distortion packed the scene tighter (finite differences of the model written out above).
    for u0 in (0, 609, 1239):
        hand = (_raw_u(u0 + 2, 173) - _raw_u(u0, 173)) / 2
        assert (mx[173, u0 + 2] - mx[173, u0]) / 2 == pytest.approx(hand, abs=1 / 32)
    assert (_raw_u(611, 173) - _raw_u(609, 173)) / 2 == pytest.approx(RAW_FX / KITTI[0, 0], rel=1e-5)
    assert (_raw_u(2, 173) - _raw_u(0, 173)) / 2 == pytest.approx(0.718, abs=0.005)


def test_undistort_inverts_distort_over_the_raw_frame():
    xd, yd = np.meshgrid(np.linspace(-0.69, 0.71, 141), np.linspace(-0.24, 0.28, 53))
    x, y = undistort(xd, yd)
    a, b = distort(x, y)
    assert np.abs(a - xd).max() < 1e-12 and np.abs(b - yd).max() < 1e-12


@pytest.mark.parametrize("edge", [100.5, 609.5, 1100.5])
def test_the_rectified_camera_leaves_an_edge_where_it_was(edge):
    """A vertical step from dark to light keeps its place to a tenth of a pixel at the centre
    and at both sides: the labels' boxes stay the image's."""
    lin = np.full((375, 1242, 3), 0.05)
    lin[:, int(edge + 0.5):] = 0.4
    cam = CameraResponse(**{**CLEAN.__dict__, "bayer": True, "gamma": 1.0})
    grey = expose(lin, KITTI, cam, np.random.default_rng(0))[150:200].astype(float).mean(axis=(0, 2))
    lo, hi = grey[int(edge) - 8], grey[int(edge) + 9]
    half = (lo + hi) / 2
    i = int(np.flatnonzero(grey > half)[0])
    crossing = i - 1 + (half - grey[i - 1]) / (grey[i] - grey[i - 1])
    assert crossing == pytest.approx(edge, abs=0.1)


def test_rectification_takes_the_colour_fringes_off_an_edge_and_softens_the_sides():
    lin = np.full((375, 1242, 3), 0.05)
    lin[:, 610:] = 0.4  # grey stays grey: any colour at the edge is the mosaic's
    fringe = {}
    for rectified in (False, True):
        cam = CameraResponse(**{**CLEAN.__dict__, "bayer": True, "gamma": 1.0, "rectified": rectified})
        out = expose(lin, KITTI, cam, np.random.default_rng(0))[150:200, 600:620].astype(float)
        fringe[rectified] = np.ptp(out, axis=2).max()
    assert fringe[True] < 0.6 * fringe[False]
    # Stripes 3 px wide: where the rectification enlarges the raw pixels (the sides) they keep
    # less of their contrast than at the centre, where it shrinks them.
    stripes = np.full((375, 1242, 3), 0.05)
    stripes[:, (np.arange(1242) // 3) % 2 == 1] = 0.4
    cam = CameraResponse(**{**CLEAN.__dict__, "bayer": True, "gamma": 1.0})
    grey = expose(stripes, KITTI, cam, np.random.default_rng(0))[150:200].astype(float).mean(axis=(0, 2))
    assert np.ptp(grey[20:60]) < 0.8 * np.ptp(grey[590:630])
