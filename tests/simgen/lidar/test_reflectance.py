"""The reflectance channel and the drop model against hand-computed values: reading of a target
of known reflectivity at known range and incidence, the floors, KITTI's quantisation, per-laser
gain, zero share and drop-out, the reading scatter, glass and leaves that rays pass."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from simgen.lidar import preset, scan
from simgen.lidar.scan import GLASS_R0
from simgen.materials import FOLIAGE, GLASS
from simgen.world import Material, Part, Weather, World

G = 2.375  # hdl64e range exponent: ln(0.8 / 0.1) / ln(120 / 50)


def _spec(**kw):
    """hdl64e with every random part off: exact ranges, every detected return kept, readings
    without per-laser gains, scatter or zero readings; every beam from the origin (the source
    offsets are geometry, tested in test_geometry), so a return's range is its norm."""
    base = {"noise_sigma": 0.0, "bias_sigma": 0.0, "dropout": 0.0, "gain_sigma": 0.0,
            "reading_sigma": 0.0, "zero_share_median": 0.0, "motion": False, "source_offsets_m": ()}
    return replace(preset("hdl64e"), **{**base, **kw})


def _world(*parts: Part, height: float = 1.73) -> World:
    pose = np.eye(4)
    pose[2, 3] = height
    return World(actors=[], static=list(parts), weather=Weather(), lidar_pose=pose)


def _wall(d: float, mat: Material, thick: float = 1.0, y: float = 400.0) -> Part:
    return Part(trimesh.creation.box(bounds=[[d, -y, -50], [d + thick, y, 80]]), mat)


def _mat(rho: float, k: float = 1.0, **kw) -> Material:
    return Material("m", (0.5, 0.5, 0.5), rho, incidence_exponent=k, **kw)


def _r(s) -> np.ndarray:
    return np.linalg.norm(s.points[:, :3].astype(np.float64), axis=1)


def _clamp(d: np.ndarray) -> np.ndarray:
    """refl_floor_power * 0.1 * (d / 50) ** 2.375 for the hdl64e defaults: an echo below it reads 0."""
    return 4.89 * 0.1 * (d / 50.0) ** G


def _expected(s_true: np.ndarray, d: np.ndarray) -> np.ndarray:
    """What the sensor writes for a true reading s at range d: 0 below the clamp, dimmed by
    (36 / d) ** 2.375 beyond the compensation range (36 m), 0 below 0.025, else rounded to 0.01,
    at most 0.99."""
    s = s_true * np.minimum(1.0, (36.0 / d) ** G)
    keep = (s_true >= _clamp(d)) & (s >= 0.025)
    return np.where(keep, np.minimum(np.round(s * 100), 99) / 100, 0.0)


def _agree(got: np.ndarray, want: np.ndarray) -> None:
    """Equal except where float32 rounding lands a value on the other side of a 0.005 step or of
    the floor (a handful of returns)."""
    off = np.abs(got - want) > 1e-6
    assert off.mean() < 0.002
    assert np.all(np.abs(got - want)[off] <= 0.0101) or off.sum() < 5


def test_lambertian_target_reads_reflectivity_times_cos():
    # 0.6 wall at 20 m: cos(incidence) = 20 / r; straight ahead it reads 0.60
    s = scan(_world(_wall(20.0, _mat(0.6))), _spec(), 0)
    r = _r(s)
    _agree(s.points[:, 3], _expected(0.6 * 20.0 / r, r))
    ahead = r < 20.02
    assert ahead.sum() > 10 and np.all(s.points[ahead, 3] == np.float32(0.6))
    # KITTI's format: float32(k / 100), k = 0..99
    k = np.round(s.points[:, 3].astype(np.float64) * 100)
    assert np.array_equal(np.float32(k / 100), s.points[:, 3]) and k.max() <= 99


