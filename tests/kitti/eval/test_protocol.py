"""Hand-counted cases of the official evaluation: each test states TP, FP and ignored, and the AP
follows by hand (precision at threshold slot t stands for recall t/40; R11 = slots 0,4..40 over 11,
R40 = slots 1..40 over 40)."""

from __future__ import annotations

import numpy as np
import pytest

from kitti.eval import ap_2d, evaluate
from kitti.eval.matching import thresholds
from kitti.eval.protocol import clean
from kitti.labels import Object3D


def obj(t="Car", slot=0, score=None, height=50.0, occ=0, trunc=0.0, alpha=0.0, bbox=None,
        z=None, x=None):
    """An object in its own place: 2D column `slot` (60 px wide, 2D boxes never overlap across
    slots) and its own spot on the ground (x = 6 m * slot, z = 30 m), so 3D never overlaps either."""
    if bbox is None:
        bbox = [60.0 * slot, 100.0, 60.0 * slot + 50.0, 100.0 + height]
    loc = [6.0 * slot if x is None else x, 1.6, 30.0 if z is None else z]
    return Object3D(t, trunc, occ, alpha, np.array(bbox, float), 1.5, 1.6, 3.9, np.array(loc), 0.3, score)


def copy_as(o: Object3D, score: float, t: str | None = None, alpha: float | None = None) -> Object3D:
    return Object3D(t or o.type, 0.0, 0, o.alpha if alpha is None else alpha, o.bbox.copy(), o.h, o.w,
                    o.l, o.location.copy(), o.rotation_y, score)


def cars(n: int, frame_size: int = 10) -> dict[str, list[Object3D]]:
    """n valid (easy) cars, frame_size per frame."""
    gt: dict[str, list[Object3D]] = {}
    for k in range(n):
        gt.setdefault(f"{k // frame_size:06d}", []).append(obj("Car", k % frame_size))
    return gt


def perfect(gt: dict, t: str = "Car") -> dict:
    """One exact detection per truth box of type t, distinct scores (1, 1 - 1/1000, ...)."""
    dt, k = {}, 0
    for fid, objs in gt.items():
        dt[fid] = []
        for o in objs:
            if o.type == t:
                dt[fid].append(copy_as(o, 1.0 - k / 1000))
                k += 1
    return dt


def r(res, cls="Car", metric="2d", key="R40", d=1, loose=False):
    return (res.ap_loose if loose else res.ap)[cls][metric][key][d]


def test_one_top_hit_is_worth_9_09_r11_and_little_r40():
    # 4 valid cars; detections: TP 0.9, FP 0.8, TP 0.7. Pass 1 gives TP scores [0.9, 0.7] and
    # thresholds [0.9, 0.7] (slots 0, 1). Precision: t=0.9 -> 1/1, t=0.7 -> 2/3.
    gt = {"000000": [obj(slot=k) for k in range(4)]}
    dt = {"000000": [copy_as(gt["000000"][0], 0.9), obj(slot=7, score=0.8),
                     copy_as(gt["000000"][1], 0.7)]}
    res = evaluate(gt, dt, classes=["Car"])
    for metric in ("2d", "bev", "3d", "aos"):
        for d in range(3):
            assert r(res, metric=metric, key="R11", d=d) == pytest.approx(100 / 11, abs=1e-4)
            assert r(res, metric=metric, key="R40", d=d) == pytest.approx(100 * (2 / 3) / 40, abs=1e-4)
    assert res.n_gt["Car"] == [4, 4, 4]


def test_40_perfect_hits_fill_40_slots_41_fill_all():
    # n_gt = 40: getThresholds yields 40 thresholds, slot 40 stays 0 -> R40 39/40, R11 10/11
    gt = cars(40)
    res = evaluate(gt, perfect(gt), classes=["Car"])
    assert r(res) == pytest.approx(97.5, abs=1e-4)
    assert r(res, key="R11") == pytest.approx(1000 / 11, abs=1e-4)
    gt = cars(41)
    res = evaluate(gt, perfect(gt), classes=["Car"])
    for metric in ("2d", "bev", "3d", "aos"):
        assert res.ap["Car"][metric] == {"R11": [100.0] * 3, "R40": [100.0] * 3}


