"""A literal, unoptimised Python transliteration of the devkit's evaluation (evaluate_object.cpp:
cleanData, computeStatistics, getThresholds, eval_class, the AP sums), frame by frame and threshold
by threshold, on dense IoU matrices from `kitti.iou`. The tests hold `kitti.eval` to it, exactly."""

from __future__ import annotations

import numpy as np

from kitti import iou_2d, iou_3d, iou_bev
from kitti.labels import Object3D

MIN_HEIGHT = [40, 25, 25]
MAX_OCCLUSION = [0, 1, 2]
MAX_TRUNCATION = [0.15, 0.3, 0.5]
N_SAMPLE_PTS = 41
NO_DETECTION = -10000000


def _valid3d(o: Object3D, metric: str) -> bool:
    if o.location[0] == -1000 or o.location[2] == -1000 or o.w <= 0 or o.l <= 0:
        return False
    return metric == "bev" or (o.location[1] != -1000 and o.h > 0)


def overlap_matrix(dets: list[Object3D], gts: list[Object3D], metric: str) -> np.ndarray:
    """(D, G) boxoverlap(det, gt); 0 where a box has no such extent (DontCare, 2D-only)."""
    out = np.zeros((len(dets), len(gts)))
    if not dets or not gts:
        return out
    if metric == "2d":
        return iou_2d(np.array([d.bbox for d in dets]), np.array([g.bbox for g in gts]))
    fn = iou_bev if metric == "bev" else iou_3d
    for j, d in enumerate(dets):
        for i, g in enumerate(gts):
            if _valid3d(d, metric) and _valid3d(g, metric):
                out[j, i] = fn(d.box7[None], g.box7[None])[0, 0]
    return out


def dc_overlap(det: Object3D, dc: Object3D) -> float:
    a, b = det.bbox, dc.bbox
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    if w <= 0 or h <= 0:
        return 0.0
    return w * h / ((a[2] - a[0]) * (a[3] - a[1]))


def clean_data(cls, gt, det, difficulty):
    ignored_gt, ignored_det, dc, n_gt = [], [], [], 0
    for g in gt:
        height = g.bbox[3] - g.bbox[1]
        if g.type.lower() == cls.lower():
            valid_class = 1
        elif cls.lower() == "pedestrian" and g.type.lower() == "person_sitting":
            valid_class = 0
        elif cls.lower() == "car" and g.type.lower() == "van":
            valid_class = 0
        else:
            valid_class = -1
        ignore = (g.occluded > MAX_OCCLUSION[difficulty] or g.truncated > MAX_TRUNCATION[difficulty]
                  or height < MIN_HEIGHT[difficulty])
        if valid_class == 1 and not ignore:
            ignored_gt.append(0)
            n_gt += 1
        elif valid_class == 0 or (ignore and valid_class == 1):
            ignored_gt.append(1)
        else:
            ignored_gt.append(-1)
    for g in gt:
        if g.type.lower() == "dontcare":
            dc.append(g)
    for d in det:
        valid_class = 1 if d.type.lower() == cls.lower() else -1
        height = int(abs(d.bbox[1] - d.bbox[3]))
        if height < MIN_HEIGHT[difficulty]:
            ignored_det.append(1)
        elif valid_class == 1:
            ignored_det.append(0)
        else:
            ignored_det.append(-1)
    return ignored_gt, dc, ignored_det, n_gt


def compute_statistics(gt, det, dc, ignored_gt, ignored_det, compute_fp, ov, min_overlap,
                       use_dc, compute_aos=False, thresh=0.0):
    tp = fp = fn = 0
    v, delta = [], []
    similarity = 0.0
    assigned = [False] * len(det)
    ignored_threshold = [compute_fp and d.score < thresh for d in det]
    for i in range(len(gt)):
        if ignored_gt[i] == -1:
            continue
        det_idx, valid_detection, max_overlap, assigned_ignored_det = -1, NO_DETECTION, 0.0, False
        for j in range(len(det)):
            if ignored_det[j] == -1 or assigned[j] or ignored_threshold[j]:
                continue
            overlap = ov[j, i]
            if not compute_fp and overlap > min_overlap and det[j].score > valid_detection:
                det_idx, valid_detection = j, det[j].score
            elif (compute_fp and overlap > min_overlap and (overlap > max_overlap or assigned_ignored_det)
                  and ignored_det[j] == 0):
                max_overlap, det_idx, valid_detection, assigned_ignored_det = overlap, j, 1, False
            elif (compute_fp and overlap > min_overlap and valid_detection == NO_DETECTION
                  and ignored_det[j] == 1):
                det_idx, valid_detection, assigned_ignored_det = j, 1, True
        if valid_detection == NO_DETECTION and ignored_gt[i] == 0:
            fn += 1
        elif valid_detection != NO_DETECTION and (ignored_gt[i] == 1 or ignored_det[det_idx] == 1):
            assigned[det_idx] = True
        elif valid_detection != NO_DETECTION:
            tp += 1
            v.append(det[det_idx].score)
            if compute_aos:
                delta.append(gt[i].alpha - det[det_idx].alpha)
            assigned[det_idx] = True
    if compute_fp:
        for j in range(len(det)):
            if not (assigned[j] or ignored_det[j] == -1 or ignored_det[j] == 1 or ignored_threshold[j]):
                fp += 1
        nstuff = 0
        if use_dc:
            for d in dc:
                for j in range(len(det)):
                    if assigned[j] or ignored_det[j] in (-1, 1) or ignored_threshold[j]:
                        continue
                    if dc_overlap(det[j], d) > min_overlap:
                        assigned[j] = True
                        nstuff += 1
        fp -= nstuff
        if compute_aos:
            tmp = [0.0] * fp + [(1.0 + np.cos(x)) / 2.0 for x in delta]
            similarity = sum(tmp, 0.0) if (tp > 0 or fp > 0) else -1
    return tp, fp, fn, v, similarity