def test_rough_ground_material_reads_flat_in_incidence():
    # incidence_exponent 0 (Lommel-Seeliger): a 0.24 wall reads 0.24 at every angle out to the
    # compensation range (36 m), a little less beyond, until the clamp passes it: 0.489 * (d / 50)
    # ** 2.375 = 0.24 at d = 50 * (0.24 / 0.489) ** (1 / 2.375) = 37.0 m (KITTI's road reads 0
    # half the time there)
    s = scan(_world(_wall(20.0, _mat(0.24, k=0.0))), _spec(), 0)
    r, v = _r(s), s.points[:, 3]
    d_star = 50.0 * (0.24 / 0.489) ** (1 / G)
    assert d_star == pytest.approx(37.0, abs=0.1)
    assert np.all(v[r < 36.0] == np.float32(0.24))
    _agree(v[r >= 36.0], _expected(np.full((r >= 36.0).sum(), 0.24), r[r >= 36.0]))
    assert np.all(v[(r > 36.5) & (r < d_star - 0.3)] == np.float32(0.23))  # 0.24 * (36 / d) ** 2.375
    assert np.all(v[r > d_star + 0.3] == 0.0)
    assert (r > d_star + 0.3).sum() > 100  # detected there (0.24 >= 0.1 * (d / 50) ** 2.375) but read 0


def test_low_readings_floor_to_zero_and_bright_ones_saturate():
    spec = _spec()

    def ahead(s):
        return s.points[_r(s) < 10.02, 3]

    assert np.all(ahead(scan(_world(_wall(10.0, _mat(0.02))), spec, 0)) == 0.0)  # below 0.025
    assert np.all(ahead(scan(_world(_wall(10.0, _mat(0.03))), spec, 0)) == np.float32(0.03))
    # the range floor: a 0.3 wall reads 0.30 at 30 m (floor 0.146) but 0 at 45 m (floor 0.381),
    # where it is still detected (threshold 0.1 * (45 / 50) ** 2.375 = 0.078)
    s30 = scan(_world(_wall(30.0, _mat(0.3))), spec, 0)
    s45 = scan(_world(_wall(45.0, _mat(0.3))), spec, 0)
    assert np.all(s30.points[_r(s30) < 30.05, 3] == np.float32(0.3))
    assert (_r(s45) < 45.05).sum() > 10 and np.all(s45.points[_r(s45) < 45.05, 3] == 0.0)
    # a retro-reflector saturates at KITTI's largest value, 0.99
    s = scan(_world(_wall(10.0, _mat(220.0, k=6.0))), spec, 0)
    assert np.all(ahead(s) == np.float32(0.99))
    # no near-range over-read: a 0.2 wall at 2.5 m reads 0.20
    s = scan(_world(_wall(2.5, _mat(0.2))), spec, 0)
    assert np.all(s.points[_r(s) < 2.502, 3] == np.float32(0.2))


def test_far_readings_dim_beyond_the_compensation_range():
    # a 0.9 wall (flat in incidence) clears the clamp at 50 m (0.489) and 60 m (0.754) but reads
    # 0.9 * (36 / 50) ** 2.375 = 0.41 and 0.9 * (36 / 60) ** 2.375 = 0.27 straight ahead
    for d, want in ((50.0, 0.41), (60.0, 0.27)):
        s = scan(_world(_wall(d, _mat(0.9, k=0.0))), _spec(), 0)
        ahead = _r(s) < d + 0.05
        assert ahead.sum() > 10 and np.all(s.points[ahead, 3] == np.float32(want))
    assert 0.9 * (36 / 50) ** G == pytest.approx(0.4125, abs=1e-4)
    assert 0.9 * (36 / 60) ** G == pytest.approx(0.2675, abs=1e-4)


