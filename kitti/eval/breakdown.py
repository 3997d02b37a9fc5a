"""The testbed's breakdowns: which detection belongs to which truth, and how wrong it is.

Two one-to-one matchings per frame and class (any difficulty, every detection unless a minimum
score is given), both greedy on the best pair first:
- "iou3d": 3D IoU strictly above a threshold (default 0.5), highest IoU first;
- "centre": the lenient one, nearest geometric centres first, accepted within
  max(2 m, 10 % of the truth's ground distance), so a box that is placed right but sized or turned
  wrong still counts.
Distances are ground-plane (camera x-z) distances of the box location, the same as for the
per-distance-bin AP; a pair is binned by its truth.
"""

from __future__ import annotations

import numba
import numpy as np

from .frames import Packed
from .volumetric import centres, volumetric

MATCHINGS = ("iou3d", "centre")
CENTRE_GATE_M = 2.0
CENTRE_GATE_FRACTION = 0.10


@numba.njit(cache=True, nogil=True)
def _greedy(a: np.ndarray, b: np.ndarray, n_a: int, n_b: int) -> np.ndarray:
    """Keep pair k (in the given order) when neither of its ends is taken yet."""
    used_a = np.zeros(n_a, np.bool_)
    used_b = np.zeros(n_b, np.bool_)
    keep = np.zeros(len(a), np.bool_)
    for k in range(len(a)):
        if not used_a[a[k]] and not used_b[b[k]]:
            used_a[a[k]] = True
            used_b[b[k]] = True
            keep[k] = True
    return keep


def match(p: Packed, cls: str, ov3d: np.ndarray, how: str, iou_threshold: float = 0.5,
          min_score: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(truth rows, detection rows) of the one-to-one matches of class `cls`."""
    c = cls.lower()
    g, d = p.pair_gt, p.pair_dt
    ok = ((p.gt.type[g] == c) & (p.dt.type[d] == c) & p.gt.has_3d[g] & p.dt.has_3d[d])
    if min_score is not None:
        ok &= p.dt.score[d] >= min_score
    k = np.nonzero(ok)[0]
    if how == "iou3d":
        key = ov3d[k]
        sel = key > iou_threshold
        k, key = k[sel], -key[sel]
    elif how == "centre":
        dist = np.linalg.norm(centres(p.dt.box7[d[k]]) - centres(p.gt.box7[g[k]]), axis=1)
        gate = np.maximum(CENTRE_GATE_M, CENTRE_GATE_FRACTION * p.gt.distance[g[k]])
        sel = dist <= gate
        k, key = k[sel], dist[sel]
    else:
        raise ValueError(f"unknown matching '{how}' (iou3d or centre)")
    k = k[np.lexsort((k, key))]  # best first, ties in file order
    keep = _greedy(g[k], d[k], len(p.gt.score), len(p.dt.score))
    return g[k[keep]], d[k[keep]]


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def _stats(x: np.ndarray, signed: bool) -> dict:
    if len(x) == 0:
        out = {"mean": None, "median": None}
        return {**out, "bias": None} if signed else out
    a = np.abs(x)
    out = {"mean": float(a.mean()), "median": float(np.median(a))}
    return {**out, "bias": float(x.mean())} if signed else out


def pair_errors(gt7: np.ndarray, dt7: np.ndarray) -> dict:
    """Error summary of matched pairs: metres, and degrees for yaw. `mean`/`median` are of the
    absolute error, `bias` the mean signed error (detection minus truth)."""
    cg, cd = centres(gt7), centres(dt7)
    yaw = np.abs(_wrap(dt7[:, 6] - gt7[:, 6]))
    return {"n": int(len(gt7)),
            "centre": _stats(np.linalg.norm(cd - cg, axis=1), False),
            "depth": _stats(cd[:, 2] - cg[:, 2], True),
            "h": _stats(dt7[:, 3] - gt7[:, 3], True),
            "w": _stats(dt7[:, 4] - gt7[:, 4], True),
            "l": _stats(dt7[:, 5] - gt7[:, 5], True),
            "yaw_deg": _stats(np.degrees(yaw), False),
            "yaw_mod_pi_deg": _stats(np.degrees(np.minimum(yaw, np.pi - yaw)), False)}


def bin_index(distance: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Bin of each distance in [edges[k], edges[k+1]); -1 outside every bin."""
    k = np.searchsorted(edges, distance, side="right") - 1
    return np.where((k >= 0) & (k < len(edges) - 1), k, -1)


def pair_breakdowns(p: Packed, classes: list[str], ov3d: np.ndarray, edges: np.ndarray | None,
                    match_iou: float, min_score: float | None, max_distance: float) -> tuple[dict, dict]:
    """({matching: {class: errors}}, {matching: {class: volumetric}}), overall and per bin."""
    errors: dict = {}
    vol: dict = {}
    for how in MATCHINGS:
        errors[how], vol[how] = {}, {}
        for cls in classes:
            gi, dj = match(p, cls, ov3d, how, match_iou, min_score)
            g7, d7 = p.gt.box7[gi], p.dt.box7[dj]
            of_cls = (p.gt.type == cls.lower()) & p.gt.has_3d
            e = {"all": {**pair_errors(g7, d7), "n_gt": int(of_cls.sum())}}
            v = {"all": volumetric(g7, d7, max_distance)}
            if edges is not None:
                kb, kg = bin_index(p.gt.distance[gi], edges), bin_index(p.gt.distance, edges)
                e["bins"], v["bins"] = [], []
                for k in range(len(edges) - 1):
                    rng = [float(edges[k]), float(edges[k + 1])]
                    sel = kb == k
                    e["bins"].append({"range": rng, **pair_errors(g7[sel], d7[sel]),
                                      "n_gt": int((of_cls & (kg == k)).sum())})
                    v["bins"].append({"range": rng, **volumetric(g7[sel], d7[sel], max_distance)})
            errors[how][cls], vol[how][cls] = e, v
    return errors, vol