def test_false_positive_on_top_and_aos_with_known_angle_errors():
    # 41 cars found with alpha off by pi/3 (similarity (1 + cos)/2 = 3/4), plus one FP scoring above
    # all: at the k-th threshold tp = k + 1, fp = 1; precision (k+1)/(k+2) rises, so the monotone
    # curve is 41/42 in every slot, and AOS 3/4 of it.
    gt = cars(41)
    dt = perfect(gt)
    for objs in dt.values():
        for o in objs:
            o.alpha = o.alpha + np.pi / 3
    dt["000000"].append(obj(slot=12, score=2.0))
    res = evaluate(gt, dt, classes=["Car"])
    for key in ("R11", "R40"):
        assert r(res, key=key) == pytest.approx(100 * 41 / 42, abs=1e-4)
        assert r(res, metric="aos", key=key) == pytest.approx(75 * 41 / 42, abs=1e-4)
        assert r(res, metric="3d", key=key) == pytest.approx(100 * 41 / 42, abs=1e-4)
    # an angle error of pi scores 0, of 0 scores 1
    for objs in dt.values():
        for o in objs:
            o.alpha += np.pi - np.pi / 3
    assert r(evaluate(gt, dt, classes=["Car"]), metric="aos") == pytest.approx(0, abs=1e-4)


def test_dontcare_suppresses_unmatched_2d_detections_by_overlap_over_their_own_area():
    gt = cars(41)
    dc_box = [800.0, 50.0, 1200.0, 300.0]
    gt["000000"].append(Object3D.dont_care(dc_box))
    dt = perfect(gt)
    inside = obj(slot=0, score=2.0, bbox=[900, 100, 960, 160], x=-20.0)  # IoU with the region ~0.04
    dt["000000"].append(inside)
    res = evaluate(gt, dt, classes=["Car"])
    assert r(res) == 100.0 and r(res, metric="aos") == 100.0  # not a false positive in 2D
    assert r(res, metric="bev") == pytest.approx(100 * 41 / 42, abs=1e-4)  # the devkit: 2D only
    # half inside: overlap over its area 0.5, not above the Car threshold 0.7 -> a false positive
    inside.bbox = np.array([770.0, 100, 830, 160])
    assert r(evaluate(gt, dt, classes=["Car"])) == pytest.approx(100 * 41 / 42, abs=1e-4)
    # 0.8 of it inside -> suppressed again
    inside.bbox = np.array([788.0, 100, 848, 160])
    assert r(evaluate(gt, dt, classes=["Car"])) == 100.0


def test_neighbour_classes_are_ignored_other_classes_are_false_positives():
    gt = cars(41)
    van, truck = obj("Van", slot=10), obj("Truck", slot=11)
    gt["000000"] += [van, truck]
    dt = perfect(gt)
    dt["000000"].append(copy_as(van, 2.0, t="Car"))  # Car detection on a Van: ignored, no FP
    res = evaluate(gt, dt, classes=["Car"])
    assert r(res) == 100.0 and res.n_gt["Car"] == [41, 41, 41]
    dt["000000"].append(copy_as(truck, 2.0, t="Car"))  # on a Truck: truth skipped, so a FP
    assert r(evaluate(gt, dt, classes=["Car"])) == pytest.approx(100 * 41 / 42, abs=1e-4)
    # a Van detection on a car is no Car detection: that car is missed (40 of 41 found)
    gt = cars(41)
    dt = perfect(gt)
    dt["000004"][0].type = "Van"
    res = evaluate(gt, dt, classes=["Car"])
    assert r(res) == pytest.approx(97.5, abs=1e-4)
    # Person_sitting is Pedestrian's neighbour; Cyclist is not
    gt = {"000000": [obj("Pedestrian", k) for k in range(41)]}
    gt["000001"] = [obj("Person_sitting", 0), obj("Cyclist", 1)]
    dt = perfect(gt, "Pedestrian")
    dt["000001"] = [copy_as(gt["000001"][0], 2.0, t="Pedestrian")]
    assert r(evaluate(gt, dt, classes=["Pedestrian"]), "Pedestrian") == 100.0
    dt["000001"].append(copy_as(gt["000001"][1], 2.0, t="Pedestrian"))
    assert r(evaluate(gt, dt, classes=["Pedestrian"]), "Pedestrian") == pytest.approx(100 * 41 / 42, abs=1e-4)