def test_the_clamp_draws_its_own_scatter():
    # a 0.2 wall at 34.3 m, where the clamp is 0.2 (0.489 * (34.3 / 50) ** 2.375), inside the
    # compensation range: half its returns read 0, and the rest read about 0.20, not the upper half
    # of the scatter (0.2 * 3 ** (0.31 / (1.4826 ln 3)) = 0.247, had the clamp used the reading's draw)
    assert 0.489 * (34.3 / 50) ** G == pytest.approx(0.2, abs=0.001)
    s = scan(_world(_wall(34.3, _mat(0.2, k=0.0))), _spec(reading_sigma=0.31), 0)
    near = _r(s) < 34.5
    v = s.points[near, 3]
    n = near.sum()
    assert n > 300
    assert (v == 0).mean() == pytest.approx(0.5, abs=0.03 + 3 * np.sqrt(0.25 / n))
    assert np.median(v[v > 0]) == pytest.approx(0.2, abs=0.012)


def test_per_laser_gain_is_fixed_per_unit():
    spec = _spec(gain_sigma=0.225)
    g = spec.laser_gains()
    s = scan(_world(_wall(10.0, _mat(0.3))), spec, 0)
    ahead = _r(s) < 10.02
    want = np.minimum(np.round(0.3 * g[s.ring[ahead]] * 100), 99) / 100
    diff = np.abs(s.points[ahead, 3] - want)  # a laser right on a 0.005 step may round the other way
    assert np.all(diff < 0.0101) and (diff < 1e-6).mean() > 0.9
    assert len(np.unique(s.points[ahead, 3])) > 5  # the lasers read differently
    many = replace(spec, lasers=tuple(range(200)), elevations_deg=tuple(np.linspace(2, -24.9, 200)))
    assert np.std(np.log(many.laser_gains())) == pytest.approx(0.225, rel=0.2)  # log-sd gain_sigma
    assert np.median(many.laser_gains()) == pytest.approx(1.0, abs=0.06)
    assert np.array_equal(preset("hdl64e", beams=32).laser_gains(), preset("hdl64e").laser_gains()[::2])
    assert not np.allclose(g, replace(spec, unit_seed=1).laser_gains())


def test_per_laser_zero_share_and_dropout_rates():
    # zero shares 0.2 on every laser (sigma 0), drop-out 0.1 +- 0.05 per laser
    spec = _spec(zero_share_median=0.2, zero_share_sigma=0.0, dropout=0.1, dropout_sigma=0.05)
    w = _world(_wall(10.0, _mat(0.5)))
    full = scan(w, _spec(), 0)
    s = scan(w, spec, 0)
    n_all = np.bincount(full.ring, minlength=64)
    n = np.bincount(s.ring, minlength=64)
    rate = spec.laser_dropouts()
    seen = n_all > 500
    kept = n[seen] / n_all[seen]
    sd = np.sqrt(rate[seen] * (1 - rate[seen]) / n_all[seen])
    assert np.all(np.abs(kept - (1 - rate[seen])) <= 4 * sd + 1e-9)
    assert rate.std() > 0.02  # the lasers do differ
    near = _r(s) < 20.0  # nearer than the range floor's reach on this wall
    zero = (s.points[near, 3] == 0).mean()
    assert zero == pytest.approx(0.2, abs=4 * np.sqrt(0.2 * 0.8 / near.sum()))


def test_reading_scatter_has_the_measured_log_sd():
    spec = _spec(reading_sigma=0.31)
    s = scan(_world(_wall(10.0, _mat(0.5, k=0.0))), spec, 0)
    v = s.points[_r(s) < 30, 3].astype(np.float64)
    lv = np.log(v[v > 0])
    assert np.median(lv) == pytest.approx(np.log(0.5), abs=0.02)
    robust_sd = 1.4826 * np.median(np.abs(lv - np.median(lv)))  # as measured on KITTI's road
    assert robust_sd == pytest.approx(0.31, rel=0.08)


