"""Step 2 of `fit` (see fit.py): which of a frustum's returns are the object's own.

Bird's-eye Euclidean clusters (a vertical surface stays connected however few beams hit it), pooled
in CELL-sized cells first so a dense near car costs no more than a sparse one. The clusters that
best explain the 2D box seed the object; each seed is grown by the neighbouring clusters that keep
it car-sized (a far car's bumper, bonnet and roof fall apart in bird's-eye view but belong
together), and the grown set that best explains the box wins.

Numba kernels: a frustum holds a few hundred cells, and numpy spent this step in call overhead.
"""

from __future__ import annotations

import numba
import numpy as np

CLUSTER_R = 0.6        # m, bird's-eye linking distance
CELL = 0.1             # m, bird's-eye cell the returns are pooled in before clustering
MIN_POINTS = 3         # fewer returns: no object here
MIN_SEED = 2           # returns of a cluster that may seed an object
MAX_SEEDS = 3          # best-scoring clusters tried as seeds
MERGE_SLACK = 0.3      # m, how much longer than the size prior's diagonal, and wider than its width,
                       # a merged set may be


@numba.njit(cache=True, nogil=True)
def _explain_score(u_span: float, count: int, gap: float, width: float, sigma: float) -> float:
    """How well a set of returns explains a 2D box: wide in the image (its column span against the
    box's width), many returns, its nearest return near the depth the road predicts (gap, m)."""
    return ((min(1.0, u_span / width) + 0.05) * min(1.0, count / 10)
            * np.exp(-0.5 * (gap / sigma) ** 2))


@numba.njit(cache=True, nogil=True)
def object_returns(xz: np.ndarray, u: np.ndarray, rng: np.ndarray, width: float, road_d: float,
                   sigma: float, diag: float, strip: float = np.inf) -> tuple[np.ndarray, float]:
    """The returns (mask) of the object a 2D box shows, and how well they explain it (0: none).

    xz: the frustum's returns in bird's-eye view; u: their image columns; rng: their bird's-eye
    range from the sensor; width: the 2D box's width (px); road_d, sigma: the depth the road
    predicts under the box and its uncertainty; diag: the size prior's bird's-eye diagonal; strip:
    its narrower side (a merged set must fit in a strip that wide)."""
    cells, inverse = _cells(xz)
    cell_label = _link_components(cells, CLUSTER_R)
    label = cell_label[inverse]
    k = cell_label.max() + 1
    # score every cluster as a seed
    count = np.zeros(k, dtype=np.int64)
    u_lo, u_hi = np.full(k, np.inf), np.full(k, -np.inf)
    near = np.full(k, np.inf)
    for i in range(len(xz)):
        c = label[i]
        count[c] += 1
        u_lo[c], u_hi[c] = min(u_lo[c], u[i]), max(u_hi[c], u[i])
        near[c] = min(near[c], rng[i])
    score = np.empty(k)
    for c in range(k):
        score[c] = _explain_score(u_hi[c] - u_lo[c], count[c], near[c] - road_d, width, sigma)
    seeds = np.flatnonzero(count >= MIN_SEED)
    seeds = seeds[np.argsort(-score[seeds], kind="mergesort")][:MAX_SEEDS]
    # each seed grown by its car-sized neighbours; the best explanation wins
    lo, hi = _bounds(cells, cell_label, k)
    best, best_score = np.zeros(len(xz), dtype=np.bool_), 0.0
    for seed in seeds:
        m = _merge(cells, cell_label, seed, diag, strip, lo, hi)[inverse]
        n = m.sum()
        if n < MIN_POINTS:
            continue
        sc = _explain_score(u[m].max() - u[m].min(), n, rng[m].min() - road_d, width, sigma)
        if sc > best_score:
            best, best_score = m, sc
    return best, best_score


def grown_beyond(obj_xz: np.ndarray, beyond_xz: np.ndarray, diag: float,
                 strip: float) -> np.ndarray:
    """Which returns beyond the image's border (mask over beyond_xz) belong to the object whose
    returns in view are obj_xz: the clusters of them that keep it car-sized, nearest first, as
    `object_returns` grows a seed. A cluster holding the car's hidden end and what touches it
    (a hedge, the next car) would not, and stays out."""
    joined = np.zeros(len(beyond_xz), dtype=np.bool_)
    # only what lies within reach of a car-sized set can join it (a frustum opened to the border
    # holds the whole street beyond it)
    reach = diag + MERGE_SLACK
    lo, hi = obj_xz.min(axis=0) - reach, obj_xz.max(axis=0) + reach
    near = np.flatnonzero(((beyond_xz >= lo) & (beyond_xz <= hi)).all(axis=1))
    if len(near) == 0:
        return joined
    cells_b, inverse_b = _cells(beyond_xz[near])
    cells_o, _ = _cells(obj_xz)
    cells = np.concatenate((cells_o, cells_b))
    label = np.concatenate((np.zeros(len(cells_o), dtype=np.int64),
                            1 + _link_components(cells_b, CLUSTER_R)))
    lo, hi = _bounds(cells, label, label.max() + 1)
    take = _merge(cells, label, 0, diag, strip, lo, hi)
    joined[near] = take[len(cells_o):][inverse_b]
    return joined


