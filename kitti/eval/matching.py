"""The devkit's `computeStatistics` and `getThresholds`, compiled.

The official matching is greedy in truth order and changes with every score threshold, so it is a
loop by nature; numba runs the loops exactly as the C++ does (same order, same ties, same branch
structure), which keeps the numbers identical and a KITTI-val-sized evaluation within seconds.

Arrays: `gt_start`/`dt_start` give each frame's rows, `pair_start` its row-major truth x detection
overlap block; `rel_gt`/`rel_dt` list the rows taking part (ignored flag != -1, in file order) and
`rel_gt_start`/`rel_dt_start` index them per frame. Rows with flag -1 never influence anything in
the devkit, so skipping them changes no result.
"""

from __future__ import annotations

import numba
import numpy as np

NO_DETECTION = -10000000.0


@numba.njit(cache=True, nogil=True)
def first_pass(gt_start, dt_start, pair_start, rel_gt, rel_gt_start, rel_dt, rel_dt_start, ov,
               ig_gt, ig_dt, score, min_ov):
    """Scores of the true positives when each truth takes its highest-scoring match (pass 1)."""
    out = np.empty(len(rel_gt))
    n = 0
    assigned = np.zeros(len(ig_dt), np.bool_)
    for f in range(len(gt_start) - 1):
        nd = dt_start[f + 1] - dt_start[f]
        for a in range(rel_gt_start[f], rel_gt_start[f + 1]):
            gi = rel_gt[a]
            row = pair_start[f] + (gi - gt_start[f]) * nd - dt_start[f]
            det = -1
            valid = NO_DETECTION
            for b in range(rel_dt_start[f], rel_dt_start[f + 1]):
                dj = rel_dt[b]
                if assigned[dj]:
                    continue
                if ov[row + dj] > min_ov and score[dj] > valid:
                    det = dj
                    valid = score[dj]
            if valid == NO_DETECTION:
                continue
            assigned[det] = True
            if ig_gt[gi] == 0 and ig_dt[det] == 0:
                out[n] = score[det]
                n += 1
    return out[:n]


@numba.njit(cache=True, nogil=True)
def thresholds(scores, n_gt, n_sample_pts):
    """Scores at which recall passes 0, 1/40, ..., 1 (the devkit's getThresholds, same arithmetic)."""
    v = -np.sort(-scores)
    t = np.empty(len(v))
    n = 0
    current = 0.0
    for i in range(len(v)):
        l_recall = (i + 1) / n_gt
        r_recall = (i + 2) / n_gt if i < len(v) - 1 else l_recall
        if (r_recall - current) < (current - l_recall) and i < len(v) - 1:
            continue
        t[n] = v[i]
        n += 1
        current += 1.0 / (n_sample_pts - 1.0)
    return t[:n]


@numba.njit(cache=True, nogil=True)
def second_pass(gt_start, dt_start, pair_start, rel_gt, rel_gt_start, rel_dt, rel_dt_start, ov,
                ig_gt, ig_dt, score, gt_alpha, dt_alpha, dc_ov, use_dc, compute_aos, min_ov, thr):
    """TP, FP, FN and orientation similarity at each threshold (pass 2): each truth takes the
    highest-overlap detection above the threshold, falling back on an ignored one.

    A frame's matching depends on the threshold only through which of its detections reach it:
    where a lower threshold admits none more of them than the threshold before it, the frame's
    counts are the ones just computed and are added again (the devkit's thresholds fall, so a
    frame with k detections is matched at most k + 1 times, not once per threshold)."""
    nt = len(thr)
    tp = np.zeros(nt, np.int64)
    fp = np.zeros(nt, np.int64)
    fn = np.zeros(nt, np.int64)
    sim = np.zeros(nt)
    assigned = np.zeros(len(ig_dt), np.bool_)
    for f in range(len(gt_start) - 1):
        nd = dt_start[f + 1] - dt_start[f]
        d0, d1 = rel_dt_start[f], rel_dt_start[f + 1]
        g0, g1 = rel_gt_start[f], rel_gt_start[f + 1]
        if g0 == g1 and d0 == d1:
            continue
        ftp = 0
        ffp = 0
        ffn = 0
        fsim = 0.0
        admitted = -1  # detections reaching the previous threshold (none computed yet)
        for t in range(nt):
            th = thr[t]
            n_in = 0
            for b in range(d0, d1):
                if score[rel_dt[b]] >= th:
                    n_in += 1
            if n_in == admitted and t > 0 and th <= thr[t - 1]:  # the same detections: same counts
                tp[t] += ftp
                fp[t] += ffp
                fn[t] += ffn
                if compute_aos and (ftp > 0 or ffp > 0):
                    sim[t] += fsim
                continue
            admitted = n_in
            for b in range(d0, d1):
                assigned[rel_dt[b]] = False
            ftp = 0
            ffp = 0
            ffn = 0
            fsim = 0.0
            for a in range(g0, g1):
                gi = rel_gt[a]
                row = pair_start[f] + (gi - gt_start[f]) * nd - dt_start[f]
                det = -1
                valid = NO_DETECTION
                max_ov = 0.0
                assigned_ignored = False
                for b in range(d0, d1):
                    dj = rel_dt[b]
                    if assigned[dj] or score[dj] < th:
                        continue
                    o = ov[row + dj]
                    if o > min_ov and (o > max_ov or assigned_ignored) and ig_dt[dj] == 0:
                        max_ov = o
                        det = dj
                        valid = 1.0
                        assigned_ignored = False
                    elif o > min_ov and valid == NO_DETECTION and ig_dt[dj] == 1:
                        det = dj
                        valid = 1.0
                        assigned_ignored = True
                if valid == NO_DETECTION:
                    if ig_gt[gi] == 0:
                        ffn += 1
                elif ig_gt[gi] == 1 or ig_dt[det] == 1:
                    assigned[det] = True
                else:
                    ftp += 1
                    if compute_aos:
                        fsim += (1.0 + np.cos(gt_alpha[gi] - dt_alpha[det])) / 2.0
                    assigned[det] = True
            for b in range(d0, d1):
                dj = rel_dt[b]
                if not (assigned[dj] or ig_dt[dj] == 1 or score[dj] < th):
                    # DontCare: an unmatched detection inside a DontCare region is not counted
                    if not (use_dc and dc_ov[dj] > min_ov):
                        ffp += 1
            tp[t] += ftp
            fp[t] += ffp
            fn[t] += ffn
            if compute_aos and (ftp > 0 or ffp > 0):
                sim[t] += fsim
    return tp, fp, fn, sim