def test_minimum_height_on_truth_and_detections():
    gt = cars(41)
    small = obj(slot=10, height=39.0)  # ignored in easy (< 40), evaluated in moderate
    dt = perfect(gt)
    gt["000000"].append(small)
    # its detection is 41 px tall (valid in easy) and overlaps it 39/41: matched to ignored truth
    dt["000000"].append(copy_as(small, 2.0))
    dt["000000"][-1].bbox[3] += 2.0
    res = evaluate(gt, dt, classes=["Car"])
    assert res.n_gt["Car"] == [41, 42, 42]
    assert r(res, d=0) == 100.0 and r(res, d=1) == 100.0
    # detections lower than the minimum are never false positives: 24.9 px in moderate, 39.9 in easy
    gt = cars(41)
    dt = perfect(gt)
    dt["000000"].append(obj(slot=11, score=2.0, height=24.9))
    res = evaluate(gt, dt, classes=["Car"])
    assert [r(res, d=d) for d in range(3)] == [100.0, 100.0, 100.0]
    dt["000000"][-1].bbox[3] += 0.1  # 25.0 px: a false positive in moderate/hard, ignored in easy
    res = evaluate(gt, dt, classes=["Car"])
    assert r(res, d=0) == 100.0
    assert r(res, d=1) == pytest.approx(100 * 41 / 42, abs=1e-4) == pytest.approx(r(res, d=2))
    # truth exactly 40.0 px tall is evaluated in easy (the devkit's `height < 40`)
    ig_gt, _ = clean("Car", 0, np.array(["car", "car"]), np.array([[0, 0, 10, 40.0], [0, 0, 10, 39.99]]),
                     np.array([0, 0]), np.array([0.0, 0.0]), np.array([], str), np.zeros((0, 4)))
    assert ig_gt.tolist() == [0, 1]


def test_difficulties_are_nested_and_use_occlusion_and_truncation():
    objs = [obj(slot=0), obj(slot=1, occ=1), obj(slot=2, occ=2), obj(slot=3, occ=3),
            obj(slot=4, trunc=0.15), obj(slot=5, trunc=0.16), obj(slot=6, trunc=0.30),
            obj(slot=7, trunc=0.31), obj(slot=8, trunc=0.5), obj(slot=9, trunc=0.51),
            obj(slot=10, height=30)]
    ig = [clean("Car", d, np.array(["car"] * 11), np.array([o.bbox for o in objs]),
                np.array([o.occluded for o in objs]), np.array([o.truncated for o in objs]),
                np.array([], str), np.zeros((0, 4)))[0].tolist() for d in range(3)]
    assert ig[0] == [0, 1, 1, 1, 0, 1, 1, 1, 1, 1, 1]
    assert ig[1] == [0, 0, 1, 1, 0, 0, 0, 1, 1, 1, 0]
    assert ig[2] == [0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0]


def test_matching_needs_overlap_strictly_above_the_threshold():
    # 2D IoU of [0,0,10,10] and [0,0,10,7] is exactly 0.7: no match for a Car, a match for 0.5
    gt = cars(41)
    dt = perfect(gt)
    o = dt["000000"][0]
    o.bbox[3] = o.bbox[1] + 0.7 * (o.bbox[3] - o.bbox[1])  # 35 of 50 px: IoU 0.7
    res = evaluate(gt, dt, classes=["Car"])
    assert r(res) < 100.0