def get_thresholds(v, n_gt):
    v = sorted(v, reverse=True)
    t, current = [], 0.0
    for i in range(len(v)):
        l_recall = (i + 1) / n_gt
        r_recall = (i + 2) / n_gt if i < len(v) - 1 else l_recall
        if (r_recall - current) < (current - l_recall) and i < len(v) - 1:
            continue
        t.append(v[i])
        current += 1.0 / (N_SAMPLE_PTS - 1.0)
    return t


def eval_class(gts, dets, cls, difficulty, metric, min_overlap, compute_aos):
    """(precision[41], aos[41] or None) for lists of frames (truth incl. DontCare, detections)."""
    use_dc = metric == "2d"
    n_gt, v, cache = 0, [], []
    for gt, det in zip(gts, dets):
        ig_gt, dc, ig_det, n = clean_data(cls, gt, det, difficulty)
        n_gt += n
        ov = overlap_matrix(det, gt, metric)
        cache.append((ig_gt, dc, ig_det, ov))
        v += compute_statistics(gt, det, dc, ig_gt, ig_det, False, ov, min_overlap, use_dc)[3]
    thresholds = get_thresholds(v, n_gt) if n_gt else []
    tp = [0] * len(thresholds)
    fp = [0] * len(thresholds)
    sim = [0.0] * len(thresholds)
    for (gt, det), (ig_gt, dc, ig_det, ov) in zip(zip(gts, dets), cache):
        for t, th in enumerate(thresholds):
            a, b, _, _, s = compute_statistics(gt, det, dc, ig_gt, ig_det, True, ov, min_overlap,
                                               use_dc, compute_aos, th)
            tp[t] += a
            fp[t] += b
            if compute_aos and s != -1:
                sim[t] += s
    precision = [0.0] * N_SAMPLE_PTS
    aos = [0.0] * N_SAMPLE_PTS
    for i in range(len(thresholds)):
        precision[i] = tp[i] / (tp[i] + fp[i])
        aos[i] = sim[i] / (tp[i] + fp[i])
    for i in range(len(thresholds)):
        precision[i] = max(precision[i:])
        aos[i] = max(aos[i:])
    return precision, (aos if compute_aos else None)


def ap(vals, r40: bool) -> float:
    s = np.float32(0)
    for i in (range(1, N_SAMPLE_PTS) if r40 else range(0, N_SAMPLE_PTS, 4)):
        s = np.float32(float(s) + vals[i])
    return float(np.float32(np.float32(s / np.float32(40 if r40 else 11)) * np.float32(100)))


# ---------------------------------------------------------------------------------------------
# kitti.eval against the transliteration, on crowded random frames that exercise every rule

import pytest  # noqa: E402

from kitti.eval import evaluate  # noqa: E402

GT_TYPES = ["Car", "Car", "Van", "Pedestrian", "Pedestrian", "Person_sitting", "Cyclist", "Truck",
            "DontCare"]
DT_TYPES = ["Car", "Car", "Van", "Pedestrian", "Cyclist"]


def _object(rng, t, base, score=None, alpha=None):
    """A box near one of the frame's few anchor places, so boxes overlap and compete."""
    x, z, u, v = base
    h, w, l = (1.5, 1.6, 3.9) if t in ("Car", "Van", "Truck") else (1.7, 0.6, 0.9)
    h, w, l = h * rng.uniform(0.8, 1.2), w * rng.uniform(0.8, 1.2), l * rng.uniform(0.8, 1.2)
    loc = [x + rng.normal(0, 0.4), 1.6 + rng.normal(0, 0.1), z + rng.normal(0, 0.4)]
    height = float(rng.choice([rng.uniform(15, 60), 25.0, 40.0, 24.6, 39.7]))  # corner heights
    width = height * rng.uniform(0.8, 1.6)
    u1, v1 = u + rng.normal(0, 4), v + rng.normal(0, 4)
    bbox = [u1, v1, u1 + width, v1 + height]
    ry = rng.uniform(-np.pi, np.pi)
    return Object3D(t, float(rng.choice([0.0, 0.1, 0.2, 0.4, 0.6])), int(rng.integers(0, 4)),
                    float(rng.uniform(-np.pi, np.pi) if alpha is None else alpha), bbox, h, w, l,
                    loc, ry, score)


