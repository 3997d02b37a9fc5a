"""Auto-anchors (thesis 000, algorithm 4.1): k-means over label box sizes with 1 - IoU as the
distance, so small and large boxes are clustered by shape agreement rather than by pixel
differences that favour big boxes. IoU here is between boxes sharing one centre.
"""
from __future__ import annotations

import numpy as np


def wh_iou(wh: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """(N,2) x (K,2) -> (N,K) IoU of centre-aligned boxes."""
    inter = np.minimum(wh[:, None, 0], anchors[None, :, 0]) * np.minimum(wh[:, None, 1], anchors[None, :, 1])
    union = wh[:, 0:1] * wh[:, 1:2] + (anchors[:, 0] * anchors[:, 1])[None, :] - inter
    return inter / union


def kmeans_anchors(wh: np.ndarray, k: int = 9, rng: np.random.Generator | None = None,
                   max_iter: int = 300) -> np.ndarray:
    """Cluster box sizes (N,2) into k anchors (k,2), sorted by area (small first).

    Initialised by k-means++ under the 1 - IoU distance, then the thesis's refinement: assign
    each box to the anchor of highest IoU, move each anchor to its cluster's mean size, and
    repeat until no anchor moves. An anchor left with no box keeps its place.
    """
    wh = np.asarray(wh, dtype=np.float64).reshape(-1, 2)
    wh = wh[(wh > 0).all(1)]
    if len(wh) < k:
        raise ValueError(f"k-means anchors need at least {k} boxes with positive size, got {len(wh)}")
    rng = rng if rng is not None else np.random.default_rng(0)
    centres = [wh[rng.integers(len(wh))]]
    for _ in range(1, k):
        d = 1 - wh_iou(wh, np.array(centres)).max(1)
        d2 = d ** 2
        total = d2.sum()
        idx = rng.choice(len(wh), p=d2 / total) if total > 0 else rng.integers(len(wh))
        centres.append(wh[idx])
    anchors = np.array(centres, dtype=np.float64)
    assign = None
    for _ in range(max_iter):
        new_assign = wh_iou(wh, anchors).argmax(1)
        if assign is not None and np.array_equal(new_assign, assign):
            break
        assign = new_assign
        for j in range(k):
            members = wh[assign == j]
            if len(members):
                anchors[j] = members.mean(0)
    return anchors[np.argsort(anchors.prod(1), kind="stable")]


def best_possible_recall(wh: np.ndarray, anchors: np.ndarray, ratio_limit: float = 4.0) -> float:
    """Share of boxes that some anchor can be trained on: width and height ratios both within
    ratio_limit (the loss's matching rule)."""
    wh = np.asarray(wh, dtype=np.float64).reshape(-1, 2)
    r = wh[:, None, :] / np.asarray(anchors, dtype=np.float64)[None]
    worst = np.maximum(r, 1 / r).max(2)
    return float((worst.min(1) < ratio_limit).mean())
