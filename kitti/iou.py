"""Exact IoU of many boxes against many: 2D axis-aligned, bird's-eye rotated, and 3D.

Bird's-eye overlap is the exact area of the intersection of two rotated rectangles in the camera
x-z plane, found by clipping one rectangle against the other's four half-planes (Sutherland-Hodgman)
in a compiled loop over the candidate pairs. Pairs whose circumscribed circles (or, in 3D, y extents) do not
meet are never clipped. Identical boxes give 1 to rounding, disjoint boxes 0.
"""

from __future__ import annotations

import numba
import numpy as np

def iou_2d(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, M) IoU of axis-aligned [x1, y1, x2, y2] boxes (continuous areas, no +1)."""
    a = np.asarray(a, dtype=float).reshape(-1, 4)
    b = np.asarray(b, dtype=float).reshape(-1, 4)
    iw = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    ih = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = np.clip(iw, 0, None) * np.clip(ih, 0, None)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1), 0.0)


def bev_corners(boxes7: np.ndarray) -> np.ndarray:
    """(N, 4, 2) bird's-eye corners (camera x, z), counter-clockwise in the x-z plane."""
    b = np.asarray(boxes7, dtype=float).reshape(-1, 7)
    c, s = np.cos(b[:, 6]), np.sin(b[:, 6])
    hl, hw = b[:, 5] / 2, b[:, 4] / 2
    # object-frame (along l, along w), listed counter-clockwise in (x, z)
    dl = np.array([1, 1, -1, -1])[None] * hl[:, None]
    dw = np.array([-1, 1, 1, -1])[None] * hw[:, None]
    # heading (c, -s) along l, (s, c) along w (camera x-z); this map is a proper rotation
    x = b[:, 0:1] + c[:, None] * dl + s[:, None] * dw
    z = b[:, 2:3] - s[:, None] * dl + c[:, None] * dw
    return np.stack([x, z], axis=2)


@numba.njit(cache=True, nogil=True)
def _clip_areas(ca: np.ndarray, cb: np.ndarray, ia: np.ndarray, ib: np.ndarray) -> np.ndarray:
    """Intersection areas of convex CCW quads ca[ia[k]] and cb[ib[k]] (Sutherland-Hodgman).

    Clipping a quad by four half-planes adds at most one vertex per plane, so 8 slots suffice.
    """
    out = np.zeros(len(ia))
    poly = np.empty((8, 2))
    nxt_poly = np.empty((8, 2))
    for k in range(len(ia)):
        i, j = ia[k], ib[k]
        for v in range(4):
            poly[v, 0], poly[v, 1] = ca[i, v, 0], ca[i, v, 1]
        n = 4
        for e in range(4):
            e0x, e0z = cb[j, e, 0], cb[j, e, 1]
            dx, dz = cb[j, (e + 1) % 4, 0] - e0x, cb[j, (e + 1) % 4, 1] - e0z
            m = 0
            for v in range(n):
                w = v + 1 if v + 1 < n else 0
                px, pz, qx, qz = poly[v, 0], poly[v, 1], poly[w, 0], poly[w, 1]
                sp = dx * (pz - e0z) - dz * (px - e0x)  # > 0: left of the edge, inside
                sq = dx * (qz - e0z) - dz * (qx - e0x)
                if sp >= 0:
                    nxt_poly[m, 0], nxt_poly[m, 1] = px, pz
                    m += 1
                if (sp >= 0) != (sq >= 0):
                    t = sp / (sp - sq)
                    nxt_poly[m, 0], nxt_poly[m, 1] = px + t * (qx - px), pz + t * (qz - pz)
                    m += 1
            poly, nxt_poly = nxt_poly, poly
            n = m
            if n < 3:
                break
        if n >= 3:
            acc = 0.0
            for v in range(n):
                w = v + 1 if v + 1 < n else 0
                acc += poly[v, 0] * poly[w, 1] - poly[v, 1] * poly[w, 0]
            out[k] = 0.5 * abs(acc)
    return out


def _candidates(a: np.ndarray, b: np.ndarray, with_y: bool) -> tuple[np.ndarray, np.ndarray]:
    ra = 0.5 * np.hypot(a[:, 4], a[:, 5])
    rb = 0.5 * np.hypot(b[:, 4], b[:, 5])
    dx = a[:, None, 0] - b[None, :, 0]
    dz = a[:, None, 2] - b[None, :, 2]
    near = dx * dx + dz * dz < (ra[:, None] + rb[None, :]) ** 2
    if with_y:
        near &= _y_overlap(a[:, None, :], b[None, :, :]) > 0
    return np.nonzero(near)


def _y_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # the box spans [y - h, y] (y down, bottom face at y)
    return np.clip(np.minimum(a[..., 1], b[..., 1]) - np.maximum(a[..., 1] - a[..., 3], b[..., 1] - b[..., 3]),
                   0, None)


def bev_intersection(a: np.ndarray, b: np.ndarray, with_y: bool = False) -> np.ndarray:
    """(N, M) exact bird's-eye intersection areas."""
    a = np.asarray(a, dtype=float).reshape(-1, 7)
    b = np.asarray(b, dtype=float).reshape(-1, 7)
    out = np.zeros((len(a), len(b)))
    ia, ib = _candidates(a, b, with_y)
    if len(ia):
        out[ia, ib] = _clip_areas(bev_corners(a), bev_corners(b), ia, ib)
    return out


def iou_bev(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, M) bird's-eye IoU of [x, y, z, h, w, l, ry] boxes (rectangles in camera x-z)."""
    a = np.asarray(a, dtype=float).reshape(-1, 7)
    b = np.asarray(b, dtype=float).reshape(-1, 7)
    inter = bev_intersection(a, b)
    union = (a[:, 4] * a[:, 5])[:, None] + (b[:, 4] * b[:, 5])[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1), 0.0)


def iou_3d(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, M) 3D IoU: bird's-eye intersection times the overlap of [y - h, y], over the union."""
    a = np.asarray(a, dtype=float).reshape(-1, 7)
    b = np.asarray(b, dtype=float).reshape(-1, 7)
    inter = bev_intersection(a, b, with_y=True) * _y_overlap(a[:, None, :], b[None, :, :])
    va, vb = a[:, 3] * a[:, 4] * a[:, 5], b[:, 3] * b[:, 4] * b[:, 5]
    union = va[:, None] + vb[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1), 0.0)
