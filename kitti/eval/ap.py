"""AP of one class, difficulty and metric from the two passes, as the devkit computes it.

Precision at the t-th threshold stands for recall t/40 (the devkit never interpolates on the
measured recall); precision is made monotone (`p[i] = max(p[i:])`); AP|R11 averages slots
0, 4, ..., 40 (recall 0 included) and AP|R40 slots 1..40, in single precision as the devkit
does. Fewer than 41 thresholds (recall never reaches 1) leave the remaining slots at 0. A threshold
where no detection counts (TP + FP = 0, possible only when every detection went to ignored truth)
has precision 0 here; the devkit would divide 0 by 0.

With fewer than 41 truth boxes the devkit's slots misstate recall: each found box adds one
threshold, the t-th stands for recall t/40 though it measured t/n, and AP|R40 cannot exceed
(n - 1)/40 (32.5 on 14 cars, however well they are found). `Curve.r40_measured` reads the same
thresholds on their measured recall instead: AP|R40 as it is defined (Simonelli et al., "Disentangling
Monocular 3D Object Detection", ICCV 2019: the mean over recall r = 1/40 ... 1 of the highest
precision at a recall >= r). With 41 or more truth boxes the devkit keeps the threshold nearest
each k/40 and the two agree to within a slot, 2.5 points, the measured figure the lower: a threshold
just short of k/40 counts only for the slot below (on 1,000 generated frames, Car 2D moderate 91.3
against the devkit's 91.6, easy 97.4 against 99.8, where recall stops at 98.7 %;
`benchmarks/ap_few_frames.py` draws small sets from such a set to show what a few frames tell).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from . import matching
from .frames import Packed
from .protocol import N_SAMPLE_PTS


def devkit_cap(n_gt: int) -> float:
    """The highest AP|R40 the devkit can give with n_gt evaluated truth boxes: each true positive
    adds one threshold and the t-th fills slot t, so fewer than 41 leave slots empty: (n_gt - 1)
    / 40, times 100 (32.5 for the real dev frames' 14 moderate Cars, whatever the detector)."""
    return 100.0 * min(max(n_gt - 1, 0), N_SAMPLE_PTS - 1) / (N_SAMPLE_PTS - 1)


def capped(n_gt: int) -> bool:
    """Whether n_gt truth boxes (some, but 40 or fewer) keep the devkit's AP|R40 below 100."""
    return 0 < n_gt and devkit_cap(n_gt) < 100.0


@dataclass
class Curve:
    """Monotone precision (and orientation similarity) at the 41 recall slots, and at each of the
    devkit's thresholds its found truth boxes (raw precision and similarity, not yet monotone)."""

    precision: np.ndarray  # (41,)
    aos: np.ndarray | None  # (41,) when orientation is scored
    n_gt: int
    recall: float  # with every detection (no score threshold); 0 without truth
    found: np.ndarray  # (T,) true positives at each threshold
    precision_at: np.ndarray  # (T,)
    aos_at: np.ndarray | None  # (T,) when orientation is scored

    @staticmethod
    def r11(p: np.ndarray) -> float:
        return float(_devkit_mean(p, 0, 4, 11))

    @staticmethod
    def r40(p: np.ndarray) -> float:
        return float(_devkit_mean(p, 1, 1, 40))

    def r40_measured(self, values_at: np.ndarray) -> float:
        """AP|R40 on the measured recall (module docstring): `values_at` (precision_at or
        aos_at) interpolated at recall k/40, k = 1..40, as the highest at any threshold whose
        found boxes reach k/40 of the truth (0 where none does), times 100."""
        slots = np.arange(1, N_SAMPLE_PTS)
        reach = self.found[None, :] * (N_SAMPLE_PTS - 1) >= slots[:, None] * self.n_gt  # exact
        best = np.where(reach, values_at[None, :], 0.0).max(axis=1, initial=0.0)
        return float(100.0 * best.mean())


@numba.njit(cache=True, nogil=True)
def _devkit_mean(p, start, step, n):
    """The devkit sums precision (p[start::step] of the N_SAMPLE_PTS values) into a C `float`,
    each step a double sum rounded to float, and prints `sum / n * 100` in float: replicated, so
    our numbers are the devkit's to the last printed digit."""
    s = np.float32(0.0)
    for i in range(start, N_SAMPLE_PTS, step):
        s = np.float32(np.float64(s) + np.float64(p[i]))
    return np.float32(np.float32(s / np.float32(n)) * np.float32(100.0))


@dataclass
class Selection:
    """The rows taking part in one evaluation (flag != -1), per frame, for the compiled passes."""

    rel_gt: np.ndarray
    rel_gt_start: np.ndarray
    rel_dt: np.ndarray
    rel_dt_start: np.ndarray

    @classmethod
    def of(cls, p: Packed, ig_gt: np.ndarray, ig_dt: np.ndarray) -> Selection:
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
    den = tp + fp
    prec_at = np.where(den > 0, tp / np.maximum(den, 1), 0.0)
    prec = np.zeros(N_SAMPLE_PTS)
    prec[:n] = prec_at
    prec = np.maximum.accumulate(prec[::-1])[::-1]
    aos = aos_at = None
    if compute_aos:
        aos_at = np.where(den > 0, sim / np.maximum(den, 1), 0.0)
        aos = np.zeros(N_SAMPLE_PTS)
        aos[:n] = aos_at
        aos = np.maximum.accumulate(aos[::-1])[::-1]
    return Curve(prec, aos, n_gt, recall, tp.astype(np.int64), prec_at, aos_at)