def random_set(seed: int, frames: int = 30, alpha_invalid: bool = False):
    rng = np.random.default_rng(seed)
    gt, dt = {}, {}
    for f in range(frames):
        bases = [(rng.uniform(-8, 8), rng.uniform(5, 40), rng.uniform(100, 1000), rng.uniform(100, 250))
                 for _ in range(rng.integers(1, 4))]
        g = [_object(rng, str(rng.choice(GT_TYPES)), bases[rng.integers(len(bases))])
             for _ in range(rng.integers(0, 9))]
        g = [Object3D.dont_care(o.bbox) if o.type == "DontCare" else o for o in g]
        d = [_object(rng, str(rng.choice(DT_TYPES)), bases[rng.integers(len(bases))],
                     score=float(np.round(rng.uniform(0, 1), 1)),  # ties on purpose
                     alpha=-10.0 if alpha_invalid else None)
             for _ in range(rng.integers(0, 12))]
        # copies of truth boxes with small noise: true positives at every metric
        for o in g:
            if o.type != "DontCare" and rng.random() < 0.6:
                c = Object3D(o.type if rng.random() < 0.8 else "Car", 0.0, 0, o.alpha + rng.normal(0, 0.3),
                             o.bbox + rng.normal(0, 1.5, 4), o.h, o.w, o.l,
                             o.location + rng.normal(0, 0.1, 3), o.rotation_y + rng.normal(0, 0.05),
                             float(rng.uniform(0, 1)))
                d.insert(int(rng.integers(0, len(d) + 1)), c)
        gt[f"{f:06d}"], dt[f"{f:06d}"] = g, d
    dt.pop("000003", None)  # a frame without a result file
    return gt, dt


def _reference(gt, dt, cls, metric, loose=False):
    ids = sorted(gt)
    gts, dets = [gt[i] for i in ids], [dt.get(i, []) for i in ids]
    strict = {"car": 0.7, "pedestrian": 0.5, "cyclist": 0.5}[cls.lower()]
    min_ov = ({"car": 0.5, "pedestrian": 0.25, "cyclist": 0.25}[cls.lower()] if loose else strict)
    out = {"R11": [], "R40": []}
    aos = {"R11": [], "R40": []}
    for diff in range(3):
        prec, a = eval_class(gts, dets, cls, diff, metric, min_ov, metric == "2d")
        for key in out:
            out[key].append(ap(prec, key == "R40"))
            if a is not None:
                aos[key].append(ap(a, key == "R40"))
    return out, aos


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matches_the_devkit_transliteration_exactly(seed):
    gt, dt = random_set(seed)
    res = evaluate(gt, dt)
    checked = 0
    for cls in ("Car", "Pedestrian", "Cyclist"):
        for metric in ("2d", "bev", "3d"):
            ref, ref_aos = _reference(gt, dt, cls, metric)
            assert res.ap[cls][metric] == ref, (cls, metric)
            if metric == "2d":
                assert res.ap[cls]["aos"] == ref_aos, cls
            else:
                ref_loose, _ = _reference(gt, dt, cls, metric, loose=True)
                assert res.ap_loose[cls][metric] == ref_loose, (cls, metric)
            checked += sum(v > 0 for v in ref["R40"])
    assert checked >= 10  # the random sets are not all-zero cases


def test_aos_absent_when_any_alpha_is_minus_10():
    gt, dt = random_set(5, frames=8, alpha_invalid=True)
    res = evaluate(gt, dt)
    for cls in ("Car", "Pedestrian", "Cyclist"):
        assert "aos" not in res.ap[cls]
        assert "alpha" in res.absent[cls]["aos"]
        ref, _ = _reference(gt, dt, cls, "2d")
        assert res.ap[cls]["2d"] == ref


def test_pair_overlaps_equal_the_dense_kitti_iou_bit_for_bit():
    from kitti.eval.frames import pack
    from kitti.eval.overlaps import dontcare_overlap, pair_overlaps

    gt, dt = random_set(7, frames=12)
    p = pack(gt, dt)
    ovs = {m: pair_overlaps(p, m) for m in ("2d", "bev", "3d")}
    dc = dontcare_overlap(p.dt, p.dc)
    assert len(p.ids) == 12 and sum(len(v) for v in dt.values()) > 0
    for f, fid in enumerate(p.ids):
        truth = [o for o in gt[fid] if o.type != "DontCare"]
        dets = dt.get(fid, [])
        block = slice(p.pair_start[f], p.pair_start[f + 1])
        for m, ov in ovs.items():
            dense = overlap_matrix(dets, truth, m)  # (D, G) from kitti.iou
            assert np.array_equal(ov[block].reshape(len(truth), len(dets)), dense.T), (fid, m)
        care = [o for o in gt[fid] if o.type == "DontCare"]
        for j, d in enumerate(dets):
            want = max([dc_overlap(d, c) for c in care], default=0.0)
            assert dc[p.dt.start[f] + j] == want