def test_porous_leaves_pass_the_expected_share():
    # a closed 1 m block of leaves at 10 m in front of a wall at 20 m: a ray passes each face
    # with p = 0.45, so (1 - p) return from the front face, p (1 - p) from the back face, p^2
    # from the wall
    p = FOLIAGE.porosity
    assert p == 0.45
    hedge = Part(trimesh.creation.box(bounds=[[10, -30, -50], [11, 30, 80]]), FOLIAGE)
    w = _world(hedge, _wall(20.0, _mat(0.5)))
    spec = _spec()
    s = scan(w, spec, 0)
    x = s.points[:, 0]
    behind = np.abs(s.azimuth) < np.arctan(2.5)  # rays that meet the hedge and then the wall
    n = behind.sum()
    front, back, wall = ((np.abs(x - c) < 0.01) & behind for c in (10.0, 11.0, 20.0))
    assert front.sum() + back.sum() + wall.sum() == n
    for got, share in ((front, 1 - p), (back, p * (1 - p)), (wall, p * p)):
        assert got.sum() / n == pytest.approx(share, abs=4 * np.sqrt(share * (1 - share) / n))
    assert np.all(s.points[front, 3] == np.float32(0.33))  # a leaf volume: 0.50 x 2/3, flat
    # same world and seed, same bytes; another seed passes other rays
    assert scan(w, spec, 0).points.tobytes() == s.points.tobytes()
    assert scan(w, spec, 1).points.tobytes() != s.points.tobytes()
    # ideal(): every surface opaque
    opaque = scan(w, preset("hdl64e").ideal(), 0)
    assert np.all(np.abs(opaque.points[np.abs(opaque.azimuth) < np.arctan(2.5), 0] - 10.0) < 0.01)


def _pane(c: float, t: float = 0.6) -> float:
    fresnel = GLASS_R0 + (1 - GLASS_R0) * (1 - c) ** 5
    return t * ((1 - fresnel) / (1 - GLASS_R0)) ** 2


def test_glass_pane_passes_beams_with_its_two_way_loss():
    # a 2 cm pane at 10 m before a 0.5 wall at 20 m: no echo from the pane; the wall reads
    # 0.5 * cos * T(cos)^2 (T = 0.6 at normal incidence: 0.5 * 0.36 = 0.18 straight ahead)
    pane = Part(trimesh.creation.box(bounds=[[10, -30, -50], [10.02, 30, 80]]), GLASS)
    w = _world(pane, _wall(20.0, _mat(0.5)))
    s = scan(w, _spec(), 0)
    x, r = s.points[:, 0], _r(s)
    through = (np.abs(s.points[:, 1]) < 25) & (s.points[:, 2] > -1.0) & (x > 5)
    assert not np.any(np.abs(x - 10.0) < 0.1)  # the pane itself never returns
    assert np.all(np.abs(x[through] - 20.0) < 0.01)
    cos = 20.0 / r[through]
    want = _expected(0.5 * cos * np.array([_pane(c) ** 2 for c in cos]), r[through])
    _agree(s.points[through, 3], want)
    assert np.all(s.points[through & (r < 20.02), 3] == np.float32(0.18))
    # behind the pane a dark far wall drops out: 0.1 * 0.36 = 0.036 < 0.1 * (45 / 50) ** 2.375
    dark = scan(_world(pane, _wall(45.0, _mat(0.1))), _spec(), 0)
    assert not np.any((np.abs(dark.points[:, 1]) < 25) & (dark.points[:, 0] > 40))
    # without the pane it is seen
    assert np.any(scan(_world(_wall(45.0, _mat(0.1))), _spec(), 0).points[:, 0] > 40)


def _entries(s, x0: float):
    """Per return of a scan from (0, 0, 1.73): its ray's direction (from its ring's elevation and
    its azimuth), and the range, height and y where that ray crosses the plane x = x0."""
    el = np.radians(np.asarray(_spec().elevations_deg)[s.ring])
    az = s.azimuth.astype(np.float64)
    d = np.c_[np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]
    t = x0 / d[:, 0]
    return d, t, 1.73 + t * d[:, 2], t * d[:, 1]


