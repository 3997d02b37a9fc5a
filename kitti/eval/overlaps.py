"""Overlaps of the evaluation, for aligned pairs (detection k with truth k), all frames at once.

The formulas are those of `kitti.iou` (`iou_2d`, `iou_bev`, `iou_3d`: continuous areas, exact
rotated-rectangle clipping), evaluated only on the pairs that share a frame instead of on dense
N x M matrices; a test checks that both agree. The detection is the first box, as in the devkit's
`boxoverlap(det, gt)`. A box whose bird's-eye or 3D extent is unknown (location -1000, size <= 0)
overlaps nothing in that metric.
"""

from __future__ import annotations

import numpy as np

from ..iou import _clip_areas, _y_overlap, bev_corners
from .frames import Objects, Packed, frame_pairs


def _safe_div(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    return np.where(den > 0, num / np.where(den > 0, den, 1), 0.0)


def _inter_2d(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    iw = np.minimum(a[:, 2], b[:, 2]) - np.maximum(a[:, 0], b[:, 0])
    ih = np.minimum(a[:, 3], b[:, 3]) - np.maximum(a[:, 1], b[:, 1])
    return np.clip(iw, 0, None) * np.clip(ih, 0, None)


def _area_2d(a: np.ndarray) -> np.ndarray:
    return (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])


def iou_2d_pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    inter = _inter_2d(a, b)
    return _safe_div(inter, _area_2d(a) + _area_2d(b) - inter)


def _bev_inter(a7: np.ndarray, b7: np.ndarray, ia: np.ndarray, ib: np.ndarray, with_y: bool) -> np.ndarray:
    """Exact bird's-eye intersection of pairs (a7[ia[k]], b7[ib[k]])."""
    a, b = a7[ia], b7[ib]
    ra, rb = 0.5 * np.hypot(a[:, 4], a[:, 5]), 0.5 * np.hypot(b[:, 4], b[:, 5])
    near = (a[:, 0] - b[:, 0]) ** 2 + (a[:, 2] - b[:, 2]) ** 2 < (ra + rb) ** 2
    if with_y:
        near &= _y_overlap(a, b) > 0
    out = np.zeros(len(ia))
    k = np.nonzero(near)[0]
    if len(k):
        out[k] = _clip_areas(bev_corners(a7), bev_corners(b7), ia[k].astype(np.int64),
                             ib[k].astype(np.int64))
    return out


def iou_bev_pairs(a7: np.ndarray, b7: np.ndarray, ia: np.ndarray, ib: np.ndarray) -> np.ndarray:
    inter = _bev_inter(a7, b7, ia, ib, False)
    a, b = a7[ia], b7[ib]
    return _safe_div(inter, a[:, 4] * a[:, 5] + b[:, 4] * b[:, 5] - inter)


def iou_3d_pairs(a7: np.ndarray, b7: np.ndarray, ia: np.ndarray, ib: np.ndarray) -> np.ndarray:
    a, b = a7[ia], b7[ib]
    inter = _bev_inter(a7, b7, ia, ib, True) * _y_overlap(a, b)
    return _safe_div(inter, a[:, 3] * a[:, 4] * a[:, 5] + b[:, 3] * b[:, 4] * b[:, 5] - inter)


def pair_overlaps(p: Packed, metric: str) -> np.ndarray:
    """(P,) overlap of every truth/detection slot of `p` in metric '2d', 'bev' or '3d'."""
    if metric == "2d":
        return iou_2d_pairs(p.dt.bbox[p.pair_dt], p.gt.bbox[p.pair_gt])
    valid_g, valid_d = (p.gt.has_bev, p.dt.has_bev) if metric == "bev" else (p.gt.has_3d, p.dt.has_3d)
    keep = np.nonzero(valid_d[p.pair_dt] & valid_g[p.pair_gt])[0]
    out = np.zeros(len(p.pair_gt))
    fn = iou_bev_pairs if metric == "bev" else iou_3d_pairs
    out[keep] = fn(p.dt.box7, p.gt.box7, p.pair_dt[keep], p.pair_gt[keep])
    return out


def dontcare_overlap(dt: Objects, dc: Objects) -> np.ndarray:
    """(D,) for each detection, its largest overlap with a DontCare region of its frame, measured
    over the detection's own area (the devkit's criterion 0)."""
    out = np.zeros(len(dt.score))
    _, i_dt, i_dc = frame_pairs(dt.start, dc.start)
    if len(i_dt):
        a = dt.bbox[i_dt]
        ov = _safe_div(_inter_2d(a, dc.bbox[i_dc]), _area_2d(a))
        np.maximum.at(out, i_dt, ov)
    return out
