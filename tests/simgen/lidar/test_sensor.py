"""The LiDAR's error model: noise, per-laser bias, detection threshold, drop-out, weather,
reflectance, and the KITTI-like totals of a default sweep."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from simgen.lidar import CLUTTER_ID, preset, scan
from simgen.lidar.weather import rain_extinction
from simgen.world import Material, Part, Weather, World
from tests.simgen.lidar.street import street_world


def _wall_world(d: float, rho: float, weather: Weather | None = None) -> World:
    wall = trimesh.creation.box(bounds=[[d, -400, -50], [d + 1, 400, 80]])
    pose = np.eye(4)
    pose[2, 3] = 1.73
    return World(actors=[], static=[Part(wall, Material("w", (0.5,) * 3, rho))],
                 weather=weather or Weather(), lidar_pose=pose)


def _r(s) -> np.ndarray:
    return np.linalg.norm(s.points[:, :3].astype(np.float64), axis=1)


def _facing(s, half_angle_deg=2.0) -> np.ndarray:
    """Returns within a few degrees of normal incidence on the wall ahead."""
    el = np.arctan2(s.points[:, 2], np.hypot(s.points[:, 0], s.points[:, 1]))
    lim = np.deg2rad(half_angle_deg)
    return (np.abs(s.azimuth) < lim) & (np.abs(el) < lim)


def test_range_exponent_fits_both_datasheet_points():
    spec = preset("hdl64e")
    assert spec.power(np.array([0.1]), np.array([50.0]))[0] == pytest.approx(1.0)
    assert spec.power(np.array([0.8]), np.array([120.0]))[0] == pytest.approx(1.0)
    rho = np.random.default_rng(0).uniform(0, 1, 10_000).astype(np.float32)
    dist = np.random.default_rng(1).uniform(1, 120, 10_000).astype(np.float32)
    p = spec.power(rho, dist)
    clear = np.abs(p - 1) > 1e-4  # away from float32 rounding at the threshold itself
    assert np.array_equal(spec.detected(rho, dist)[clear], (p >= 1)[clear])


def test_dark_far_surfaces_vanish_first():
    spec = replace(preset("hdl64e"), dropout=0.0)
    # 10 % wall: seen head-on at 45 m, gone at 55 m; an 80 % wall still seen at 110 m
    assert _facing(scan(_wall_world(45.0, 0.1), spec, 0)).sum() > 50
    assert _facing(scan(_wall_world(55.0, 0.1), spec, 0)).sum() == 0
    assert _facing(scan(_wall_world(110.0, 0.8), spec, 0)).sum() > 50
    # at a fixed range, oblique (grazing) parts of a dark wall vanish before the facing part
    # (detected iff cos >= (r / 50)^g with r = 40 / cos, i.e. cos >= 0.8^(g / (1 + g)))
    s = scan(_wall_world(40.0, 0.1), replace(spec, noise_sigma=0.0, bias_sigma=0.0), 0)
    cos_inc = 40.0 / _r(s)
    g = spec.range_exponent
    bound = 0.8 ** (g / (1 + g))
    assert bound > 0.8 and cos_inc.min() >= bound - 1e-4 and cos_inc.min() < bound + 0.01


def test_noise_and_per_laser_bias_statistics():
    d = 20.0
    spec = replace(preset("hdl64e"), dropout=0.0, noise_sigma=0.02, bias_sigma=0.05)
    w = _wall_world(d, 0.8)
    s1, s2 = scan(w, spec, 1), scan(w, spec, 2)
    ideal = scan(w, replace(spec, noise_sigma=0.0, bias_sigma=0.0), 0)
    assert len(s1) == len(ideal)
    err1 = _r(s1) - _r(ideal)
    err2 = _r(s2) - _r(ideal)
    bias = spec.laser_biases()
    # per ring, the mean error is the laser's fixed bias (same in both frames)
    for ring in (0, 20, 63):
        m = s1.ring == ring
        assert err1[m].mean() == pytest.approx(bias[ring], abs=0.003)
        assert err2[m].mean() == pytest.approx(bias[ring], abs=0.003)
        assert err1[m].std() == pytest.approx(0.02, rel=0.1)
    # the ray noise differs between frames, the biases do not
    assert not np.allclose(err1, err2)
    assert np.allclose(bias, replace(spec, name="other").laser_biases())
    assert not np.allclose(bias, replace(spec, unit_seed=1).laser_biases())


def test_dropout_rate():
    spec = replace(preset("hdl64e"), dropout=0.1, noise_sigma=0.0, bias_sigma=0.0)
    w = _wall_world(10.0, 0.8)
    n_all = len(scan(w, replace(spec, dropout=0.0), 0))
    n = len(scan(w, spec, 0))
    assert n / n_all == pytest.approx(0.9, abs=0.005)


def test_reflectance_follows_reflectivity_and_incidence():
    # the reading model pinned in detail in test_reflectance.py; here the default sensor: a 0.6
    # wall at 20 m reads 0.6 * cos(incidence) times the laser's gain and scatter, floored and
    # quantised as KITTI writes it
    spec = replace(preset("hdl64e"), dropout=0.0, noise_sigma=0.0, bias_sigma=0.0)
    d = 20.0
    s = scan(_wall_world(d, 0.6), spec, 0)
    near = _r(s) < 25.0  # inside the range floor's reach (0.489 * (25 / 50) ** 2.375 = 0.094)
    v = s.points[near, 3].astype(np.float64)
    lit = v > 0
    ratio = v[lit] / (0.6 * d / _r(s)[near][lit] * spec.laser_gains()[s.ring[near][lit]])
    assert np.median(ratio) == pytest.approx(1.0, abs=0.03)  # the scatter's median is 1
    q = s.points[:, 3].astype(np.float64) * 100
    np.testing.assert_allclose(q, np.round(q), atol=1e-4)  # 0.01 steps, as in KITTI
    assert s.points[:, 3].max() <= np.float32(0.99)
    # zero readings: the lasers' zero shares (mean about 0.1) on this bright, near wall
    assert 0.03 < (v == 0).mean() < 0.25


def test_fog_attenuates_and_adds_near_scatter():
    spec = preset("hdl64e")
    clear = scan(street_world(5), spec, 0)
    fog = Weather(fog_extinction=0.06)  # visibility 50 m
    w = street_world(5, weather=fog)
    foggy = scan(w, spec, 0)
    r_clear, r_fog = _r(clear), _r(foggy)
    assert (r_fog > 30).sum() < 0.5 * (r_clear > 30).sum()
    clutter = foggy.actor_id == CLUTTER_ID
    assert clutter.sum() > 100
    assert _r(foggy)[clutter].max() < 15.0  # scatter echoes only near the sensor
    assert not np.any(clear.actor_id == CLUTTER_ID)
    assert scan(w, replace(spec, weather=False), 0).points.tobytes() == clear.points.tobytes()


def test_rain_extinction_and_clutter():
    # Marshall-Palmer optical extinction: pi N0 / Lambda^3 with Lambda = 4.1 R^-0.21
    assert rain_extinction(10.0) == pytest.approx(np.pi * 8000 / (4.1 * 10 ** -0.21) ** 3 * 1e-6)
    assert rain_extinction(0.0) == 0.0
    spec = preset("hdl64e")
    clear = scan(street_world(6), spec, 0)
    rainy = scan(street_world(6, weather=Weather(rain_rate=25.0)), spec, 0)
    clutter = rainy.actor_id == CLUTTER_ID
    assert 0.002 < clutter.mean() < 0.05
    assert _r(rainy)[clutter].max() < 15.0
    assert (_r(rainy) > 40).sum() < (_r(clear) > 40).sum()


def test_default_hdl64e_street_sweep_is_kitti_like():
    s = scan(street_world(0), preset("hdl64e"), 0)
    r = _r(s)
    assert 110_000 <= len(s) <= 128_000  # KITTI: 115k-127k
    assert 6.0 < np.median(r) < 16.0  # KITTI street: about 10 m
    assert (r > 80).mean() < 0.02
    assert np.all(np.abs(s.time) <= 0.05) and s.time.dtype == np.float32
    # per ring in firing order: time rises, azimuth falls (clockwise head)
    ring0 = s.ring == 40
    assert np.all(np.diff(s.time[ring0]) > 0) and np.all(np.diff(s.azimuth[ring0]) < 0)
