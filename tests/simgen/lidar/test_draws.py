"""draws.standard_normal is numpy's float32 standard_normal: the same bits, and the generator left
where numpy leaves it (the scan's later draws depend on it)."""

from __future__ import annotations

import numpy as np
import pytest

from simgen.lidar.draws import standard_normal


@pytest.mark.parametrize("bit_generator", [np.random.PCG64, np.random.MT19937, np.random.Philox])
def test_standard_normal_is_numpys(bit_generator):
    sizes = np.random.default_rng(7).integers(1, 200_000, 40)
    for seed, n in enumerate([0, 1, 2, 3, 255, 256, 257, *sizes]):
        ours, theirs = np.random.Generator(bit_generator(seed)), np.random.Generator(bit_generator(seed))
        a, b = standard_normal(ours, int(n)), theirs.standard_normal(int(n), dtype=np.float32)
        assert a.dtype == np.float32 and np.array_equal(a.view(np.uint32), b.view(np.uint32)), (seed, n)
        assert np.array_equal(ours.random(9, dtype=np.float32), theirs.random(9, dtype=np.float32))


def test_the_rare_branches_are_numpys():
    """Draws from the ziggurat's tail and wedges (0.7 % of them), across batch boundaries."""
    n = 3_000_000
    a = standard_normal(np.random.default_rng(123), n)
    b = np.random.default_rng(123).standard_normal(n, dtype=np.float32)
    assert (np.abs(b) > 3.6541529).sum() > 100  # the tail beyond r was drawn
    assert np.array_equal(a.view(np.uint32), b.view(np.uint32))
