"""AP of one class, difficulty and metric from the two passes, as the devkit computes it.

Precision at the t-th threshold stands for recall t/40 (the devkit never interpolates on the
measured recall); precision is made monotone (`p[i] = max(p[i:])`); AP|R11 averages slots
0, 4, ..., 40 (recall 0 included) and AP|R40 slots 1..40, in single precision as the devkit
does. Fewer than 41 thresholds (recall never reaches 1) leave the remaining slots at 0. A threshold
where no detection counts (TP + FP = 0, possible only when every detection went to ignored truth)
has precision 0 here; the devkit would divide 0 by 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import matching
from .frames import Packed
from .protocol import N_SAMPLE_PTS


@dataclass
class Curve:
    """Monotone precision (and orientation similarity) at the 41 recall slots."""

    precision: np.ndarray  # (41,)
    aos: np.ndarray | None  # (41,) when orientation is scored
    n_gt: int
    recall: float  # with every detection (no score threshold); 0 without truth

    @staticmethod
    def r11(p: np.ndarray) -> float:
        return _devkit_mean(p, range(0, N_SAMPLE_PTS, 4), 11)

    @staticmethod
    def r40(p: np.ndarray) -> float:
        return _devkit_mean(p, range(1, N_SAMPLE_PTS), 40)


def _devkit_mean(p: np.ndarray, slots: range, n: int) -> float:
    """The devkit sums precision into a C `float` and prints `sum / n * 100` in float: replicated,
    so our numbers are the devkit's to the last printed digit."""
    s = np.float32(0.0)
    for i in slots:
        s = np.float32(float(s) + float(p[i]))
    return float(np.float32(np.float32(s / np.float32(n)) * np.float32(100)))


@dataclass
class Selection:
    """The rows taking part in one evaluation (flag != -1), per frame, for the compiled passes."""

    rel_gt: np.ndarray
    rel_gt_start: np.ndarray
    rel_dt: np.ndarray
    rel_dt_start: np.ndarray

    @classmethod
    def of(cls, p: Packed, ig_gt: np.ndarray, ig_dt: np.ndarray) -> "Selection":
        rel_gt = np.nonzero(ig_gt != -1)[0].astype(np.int64)
        rel_dt = np.nonzero(ig_dt != -1)[0].astype(np.int64)
        return cls(rel_gt, np.searchsorted(rel_gt, p.gt.start).astype(np.int64),
                   rel_dt, np.searchsorted(rel_dt, p.dt.start).astype(np.int64))


def curve(p: Packed, ov: np.ndarray, ig_gt: np.ndarray, ig_dt: np.ndarray, min_ov: float,
          dc_ov: np.ndarray | None, compute_aos: bool) -> Curve:
    """Both passes over all frames for one (class, difficulty, metric[, subset])."""
    sel = Selection.of(p, ig_gt, ig_dt)
    common = (p.gt.start, p.dt.start, p.pair_start, sel.rel_gt, sel.rel_gt_start, sel.rel_dt,
              sel.rel_dt_start, ov, ig_gt, ig_dt, p.dt.score)
    n_gt = int((ig_gt == 0).sum())
    scores = matching.first_pass(*common, float(min_ov))
    thr = matching.thresholds(scores, float(n_gt), float(N_SAMPLE_PTS)) if n_gt else np.zeros(0)
    use_dc = dc_ov is not None
    # one extra threshold below every score gives the recall with all detections
    tp, fp, _fn, sim = matching.second_pass(
        *common, p.gt.alpha, p.dt.alpha, dc_ov if use_dc else np.zeros(len(ig_dt)), use_dc,
        compute_aos, float(min_ov), np.append(thr, -np.inf))
    recall = float(tp[-1] / n_gt) if n_gt else 0.0
    n = len(thr)
    tp, fp, sim = tp[:n], fp[:n], sim[:n]
    prec = np.zeros(N_SAMPLE_PTS)
    den = tp + fp
    prec[:n] = np.where(den > 0, tp / np.maximum(den, 1), 0.0)
    prec = np.maximum.accumulate(prec[::-1])[::-1]
    aos = None
    if compute_aos:
        aos = np.zeros(N_SAMPLE_PTS)
        aos[:n] = np.where(den > 0, sim / np.maximum(den, 1), 0.0)
        aos = np.maximum.accumulate(aos[::-1])[::-1]
    return Curve(prec, aos, n_gt, recall)
