"""Procedural texture tiles (simgen.textures): mean-one multipliers, seamless, deterministic."""

from __future__ import annotations

import numpy as np
import pytest

from simgen import textures


@pytest.mark.parametrize("kind", sorted(textures.TILE_M))
def test_tiles_keep_the_material_colour_on_average_and_repeat_without_a_seam(kind):
    tile = textures.tile(kind, 0).astype(np.float64) * textures.MAX_GAIN / 255.0
    # Mean multiplier 1 per channel, up to the 8-bit rounding and the clip at MAX_GAIN.
    np.testing.assert_allclose(tile.reshape(-1, 3).mean(axis=0), 1.0, atol=0.01)
    grey = tile.mean(axis=2)
    # Across the wrap the step is no larger than the largest step between neighbouring columns
    # (rows) inside the tile: joints and window edges are steps a seam must not exceed.
    inner_u = np.abs(np.diff(grey, axis=1)).mean(axis=0).max()
    inner_v = np.abs(np.diff(grey, axis=0)).mean(axis=1).max()
    assert np.abs(grey[:, 0] - grey[:, -1]).mean() <= inner_u
    assert np.abs(grey[0] - grey[-1]).mean() <= inner_v


def test_a_tile_is_a_pure_function_of_kind_and_variant():
    a = textures._made.__wrapped__("asphalt", 0)[0]
    b = textures._made.__wrapped__("asphalt", 0)[0]
    c = textures._made.__wrapped__("asphalt", 1)[0]
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_fractal_noise_is_periodic_zero_mean_unit_sd():
    n = textures._fractal(np.random.default_rng(0), 1.5, size=(64, 128))
    assert n.shape == (64, 128)
    assert abs(n.mean()) < 1e-9 and n.std() == pytest.approx(1.0)
    # Periodic: the circular shift by half a period is the same field, its spectrum unchanged.
    np.testing.assert_allclose(np.abs(np.fft.fft2(np.roll(n, 32, axis=1))), np.abs(np.fft.fft2(n)),
                               atol=1e-9)


def test_an_unknown_kind_is_named():
    with pytest.raises(KeyError, match="no texture kind 'tarmac'"):
        textures.tile("tarmac", 0)


def test_a_crown_shows_the_camera_a_canopys_reflectance_and_the_lidar_a_leafs():
    """Two-stream albedo of a deep layer of leaves, by hand: the Community Land Model's broadleaf
    leaves (visible reflectance 0.10, transmittance 0.05: w = 0.15; near infrared 0.45 and 0.25:
    w = 0.70) give (1 - sqrt(0.85)) / (1 + sqrt(0.85)) = 0.0406 and (1 - sqrt(0.3)) / (1 +
    sqrt(0.3)) = 0.2922."""
    from simgen.materials import FOLIAGE, LEAF, SHRUB_MASS, canopy_reflectance

    assert canopy_reflectance((0.10,)) == (0.0406,)
    assert canopy_reflectance((0.45,), transmittance_ratio=0.25 / 0.45) == (0.2922,)
    assert FOLIAGE.color == SHRUB_MASS.color == canopy_reflectance(LEAF)
    # darker than a leaf in every channel, the green leading by more (multiple scattering)
    assert all(c < 0.45 * leaf for c, leaf in zip(FOLIAGE.color, LEAF))
    assert FOLIAGE.color[1] / FOLIAGE.color[0] > LEAF[1] / LEAF[0]
    assert FOLIAGE.reflectivity == 0.33  # the LiDAR reads the first leaf its beam lights
