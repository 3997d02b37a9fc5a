"""A sweep's random numbers are Philox4x32-10's, each ray's its own: Random123's known answers,
numpy's float32 conversions and ziggurat, and a scan in which one object is gone keeps every
other ray's point bit for bit."""

from __future__ import annotations

import dataclasses

import numba
import numpy as np
from scipy import stats

from simgen.lidar import preset, scan
from simgen.lidar.draws import normals, philox, ray_words, to_uniform, uniforms
from tests.simgen.lidar.street import street_world

# Random123's known-answer vectors for Philox4x32-10 (its tests/kat_vectors): counter, key, words.
KAT = [((0, 0, 0, 0), (0, 0), (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)),
       ((0xFFFFFFFF,) * 4, (0xFFFFFFFF,) * 2, (0x408F276D, 0x41C83B0E, 0xA20BC7C6, 0x6D5451FD)),
       ((0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344), (0xA4093822, 0x299F31D0),
        (0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1))]


@numba.njit
def _philox(c, k):
    return philox(c[0], c[1], c[2], c[3], k[0], k[1])


def test_philox_gives_random123s_known_answers():
    for counter, key, words in KAT:
        out = _philox(np.array(counter, np.uint64), np.array(key, np.uint64))
        assert tuple(int(w) for w in out) == words


def test_a_uniform_is_numpys_float32_of_the_ray_s_first_word():
    """Ray 0's block under key (0, 0) is the first known answer: its words' top 24 bits over
    2 ** 24, as numpy's Generator.random(dtype=float32) converts a word."""
    words = ray_words(np.zeros(2, np.uint32), 3)
    assert tuple(int(w) for w in words[:, 0]) == KAT[0][2]
    u = to_uniform(words[:, 0])
    assert u.dtype == np.float32 and np.array_equal(u, np.array([w >> 8 for w in KAT[0][2]]) / np.float32(2**24))
    assert uniforms(np.zeros(2, np.uint32), np.array([0, 2]), 0)[1] == to_uniform(words[0, 2])


def test_each_ray_s_numbers_are_its_own():
    """A ray's draws do not depend on which other rays draw, nor in what order; uses and keys
    give other numbers."""
    key = np.array([7, 11], np.uint32)
    rays = np.arange(50_000)
    pick = np.random.default_rng(0).permutation(rays)[:5_000]
    words = ray_words(key, len(rays))
    full = normals(key, rays, words)
    assert np.array_equal(normals(key, pick, words).view(np.uint32), full[pick].view(np.uint32))
    full = uniforms(key, rays, 3)
    assert np.array_equal(uniforms(key, pick, 3), full[pick])
    assert np.mean(uniforms(key, rays, 4) == full) < 1e-3
    assert np.mean(uniforms(np.array([7, 12], np.uint32), rays, 3) == full) < 1e-3


def test_normals_are_standard_normal_out_to_the_ziggurat_tail():
    """Two million draws (a fixed key: the test is the same every run): Kolmogorov-Smirnov against
    N(0, 1), and the share beyond the ziggurat's r = 3.6541529, drawn by its tail branch, within
    four standard deviations of 2 (1 - Phi(r))."""
    key, rays = np.array([3, 5], np.uint32), np.arange(2_000_000)
    z = normals(key, rays, ray_words(key, len(rays)))
    assert z.dtype == np.float32
    assert stats.kstest(z, "norm").pvalue > 1e-3
    expect = 2_000_000 * 2 * stats.norm.sf(3.6541529)
    assert abs((np.abs(z) > 3.6541529).sum() - expect) < 4 * np.sqrt(expect)
    u = uniforms(key, rays, 3)
    assert stats.kstest(u, "uniform").pvalue > 1e-3 and u.min() >= 0.0 and u.max() < 1.0


def test_an_object_gone_leaves_every_other_ray_s_point_as_it_was():
    """The same street scanned with and without one parked car: every return that did not lie on
    that car is in the other scan, bit for bit (its ray's range noise, drop-out and reading are
    its own), though the car's rays now go on to what stood behind it and draw anew."""
    world = street_world(seed=3)
    gone = next(a for a in world.actors if a.cls == "Car" and not a.moving)
    other = dataclasses.replace(world, actors=[a for a in world.actors if a is not gone])
    a, b = scan(world, preset("hdl64e"), 5), scan(other, preset("hdl64e"), 5)

    def rows(s, keep):
        return {(int(r), float(t)): p.tobytes() for r, t, p in zip(s.ring[keep], s.azimuth[keep], s.points[keep])}

    on_car = a.actor_id == gone.id
    assert on_car.sum() > 100
    before, after = rows(a, ~on_car), rows(b, np.ones(len(b), bool))
    assert all(after.get(k) == v for k, v in before.items())
    assert len(after) - len(before) <= on_car.sum()
