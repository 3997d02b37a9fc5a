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
