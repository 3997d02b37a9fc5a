"""Weather and sensor looks: Koschmieder fog from the depth, seeded rain, sensor emulations."""

from __future__ import annotations

import numpy as np
import pytest

from simgen.look import AIRLIGHT, apply_look, fog, ray_length
from simgen.world import Light, Weather

K = np.array([[700.0, 0.0, 20.0], [0.0, 700.0, 10.0], [0.0, 0.0, 1.0]])


def test_ray_length_is_depth_times_the_ray_slope_and_inf_for_the_sky():
    depth = np.full((21, 41), 10.0)
    depth[0, 0] = 0.0
    r = ray_length(depth, K)
    assert r[10, 20] == 10.0  # the principal point's ray is the optical axis
    u, v = 40, 20
    assert r[v, u] == pytest.approx(10.0 * np.sqrt(1 + ((u - 20) / 700) ** 2 + ((v - 10) / 700) ** 2))
    assert np.isinf(r[0, 0])


def test_fog_follows_koschmieder_with_the_worlds_extinction():
    img = np.zeros((21, 41, 3))
    img[..., 1] = 1.0
    depth = np.full((21, 41), 50.0)
    depth[:, :5] = 0.0  # sky
    beta = 0.03
    out = fog(img, depth, K, beta, "day")
    t = np.exp(-beta * 50.0)
    np.testing.assert_allclose(out[10, 20], np.array([0, 1, 0]) * t + np.array(AIRLIGHT["day"]) * (1 - t))
    np.testing.assert_allclose(out[3, 2], AIRLIGHT["day"])


def test_looks_are_deterministic_and_change_the_image_as_documented():
    rng_img = np.random.default_rng(0)
    color = rng_img.integers(0, 256, (60, 80, 3), dtype=np.uint8)
    depth = rng_img.uniform(2.0, 80.0, (60, 80)).astype(np.float32)
    light = Light()
    clear = apply_look(color, depth, K, Weather(), light, "normal", np.random.default_rng(1))
    assert np.array_equal(clear, color)  # no weather, normal sensor: the render itself
    rain = [apply_look(color, depth, K, Weather(rain_rate=30.0, wind=10.0), light, "normal",
                       np.random.default_rng(1)) for _ in range(2)]
    assert np.array_equal(rain[0], rain[1]) and not np.array_equal(rain[0], color)
    nv = apply_look(color, depth, K, Weather(), light, "night_vision", np.random.default_rng(1))
    assert np.all(nv[..., 1] >= nv[..., 0]) and np.all(nv[..., 1] >= nv[..., 2])  # green phosphor
    th = apply_look(color, depth, K, Weather(), light, "thermal", np.random.default_rng(1))
    assert np.array_equal(th[..., 0], th[..., 1]) and np.array_equal(th[..., 1], th[..., 2])