def test_ap_2d_at_another_overlap_counts_loose_boxes_and_equals_the_protocol_at_its_own():
    # 40 exact Car detections and one as tall as its truth but 30 of its 50 px wide: IoU 0.6, a
    # match at 0.5, not at 0.7. R40 at 0.7: 40 of 41 found, precision 1 up to recall 40/41, so 39
    # of the 40 recall slots (1/40 ... 39/40 <= 40/41) hold 1.0 and the last 0: 97.5. At 0.5 all 40.
    gt = cars(41)
    dt = perfect(gt)
    o = dt["000004"][0]
    o.bbox[2] = o.bbox[0] + 0.6 * (o.bbox[2] - o.bbox[0])
    assert ap_2d(gt, dt, "Car", 0.7) == pytest.approx([97.5] * 3)
    official = evaluate(gt, dt, classes=["Car"]).ap["Car"]["2d"]["R40"]
    assert ap_2d(gt, dt, "Car", 0.7) == pytest.approx(official)
    assert ap_2d(gt, dt, "Car", 0.5) == pytest.approx([100.0] * 3)
    assert ap_2d(gt, dt, "Car", 0.61) == pytest.approx([97.5] * 3)  # strictly above: 0.6 < 0.61
    with pytest.raises(ValueError, match="overlap"):
        ap_2d(gt, dt, "Car", 1.0)
    with pytest.raises(ValueError, match="no IoU threshold"):
        ap_2d(gt, dt, "Bus", 0.5)


def test_second_pass_prefers_overlap_first_pass_prefers_score():
    # 41 cars with exact detections scored 1.000, 0.999, ..., 0.960; car 0 also gets A (IoU 0.9,
    # score 5) and its exact copy B is re-scored. Pass 1 gives car 0 to A (highest score), so the
    # thresholds are 5, 0.999, ..., 0.960.
    gt = cars(41)
    dt = perfect(gt)
    first = gt["000000"][0]
    a = copy_as(first, 5.0)
    a.bbox = first.bbox + np.array([0, 0, 0, -5.0])  # 45/50 = 0.9 IoU
    dt["000000"].append(a)
    dt["000000"][0].score = 0.955  # B below every threshold: never counted
    res = evaluate(gt, dt, classes=["Car"])
    assert r(res) == 100.0
    # B just above the last threshold: there car 0 takes B (overlap 1 beats 0.9) and A becomes a
    # false positive: precision 41/42 in slot 40 only -> R40 (39 + 41/42) / 40, R11 (10 + 41/42) / 11
    dt["000000"][0].score = 0.9605
    res = evaluate(gt, dt, classes=["Car"])
    assert r(res) == pytest.approx(100 * (39 + 41 / 42) / 40, abs=1e-4)
    assert r(res, key="R11") == pytest.approx(100 * (10 + 41 / 42) / 11, abs=1e-4)


def test_missing_result_frame_means_no_detections_and_errors_are_clear():
    gt = cars(41, frame_size=41)
    gt["000001"] = [obj(slot=0)]
    res = evaluate(gt, perfect({"000000": gt["000000"]}), classes=["Car"])
    assert res.n_gt["Car"] == [42, 42, 42]
    # 41 hits of 42: getThresholds skips the 31st score (recall 31/42 is nearer slot 30 than 31/40)
    # and keeps 40 thresholds, so slot 40 stays 0
    assert r(res) == pytest.approx(97.5, abs=1e-4)
    assert r(res, key="R11") == pytest.approx(1000 / 11, abs=1e-4)
    s = np.linspace(1.0, 0.96, 41)
    t = thresholds(s, 42.0, 41.0)
    assert len(t) == 40 and s[30] not in t
    with pytest.raises(ValueError, match="no score"):
        evaluate(gt, {"000000": [obj()]}, classes=["Car"])
    with pytest.raises(ValueError, match="Bus"):
        evaluate(gt, {}, classes=["Bus"])


def test_2d_only_results_leave_bev_and_3d_absent():
    gt = cars(41)
    dt = perfect(gt)
    for objs in dt.values():
        for o in objs:
            o.location = np.array([-1000.0, -1000.0, -1000.0])
            o.h = o.w = o.l = -1.0
    res = evaluate(gt, dt, classes=["Car"])
    assert r(res) == 100.0
    assert set(res.ap["Car"]) == {"2d", "aos"}
    assert set(res.absent["Car"]) == {"bev", "3d"}
    assert "3d" not in res.ap_loose["Car"]
