"""Beam reduction, ring recovery on KITTI-ordered scans, presets' beam options, side files."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from kitti.errors import KittiFormatError
from kitti.rings import kept_rings, recover_rings, reduce_rings
from kitti.velodyne import read_velodyne
from kitti.velodyne_info import info_path, read_scan_info, velodyne_path
from simgen.lidar import preset, read_scan, scan, write_scan
from tests.simgen.lidar.street import street_world

REAL_KITTI = Path(__file__).resolve().parents[3] / "shared" / "kitti_real_dev"


@pytest.fixture(scope="module")
def hdl64_scan():
    return scan(street_world(7), preset("hdl64e"), 7)


def test_reduce_64_to_32_keeps_exactly_every_second_ring(hdl64_scan):
    s = hdl64_scan
    mask, new_ring = reduce_rings(s.ring, 64, 32)
    assert np.array_equal(np.unique(s.ring[mask]), np.arange(0, 64, 2))
    assert np.array_equal(mask, s.ring % 2 == 0)
    assert np.array_equal(new_ring, s.ring[mask] // 2)
    assert np.array_equal(kept_rings(64, 16), [0, 4, 8, 12, 16, 20, 24, 28, 32, 36, 40, 44,
                                               48, 52, 56, 60])
    with pytest.raises(ValueError, match="must divide"):
        kept_rings(64, 24)


def test_preset_beams_subsamples_like_reduce_beams(hdl64_scan):
    full, half = preset("hdl64e"), preset("hdl64e", beams=32)
    assert half.elevations_deg == full.elevations_deg[::2]
    np.testing.assert_array_equal(half.laser_biases(), full.laser_biases()[::2])  # same unit
    s_half = scan(street_world(7), half.ideal(), 0)
    s_full = scan(street_world(7), full.ideal(), 0)
    mask, new_ring = reduce_rings(s_full.ring, 64, 32)
    # same world, same directions: the 32-beam sensor sees exactly the kept rings
    assert np.array_equal(s_half.points, s_full.points[mask])
    assert np.array_equal(s_half.ring, new_ring)
    with pytest.raises(ValueError, match="uniform"):
        preset("hdl64e", beams=48)
    u = preset("uniform", beams=128, fov_deg=(2.0, -24.9))
    assert u.beams == 128 and u.elevations_deg[0] == 2.0 and u.elevations_deg[-1] == -24.9
    np.testing.assert_allclose(np.diff(u.elevations_deg), -26.9 / 127)
    assert preset("hdl64e", max_range=50.0).max_range == 50.0
    with pytest.raises(ValueError, match="unknown LiDAR preset"):
        preset("hdl128")


def test_ring_recovery_from_azimuth_wraps_is_exact(hdl64_scan):
    rings = recover_rings(hdl64_scan.points, 64)
    assert rings.method == "azimuth-wrap"
    assert np.array_equal(rings.ring, hdl64_scan.ring)
    _assert_ring_elevations_are_medians(rings, hdl64_scan.points)


def _assert_ring_elevations_are_medians(rings, points):
    """Each ring's elevation is np.median of its returns' elevations, bit for bit."""
    el = np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]))
    want = [np.median(el[rings.ring == k]) if np.any(rings.ring == k) else np.nan
            for k in range(len(rings.elevation))]
    np.testing.assert_array_equal(rings.elevation, want)


def test_ring_recovery_survives_rings_that_start_past_the_back(hdl64_scan):
    # rotate each ring's point sequence a little: a laser whose revolution starts a few
    # firings late (its first points move to its end) or early (its last points move to its
    # start), so the azimuth wraps inside the ring
    s = hdl64_scan
    rng = np.random.default_rng(1)
    order = []
    for ring in range(64):
        ix = np.flatnonzero(s.ring == ring)
        order.append(np.roll(ix, int(rng.integers(-8, 9))))
    order = np.concatenate(order)
    rings = recover_rings(s.points[order], 64)
    ring = rings.ring
    assert rings.method == "azimuth-wrap"
    # where two lasers' points meet with no step back in azimuth, only elevation could tell:
    # the few points misplaced there are behind the car (out of the camera's view) and one
    # ring off
    bad = ring != s.ring[order]
    assert bad.mean() < 1e-3
    assert np.all(np.abs(s.azimuth[order][bad]) > np.deg2rad(160))
    assert np.all(np.abs(ring[bad].astype(int) - s.ring[order][bad]) == 1)


def test_ring_recovery_finds_revolutions_that_start_at_the_front(hdl64_scan):
    """KITTI's revolutions start at the front (azimuth 0), the simulator's at the back: cut at the
    back, every laser would split in two and each run mix two lasers (65 runs)."""
    s = hdl64_scan
    order = []
    for ring in range(64):
        ix = np.flatnonzero(s.ring == ring)
        front = np.flatnonzero(np.abs(np.diff(np.mod(s.azimuth[ix], 2 * np.pi))) > np.pi)
        assert len(front) == 1  # one pass through the front per revolution
        order.append(np.roll(ix, -int(front[0] + 1)))
    order = np.concatenate(order)
    assert len(order) == len(s)
    rings = recover_rings(s.points[order], 64)
    assert rings.method == "azimuth-wrap"
    assert np.array_equal(rings.ring, s.ring[order])


@pytest.mark.skipif(not REAL_KITTI.is_dir(), reason=f"real KITTI dev frames not found at {REAL_KITTI}")
def test_real_kitti_scans_give_64_rings_from_their_point_order():
    files = sorted((REAL_KITTI / "training" / "velodyne").glob("*.bin"))
    assert len(files) == 11
    for f in files:
        pts = read_velodyne(f)
        rings = recover_rings(pts, 64)
        ring = rings.ring
        assert rings.method == "azimuth-wrap", f
        _assert_ring_elevations_are_medians(rings, pts)
        med = np.degrees(rings.elevation)
        assert np.all(np.diff(med) < 0), f  # one laser per ring, top to bottom
        assert 1.5 < med[0] < 4.5 and -24.5 < med[-1] < -22.5, f  # the HDL-64E's +2 / -24.9 deg
        assert np.bincount(ring, minlength=64).min() > 500, f


def test_ring_recovery_falls_back_to_elevation_clustering():
    # Beams from the origin: with the unit's source offsets (simgen.lidar.spec) a near return's
    # elevation seen from the origin moves by up to 1.2 deg, more than the rings' spacing, and only
    # the order of the points tells the rings apart.
    spec = replace(preset("hdl64e").ideal(), source_offsets_m=())
    s = scan(street_world(8, moving_cars=0), spec, 0)
    perm = np.random.default_rng(0).permutation(len(s))  # order lost: no wraps to find
    rings = recover_rings(s.points[perm], 64)
    assert rings.method == "elevation-kmeans"
    assert np.array_equal(rings.ring, s.ring[perm])
    _assert_ring_elevations_are_medians(rings, s.points[perm])


def test_side_file_round_trip_and_same_bytes(tmp_path, hdl64_scan):
    assert write_scan(tmp_path / "a", 3, hdl64_scan) == [velodyne_path(tmp_path / "a", 3),
                                                         info_path(tmp_path / "a", 3)]
    write_scan(tmp_path / "b", "000003", hdl64_scan)
    for f in (velodyne_path, info_path):
        assert f(tmp_path / "a", 3).read_bytes() == f(tmp_path / "b", 3).read_bytes()
    back = read_scan(tmp_path / "a", 3)
    assert np.array_equal(back.points, hdl64_scan.points)
    for k in ("ring", "azimuth", "time", "actor_id"):
        a, b = getattr(back, k), getattr(hdl64_scan, k)
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert read_velodyne(velodyne_path(tmp_path / "a", 3)).shape == (len(hdl64_scan), 4)
    with pytest.raises(KittiFormatError, match="the .bin has"):
        read_scan_info(info_path(tmp_path / "a", 3), len(hdl64_scan) - 1)
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(KittiFormatError, match="bad.npz"):
        read_scan_info(bad)
