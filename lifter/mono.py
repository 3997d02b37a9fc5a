"""Image-only lifting (003, Deep3DBox style): the translation that makes the projected 3D box fit
tightly in the 2D box.

Given the size and the orientation, each side of the 2D box is touched by one corner of the 3D box.
For a side at image column u and a corner c (object frame offset o = R·c from the bottom centre T),
`(P[0] - u·P[2]) · [o + T, 1] = 0` is linear in T; the row is the same for every corner, only the
right-hand side changes. So every corner assignment (left/right: any of 8 corners; top: a top corner;
bottom: a bottom corner, 1024 in all) is one column of right-hand sides solved through a single
pseudo-inverse; the assignment whose box projects closest to the 2D box wins.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kitti.boxes import box_corners, wrap_angle
from kitti.calib import Calibration

# Side is "cut by the border" when it lies within this many pixels of the image edge: its column is
# the border, not a corner of the object, so it is no constraint.
BORDER_PX = 1.0
# Weight of the ground-plane row relative to a pixel row (rows are scaled to ~pixels at 1 m).
PLANE_WEIGHT = 1.0

_ALL = np.arange(8)
_TOP = np.arange(4, 8)
_BOTTOM = np.arange(4)


@dataclass
class MonoSolution:
    location: np.ndarray  # (3,) bottom-face centre, rectified camera frame
    rotation_y: float
    box_error_px: float  # mean |projected box side - 2D box side| over the constrained sides


def _grid(choices: list[np.ndarray]) -> np.ndarray:
    """(K, len(choices)) every combination of one corner per constrained side."""
    mesh = np.meshgrid(*choices, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def _project(pts: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    hom = np.einsum("...j,ij->...i", pts, P[:, :3]) + P[:, 3]
    return hom[..., :2] / hom[..., 2:3], hom[..., 2]


def solve_translation(dims: np.ndarray, rotation_y: float, bbox: np.ndarray, calib: Calibration,
                      image_size: tuple[int, int], plane: np.ndarray | None = None,
                      cam: int = 2, cut_ok: bool = False) -> MonoSolution:
    """Bottom-centre translation for a box of size `dims` (h, w, l) and yaw `rotation_y` whose
    projection fits `bbox` [x1, y1, x2, y2]. `plane` (a, b, c, d; rect frame) adds the constraint
    that the bottom centre lies on the road: with the bottom edge it fixes the depth (the top edge
    is then not used), and it still fixes it when the box is cut by the border.
    With `cut_ok`, a box cut on so many sides that fewer than 3 constraints remain uses its border
    sides too; without it, that is an error.
    """
    h, w, l = (float(v) for v in dims)
    P = calib.P(cam)
    W, H = image_size
    x1, y1, x2, y2 = (float(v) for v in bbox)
    offs = box_corners(np.array([[0, 0, 0, h, w, l, rotation_y]]))[0]  # (8, 3) from bottom centre
    # (axis, pixel, admissible corners, constrains?). With the road plane and a visible bottom edge,
    # the ground contact fixes the depth; the top edge would only add the predicted height's error
    # (7 % of the depth for a 0.1 m error on a car), so it is left out.
    bottom_seen = y2 < H - 1 - BORDER_PX
    sides = [(0, x1, _ALL, x1 > BORDER_PX), (0, x2, _ALL, x2 < W - 1 - BORDER_PX),
             (1, y1, _TOP, y1 > BORDER_PX and (plane is None or not bottom_seen)),
             (1, y2, _BOTTOM, bottom_seen)]
    rows, rhs_sets, choices = [], [], []
    if sum(side[3] for side in sides) + (plane is not None) < 3 and cut_ok:
        # cut on too many sides: take the border as the outline there (the box is then too small,
        # so the depth comes out too far; the only answer the image still gives)
        sides = [(axis, s, corner_set, True) for axis, s, corner_set, _ in sides]
    sides = [side for side in sides if side[3]]
    for axis, s, corner_set, _ in sides:
        r = P[axis] - s * P[2]  # (4,)
        rows.append(r[:3])
        rhs_sets.append(-(offs @ r[:3] + r[3]))  # (8,) one rhs per corner
        choices.append(corner_set)
    if plane is not None:
        n = np.asarray(plane, dtype=float)
        scale = PLANE_WEIGHT * P[0, 0]  # a metre of plane error ~ f pixels at 1 m
        rows.append(n[:3] * scale)
        rhs_sets.append(np.full(8, -n[3] * scale))
        choices.append(np.zeros(1, dtype=int))
    if len(rows) < 3:
        raise ValueError(f"box {bbox.tolist()} leaves {len(rows)} constraints; 3 are needed")
    A = np.array(rows)  # (k, 3)
    combos = _grid(choices)  # (K, k)
    B = np.stack([rhs_sets[i][combos[:, i]] for i in range(len(rows))], axis=0)  # (k, K)
    T = np.einsum("ij,jk->ki", np.linalg.pinv(A), B)  # (K, 3); einsum: no BLAS threads
    corners = T[:, None, :] + offs[None]  # (K, 8, 3)
    uv, z = _project(corners, P)
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    proj = np.stack([np.clip(lo[:, 0], 0, W - 1), np.clip(lo[:, 1], 0, H - 1),
                     np.clip(hi[:, 0], 0, W - 1), np.clip(hi[:, 1], 0, H - 1)], axis=1)
    err = np.abs(proj - np.array([x1, y1, x2, y2])).mean(axis=1)
    err = np.where((z > 0.1).all(axis=1), err, np.inf)
    best = int(np.argmin(err))
    return MonoSolution(T[best], float(rotation_y), float(err[best]))


def solve_from_alpha(dims: np.ndarray, alpha: float, bbox: np.ndarray, calib: Calibration,
                     image_size: tuple[int, int], plane: np.ndarray | None = None, cam: int = 2,
                     iters: int = 8, tol: float = 1e-6, cut_ok: bool = False) -> MonoSolution:
    """As `solve_translation`, for a local orientation alpha: rotation_y = alpha + atan2(x, z)
    depends on the translation, so start from the ray through the 2D box centre and iterate (the
    ray angle moves little with the translation: converges in a few steps)."""
    u = 0.5 * (bbox[0] + bbox[2])
    v = 0.5 * (bbox[1] + bbox[3])
    ray = calib.image_to_rect(np.array([[u, v]]), np.array([10.0]), cam)[0]
    ry = float(wrap_angle(alpha + np.arctan2(ray[0], ray[2])))
    sol = solve_translation(dims, ry, bbox, calib, image_size, plane, cam, cut_ok)
    for _ in range(iters):
        ry_new = float(wrap_angle(alpha + np.arctan2(sol.location[0], sol.location[2])))
        if abs(wrap_angle(ry_new - ry)) < tol:
            break
        ry = ry_new
        sol = solve_translation(dims, ry, bbox, calib, image_size, plane, cam, cut_ok)
    return sol