@numba.njit(cache=True, nogil=True)
def _cells(xz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The occupied CELL-sized bird's-eye cells (centres, in the order of their key), and each
    return's cell."""
    ij = np.floor(xz / CELL).astype(np.int64)
    i0, j0 = ij[:, 0].min(), ij[:, 1].min()
    span = ij[:, 1].max() - j0 + 1
    key = (ij[:, 0] - i0) * span + (ij[:, 1] - j0)  # one integer per cell
    order = np.argsort(key, kind="mergesort")
    inverse = np.empty(len(xz), dtype=np.int64)
    first = np.empty(len(xz), dtype=np.int64)
    n = 0
    for t in range(len(order)):
        i = order[t]
        if t == 0 or key[i] != key[order[t - 1]]:
            first[n] = i
            n += 1
        inverse[i] = n - 1
    return (np.floor(xz[first[:n]] / CELL) + 0.5) * CELL, inverse


@numba.njit(cache=True, nogil=True)
def _link_components(p: np.ndarray, r: float) -> np.ndarray:
    """Connected components of the points under 'closer than r' (labels 0, 1, ... in order of
    each component's first point): a flood fill over all pairs, cheaper than a k-d tree and a
    sparse graph for the few hundred cells of one frustum."""
    n = len(p)
    label = np.full(n, -1, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    r2 = r * r
    k = 0
    for s in range(n):
        if label[s] >= 0:
            continue
        label[s] = k
        top = 0
        stack[0] = s
        while top >= 0:
            i = stack[top]
            top -= 1
            for j in range(n):
                if label[j] < 0:
                    dx = p[i, 0] - p[j, 0]
                    dz = p[i, 1] - p[j, 1]
                    if dx * dx + dz * dz <= r2:
                        label[j] = k
                        top += 1
                        stack[top] = j
        k += 1
    return label


@numba.njit(cache=True, nogil=True)
def _bounds(xz: np.ndarray, label: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Per cluster, the lower and upper corners of its bird's-eye bounding box."""
    lo, hi = np.full((k, 2), np.inf), np.full((k, 2), -np.inf)
    for i in range(len(xz)):
        c = label[i]
        for a in range(2):
            lo[c, a], hi[c, a] = min(lo[c, a], xz[i, a]), max(hi[c, a], xz[i, a])
    return lo, hi


@numba.njit(cache=True, nogil=True)
def _merge(xz: np.ndarray, label: np.ndarray, seed: int, diag: float, strip: float,
           lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The seed cluster plus the nearby clusters, nearest first, that keep the set within the
    size prior's diagonal and width (+ MERGE_SLACK)."""
    take = label == seed
    seed_xz = xz[take]
    k = len(lo)
    dist = np.full(k, np.inf)
    for c in range(k):
        # the gap between bounding boxes bounds the distance from below: only clusters within
        # diag of the seed's box get the exact point-to-point distance
        gx = max(0.0, max(lo[c, 0] - hi[seed, 0], lo[seed, 0] - hi[c, 0]))
        gz = max(0.0, max(lo[c, 1] - hi[seed, 1], lo[seed, 1] - hi[c, 1]))
        if c == seed or np.hypot(gx, gz) > diag:
            continue
        d2 = np.inf
        for i in range(len(xz)):
            if label[i] == c:
                for j in range(len(seed_xz)):
                    dx, dz = xz[i, 0] - seed_xz[j, 0], xz[i, 1] - seed_xz[j, 1]
                    d2 = min(d2, dx * dx + dz * dz)
        dist[c] = np.sqrt(d2)
    for c in np.argsort(dist, kind="mergesort"):
        if dist[c] > diag:
            break
        trial = take | (label == c)
        longest, narrowest = _extents(xz[trial])
        if longest <= diag + MERGE_SLACK and narrowest <= strip + MERGE_SLACK:
            take = trial
    return take


@numba.njit(cache=True, nogil=True)
def _extents(pts: np.ndarray) -> tuple[float, float]:
    """The set's largest and smallest extent over 16 directions: its diameter (within 2 %) and
    the width of the narrowest strip holding it (within 2 % of the set's diameter). Twice the
    largest distance from the centroid is no measure of the diameter: an object's returns crowd
    on its near face, so the centroid lies there and the far end of a long side counts double.
    The narrow strip keeps out what lies beside the object (a post, the car in front) even where
    the set would still fit in the prior's diagonal."""
    longest, narrowest = 0.0, np.inf
    for k in range(16):
        c, s = np.cos(np.pi * k / 16), np.sin(np.pi * k / 16)
        lo, hi = np.inf, -np.inf
        for i in range(len(pts)):
            p = c * pts[i, 0] + s * pts[i, 1]
            lo, hi = min(lo, p), max(hi, p)
        longest, narrowest = max(longest, hi - lo), min(narrowest, hi - lo)
    return longest, narrowest
