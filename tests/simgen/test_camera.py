"""The colour camera (simgen.camera): metering, vignetting, noise and demosaicing against the
values their definitions give."""

from __future__ import annotations

import numpy as np
import pytest

from simgen.camera import CROSSTALK, GAMMA, KEY, LOG_FLOOR, _noisy, _vignetting, expose
from simgen.world import CameraResponse

K = np.array([[721.5, 0.0, 609.6], [0.0, 721.5, 172.9], [0.0, 0.0, 1.0]])
CLEAN = CameraResponse(white_balance_sd=0.0, corner_illumination=1.0, blur_sigma_px=0.0,
                       full_well_e=0.0, bayer=False)


def _linear(img8: np.ndarray, gamma: float = GAMMA) -> np.ndarray:
    return (img8.astype(np.float64) / 255.0) ** gamma


@pytest.mark.parametrize("ev, gamma", [(-1.0, 2.2), (0.0, 2.2), (0.5, 2.2), (0.0, 1.0), (0.0, 1.2)])
def test_auto_exposure_brings_the_log_average_luminance_to_the_key(ev, gamma):
    rng = np.random.default_rng(0)
    lin = rng.uniform(0.02, 0.3, (120, 160, 3))
    out = expose(lin, K, CameraResponse(**{**CLEAN.__dict__, "exposure_ev": ev, "gamma": gamma}), rng)
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
    out = expose(lin, K, cam, np.random.default_rng(0))
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
    grey = expose(np.full((32, 32, 3), 0.2), K, cam, np.random.default_rng(0))[4:-4, 4:-4]
    assert np.ptp(grey.reshape(-1, 3).mean(axis=0)) == 0
    red = np.zeros((32, 32, 3))
    red[..., 0] = 0.2
    out = expose(red, K, cam, np.random.default_rng(0))[4:-4, 4:-4].reshape(-1, 3).mean(axis=0)
    # Linear output: green and blue each get CROSSTALK / (1 - 2 CROSSTALK) of red's signal.
    assert out[1] == out[2]
    assert out[1] / out[0] == pytest.approx(CROSSTALK / (1 - 2 * CROSSTALK), abs=0.01)


def test_same_generator_same_image_and_noise_changes_it():
    lin = np.random.default_rng(3).uniform(0.0, 0.5, (50, 70, 3))
    cam = CameraResponse()
    a = expose(lin, K, cam, np.random.default_rng(9))
    b = expose(lin, K, cam, np.random.default_rng(9))
    c = expose(lin, K, cam, np.random.default_rng(10))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
