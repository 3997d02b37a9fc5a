"""The road plane per frame: from KITTI `planes/` when present, else fitted to the LiDAR by RANSAC.

Plane convention (KITTI planes/ files): a·x + b·y + c·z + d = 0 in the rectified camera frame with
the normal pointing up (b < 0), so `height_above(X) = n·X + d` for a unit normal.
"""

from __future__ import annotations

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
    pts = points_rect[points_rect[:, 1] > CANDIDATE_BELOW]
    if len(pts) > MAX_POINTS:  # an even stride keeps the spatial spread at a fraction of the cost
        pts = pts[:: int(np.ceil(len(pts) / MAX_POINTS))]
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
    dist = pts[:, :1] * n[:, 0] + pts[:, 1:2] * n[:, 1] + pts[:, 2:3] * n[:, 2] + d  # (N, K)
    counts = (np.abs(dist) < INLIER_M).sum(axis=0)
    best = normalise_plane(np.append(n[np.argmax(counts)], d[np.argmax(counts)]))
    # refine by least squares, re-selecting the inliers: a sample from the dense near returns is
    # slightly off in pitch, and only the refit brings the far road back inside the threshold
    for _ in range(REFINE_STEPS):
        inliers = pts[np.abs(height_above(pts, best)) < INLIER_M]
        if len(inliers) < 10:
            break
        centre = inliers.mean(axis=0)
        q = inliers - centre
        scatter = np.array([[q[:, i] @ q[:, j] for j in range(3)] for i in range(3)])
        _, vecs = np.linalg.eigh(scatter)
        n = vecs[:, 0]  # smallest scatter: the normal
        best = normalise_plane(np.append(n, -np.dot(n, centre)))
    return best
