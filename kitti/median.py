"""np.median of a 1-D float array, bit for bit, without its overhead: per-ring elevations and the
fidelity report's robust spreads take tens of medians a frame, where np.median's own bookkeeping
cost as much as the partition."""

from __future__ import annotations

import numpy as np


def median(x: np.ndarray) -> np.floating:
    """np.median(x) of a non-empty 1-D float array: the mean of its middle order statistics,
    (a + b) / 2 in x's dtype, from one np.partition. A zero (its sign depends on which of 0.0 and
    -0.0 the partition puts in the middle, and data hold both) and NaN are left to np.median."""
    h = len(x) // 2
    even = len(x) % 2 == 0
    part = np.partition(x, [h - 1, h, -1] if even else [h, -1])
    mid = (part[h - 1] + part[h]) / 2 if even else part[h]
    if mid == 0 or np.isnan(part[-1]):
        return np.median(x)
    return mid


def group_medians(group: np.ndarray, values: np.ndarray, groups: int) -> np.ndarray:
    """np.median of `values` in each group 0..groups-1 (NaN for an empty one), bit for bit: the
    values sorted into their groups once (a stable radix sort of the small group numbers), then
    each group's two middle values by partition, averaged as numpy averages them."""
    keep = (group >= 0) & (group < groups)
    g = group[keep].astype(np.int16)
    v = values[keep][np.argsort(g, kind="stable")]
    counts = np.bincount(g, minlength=groups)
    out = np.full(groups, np.nan)
    start = 0
    for k, n in enumerate(counts.tolist()):
        if n:
            lo, hi = (n - 1) // 2, n // 2
            part = np.partition(v[start:start + n], (lo, hi))
            out[k] = (part[lo] + part[hi]) / 2
        start += n
    return out