def test_glasshouse_ends_beams_on_the_cabin_where_the_glass_shows_it():
    # a glass solid 2 m deep from x = 5 to 7, z = 0 to 2 (the sensor at 1.73 m), a wall at 20 m.
    # A beam entering the front face at height h = z / 2 of the pane ends 0.25 m behind it (the
    # cabin) on the share of that height the camera's glass tile shows as cabin: all of it below
    # h = 0.35 (trim, cushions), 0.44 of every 0.6 m below 0.5 (seat backs), 0.26 of every 0.6 m
    # at 0.56-0.72 (head restraints), none elsewhere; it reads the interior's 0.13 after one pane.
    # The others pass both panes to the wall (0.5 * 0.6^4 = 0.0648 -> 0.06 straight ahead).
    house = Part(trimesh.creation.box(bounds=[[5, -3, 0.0], [7, 3, 2.0]]), GLASS)
    s = scan(_world(house, _wall(20.0, _mat(0.5))), _spec(), 0)
    d, t, z, y = _entries(s, 5.0)
    r, v = _r(s), s.points[:, 3]
    front = (np.abs(y) < 2.5) & (z > 0.2)  # lower, the solid's floor is nearer than 0.25 m
    cabin = np.abs(r - (t + 0.25)) < 1e-3
    assert np.all(cabin[front] | (np.abs(s.points[front, 0] - 20.0) < 0.01))
    h = z / 2.0
    for lo, hi, share in ((0.1, 0.35, 1.0), (0.35, 0.5, 0.44 / 0.6), (0.5, 0.56, 0.0),
                          (0.56, 0.72, 0.26 / 0.6), (0.72, 1.0, 0.0)):
        band = front & (h >= lo + 0.005) & (h < hi - 0.005)
        assert band.sum() > 300
        if share in (0.0, 1.0):
            assert np.all(cabin[band] == bool(share))
        else:  # an independent draw per beam: within 4 binomial sds of the share
            assert abs(cabin[band].mean() - share) < 4 * np.sqrt(share * (1 - share) / band.sum())
    c_in = d[front & cabin, 0]  # incidence on the front face x = 5
    want = np.round(0.13 * np.array([_pane(c) ** 2 for c in c_in]) * 100) / 100
    assert np.all(np.abs(v[front & cabin] - want) < 0.0101)
    level = np.abs(d[:, 2]) < 0.009
    straight = (np.abs(s.points[:, 1]) < 0.3) & (np.abs(s.points[:, 0] - 20.0) < 0.01) & level
    assert straight.sum() > 0 and np.all(v[straight] == np.float32(0.06))
    assert GLASS.reflectivity == pytest.approx(0.13)


def test_glasshouse_beam_that_leaves_through_its_bottom_returns_from_the_interior():
    # a glass solid from x = 1 to 6, z = 0.5 to 1.5: beams 12-25 deg down, nearly straight ahead,
    # enter its front face at h = 0.74-1.0 of the pane (no cabin there: the scene through the far windows) and leave
    # through its bottom into the vehicle body below the windows, returning from there with the
    # interior's reading after one pane: 0.13 * tr(c)^2
    house = Part(trimesh.creation.box(bounds=[[1, -3, 0.5], [6, 3, 1.5]]), GLASS)
    s = scan(_world(house), _spec(), 0)
    d, t, z, y = _entries(s, 1.0)
    steep = (np.abs(y) < 0.3) & (d[:, 2] < np.sin(np.radians(-12.0))) & (z < 1.45)  # not the top face
    assert steep.sum() > 100 and np.all((z[steep] - 0.5) / 1.0 > 0.72)
    assert np.all(np.abs(s.points[steep, 2] - (0.5 - 1.73)) < 1e-3)  # every one on the bottom face
    want = np.round(0.13 * np.array([_pane(c) ** 2 for c in d[steep, 0]]) * 100) / 100
    assert np.all(np.abs(s.points[steep, 3] - want) < 0.0101)
