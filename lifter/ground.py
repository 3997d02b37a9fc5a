"""The road plane per frame: from KITTI `planes/` when present, else fitted to the LiDAR by RANSAC.

Plane convention (KITTI planes/ files): a·x + b·y + c·z + d = 0 in the rectified camera frame with
the normal pointing up (b < 0), so `height_above(X) = n·X + d` for a unit normal.
"""

from __future__ import annotations

import numba
import numpy as np

from .points import rowdot

# RANSAC settings (no document gives them; chosen for a 1.65-1.73 m high sensor on a road):
INLIER_M = 0.05       # a return within 5 cm of the plane is road (a 15 cm curb is not)
ITERATIONS = 60       # P(no all-road sample) < 1e-6 when half the candidates are road
MIN_UP = 0.95         # |n_y| of an admissible road normal (slopes up to ~18 deg)
REFINE_STEPS = 4        # least-squares refits
MAX_POINTS = 3000       # candidate returns used
CANDIDATE_BELOW = 0.8  # only returns at least this far below the camera can be road (metres)


def normalise_plane(plane: np.ndarray) -> np.ndarray:
    """Unit normal pointing up (negative camera y)."""
    p = np.asarray(plane, dtype=float).reshape(4)
    p = p / np.linalg.norm(p[:3])
    return -p if p[1] > 0 else p


def height_above(points_rect: np.ndarray, plane: np.ndarray) -> np.ndarray:
    return rowdot(points_rect, plane[:3]) + plane[3]


def fit_ground_plane(points_rect: np.ndarray, seed: int = 0,
                     fallback_height: float = 1.65) -> np.ndarray:
    """RANSAC plane on the low returns, refined by least squares on its inliers.

    With too few low returns (a sparse or empty scan) the flat plane `fallback_height` below the
    camera is returned: the testbed's and KITTI's rig."""
    flat = np.array([0.0, -1.0, 0.0, fallback_height])
    pts = _low_returns(np.ascontiguousarray(points_rect, dtype=np.float64), CANDIDATE_BELOW,
                       MAX_POINTS)
    if len(pts) < 30:
        return flat
    rng = np.random.default_rng(seed)
    a, b, c = (pts[rng.integers(0, len(pts), size=ITERATIONS)] for _ in range(3))
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    ok = (norm > 1e-9) & (np.abs(n[:, 1]) > MIN_UP * np.maximum(norm, 1e-12))
    if not ok.any():
        return flat
    n = n[ok] / norm[ok, None]
    d = -(n * a[ok]).sum(axis=1)
    counts = _inlier_counts(pts, n, d, INLIER_M)
    best = normalise_plane(np.append(n[np.argmax(counts)], d[np.argmax(counts)]))
    # refine by least squares, re-selecting the inliers: a sample from the dense near returns is
    # slightly off in pitch, and only the refit brings the far road back inside the threshold
    for _ in range(REFINE_STEPS):
        count, centre, scatter = _inlier_scatter(pts, best, INLIER_M)
        if count < 10:
            break
        _, vecs = np.linalg.eigh(scatter)
        n = vecs[:, 0]  # smallest scatter: the normal
        best = normalise_plane(np.append(n, -np.dot(n, centre)))
    return best


@numba.njit(cache=True, nogil=True)
def _low_returns(p: np.ndarray, below: float, max_points: int) -> np.ndarray:
    """The returns lower than `below` under the camera (rect y > below); more than max_points of
    them are thinned by an even stride, which keeps their spatial spread at a fraction of the
    cost."""
    low = 0
    for i in range(len(p)):
        low += p[i, 1] > below
    step = 1 if low <= max_points else -(-low // max_points)
    out = np.empty(((low + step - 1) // step, 3))
    k = j = 0
    for i in range(len(p)):
        if p[i, 1] > below:
            if j % step == 0:
                out[k] = p[i]
                k += 1
            j += 1
    return out


@numba.njit(cache=True, nogil=True)
def _inlier_counts(p: np.ndarray, n: np.ndarray, d: np.ndarray, tol: float) -> np.ndarray:
    """Per candidate plane (unit normal n[k], offset d[k]), the returns within tol of it: no
    (N, K) distance matrix as numpy would make, and a branch-free count over the returns' columns
    per plane, which the compiler vectorises (four times faster than a branch per pair)."""
    x, y, z = p[:, 0].copy(), p[:, 1].copy(), p[:, 2].copy()
    counts = np.zeros(len(d), dtype=np.int64)
    for k in range(len(d)):
        a, b, c, e = n[k, 0], n[k, 1], n[k, 2], d[k]
        m = 0
        for i in range(len(x)):
            m += abs(x[i] * a + y[i] * b + z[i] * c + e) < tol
        counts[k] = m
    return counts


@numba.njit(cache=True, nogil=True)
def _inlier_scatter(p: np.ndarray, plane: np.ndarray,
                    tol: float) -> tuple[int, np.ndarray, np.ndarray]:
    """The returns within tol of the plane: how many, their centroid and their scatter matrix,
    in two passes without the inlier copies numpy would make."""
    inlier = np.empty(len(p), dtype=np.bool_)
    centre = np.zeros(3)
    for i in range(len(p)):
        inlier[i] = abs(p[i, 0] * plane[0] + p[i, 1] * plane[1] + p[i, 2] * plane[2]
                        + plane[3]) < tol
        if inlier[i]:
            for a in range(3):
                centre[a] += p[i, a]
    count = inlier.sum()
    centre /= max(count, 1)
    scatter = np.zeros((3, 3))
    for i in range(len(p)):
        if inlier[i]:
            for a in range(3):
                for b in range(3):
                    scatter[a, b] += (p[i, a] - centre[a]) * (p[i, b] - centre[b])
    return count, centre, scatter
