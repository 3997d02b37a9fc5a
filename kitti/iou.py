"""Exact IoU of many boxes against many: 2D axis-aligned, bird's-eye rotated, and 3D.

Bird's-eye overlap is the exact area of the intersection of two rotated rectangles in the camera
x-z plane, found by clipping one rectangle against the other's four half-planes (Sutherland-Hodgman)
for all candidate pairs at once. Pairs whose circumscribed circles (or, in 3D, y extents) do not
meet are never clipped. Identical boxes give 1 to rounding, disjoint boxes 0.
"""

from __future__ import annotations

import numpy as np

_CHUNK = 1 << 16  # pairs clipped at once: bounds memory at a few tens of MB


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


def _clip_area(subj: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Intersection areas of P convex quads `subj` (P,4,2) with convex CCW quads `clip` (P,4,2)."""
    with np.errstate(divide="ignore", invalid="ignore"):  # 0/0 only in slots that are dropped
        return _clip_area_unchecked(subj, clip)


def _clip_area_unchecked(subj: np.ndarray, clip: np.ndarray) -> np.ndarray:
    p = len(subj)
    poly = np.zeros((p, 8, 2))
    poly[:, :4] = subj
    n = np.full(p, 4)
    idx = np.arange(8)[None, :]
    rows = np.arange(p)[:, None]
    for k in range(4):
        e0, e1 = clip[:, k], clip[:, (k + 1) % 4]
        d = e1 - e0
        # side > 0: left of the directed edge, inside a CCW polygon
        side = d[:, None, 0] * (poly[..., 1] - e0[:, None, 1]) - d[:, None, 1] * (poly[..., 0] - e0[:, None, 0])
        live = idx < n[:, None]
        nxt = np.where(idx + 1 < n[:, None], idx + 1, 0)
        side_n = side[rows, nxt]
        inside, inside_n = side >= 0, side_n >= 0
        t = side / (side - side_n)
        cross_pt = poly + t[..., None] * (poly[rows, nxt] - poly)
        cand = np.stack([poly, cross_pt], axis=2).reshape(p, 16, 2)
        keep = np.stack([inside & live, (inside != inside_n) & live], axis=2).reshape(p, 16)
        order = np.argsort(~keep, axis=1, kind="stable")[:, :8]
        poly = cand[rows, order]
        n = np.minimum(keep.sum(axis=1), 8)
    live = idx < n[:, None]
    nxt = np.where(idx + 1 < n[:, None], idx + 1, 0)
    q = poly[rows, nxt]
    cross = np.where(live, poly[..., 0] * q[..., 1] - poly[..., 1] * q[..., 0], 0.0)
    return np.where(n >= 3, 0.5 * np.abs(cross.sum(axis=1)), 0.0)


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
        ca, cb = bev_corners(a), bev_corners(b)
        for s in range(0, len(ia), _CHUNK):
            i, j = ia[s:s + _CHUNK], ib[s:s + _CHUNK]
            out[i, j] = _clip_area(ca[i], cb[j])
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
