"""Breakdowns: AP per distance bin (outside = ignored, not deleted), matched-pair errors and the
004 volumetric metrics, against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

from kitti.eval import evaluate
from kitti.labels import Object3D


def car(x, z, score=None, bbox=None, h=1.5, w=1.6, l=3.9, ry=0.0, y=1.6, t="Car"):
    if bbox is None:
        bbox = [100.0 + 10 * x, 100.0, 160.0 + 10 * x, 160.0]
    return Object3D(t, 0.0, 0, 0.0, np.array(bbox, float), h, w, l, np.array([x, y, z]), ry, score)


def spread(n, z0, dz=0.0):
    """n cars, one per frame, 2D and 3D far from anything else; z = z0 + k * dz."""
    return {f"{k:06d}": [car(0.0, z0 + k * dz)] for k in range(n)}


def exact(gt, score0=1.0):
    dt, k = {}, 0
    for fid, objs in gt.items():
        dt[fid] = [Object3D(o.type, 0, 0, o.alpha, o.bbox.copy(), o.h, o.w, o.l, o.location.copy(),
                            o.rotation_y, score0 - k / 1000) for o in objs]
        k += len(objs)
    return dt


def test_range_bins_ignore_outside_objects_rather_than_delete_them():
    gt = spread(41, 5.0, 0.3)  # 41 cars between 5 and 17 m
    dt = exact(gt)
    # a car at 21 m (bin 20-40) whose detection sits at 19.5 m (bin 0-20); same 2D box
    gt["000100"] = [car(0.0, 21.0)]
    dt["000100"] = [car(0.0, 19.5, score=2.0)]
    res = evaluate(gt, dt, classes=["Car"], range_bins=[0, 20, 40])
    near, far = res.range_bins["bins"]
    assert near["range"] == [0.0, 20.0] and near["n_gt"]["Car"] == [41, 41, 41]
    # in 0-20 the detection is matched (2D) to truth that is ignored there: no false positive
    assert near["ap"]["Car"]["2d"]["R40"] == [100.0] * 3
    # in 20-40 the truth is evaluated and its only match is an ignored detection: not a TP
    assert far["n_gt"]["Car"] == [1, 1, 1]
    assert far["ap"]["Car"]["2d"]["R40"] == [0.0] * 3
    # deleting instead of ignoring would make the detection a false positive in 0-20
    deleted = evaluate({**gt, "000100": []}, dt, classes=["Car"])
    assert deleted.ap["Car"]["2d"]["R40"][1] == pytest.approx(100 * 41 / 42, abs=1e-4)
    # a bin without truth reports None, not 0
    empty = evaluate(gt, dt, classes=["Car"], range_bins=[50, 60]).range_bins["bins"][0]
    assert empty["ap"]["Car"]["3d"]["R40"] == [None] * 3


def test_matched_pair_errors_and_volumetric_metrics_by_hand():
    g = car(1.0, 20.0, h=1.5, w=1.6, l=3.9, ry=0.2)
    d = car(1.15, 20.2, score=0.9, h=1.6, w=1.5, l=4.1, ry=0.2 + np.pi)  # turned round: same footprint
    res = evaluate({"000000": [g]}, {"000000": [d]}, classes=["Car"], range_bins=[0, 10, 30],
                   max_distance=80.0)
    for how in ("iou3d", "centre"):
        e = res.errors[how]["Car"]["all"]
        assert e["n"] == 1 and e["n_gt"] == 1
        # geometric centres: y - h/2 -> 0.85 vs 0.80; offsets (0.15, -0.05, 0.2)
        assert e["centre"]["mean"] == pytest.approx(np.sqrt(0.15**2 + 0.05**2 + 0.2**2))
        assert e["depth"]["mean"] == pytest.approx(0.2) and e["depth"]["bias"] == pytest.approx(0.2)
        assert e["h"]["bias"] == pytest.approx(0.1) and e["w"]["bias"] == pytest.approx(-0.1)
        assert e["l"]["mean"] == pytest.approx(0.2)
        assert e["yaw_deg"]["mean"] == pytest.approx(180.0)
        assert e["yaw_mod_pi_deg"]["mean"] == pytest.approx(0.0, abs=1e-9)
        assert [b["n"] for b in res.errors[how]["Car"]["bins"]] == [0, 1]
        v = res.volumetric[how]["Car"]["all"]
        assert v["size_precision"] == pytest.approx(100 * (1 - 0.1 / 1.5 - 0.1 / 1.6 - 0.2 / 3.9))
        assert v["size_error"] == pytest.approx(0.4)
        assert v["location_precision"] == pytest.approx(100 * (1 - 0.35 / 40))
        assert v["location_error"] == pytest.approx(0.35)
        assert (v["L"], v["W"], v["H"]) == pytest.approx((0.2, 0.1, 0.1))
        assert (v["XC"], v["YC"], v["ZC"]) == pytest.approx((0.15, 0.2, 0.05))


def test_lenient_centre_matching_gate():
    # 1.5 m off: too far for 3D IoU > 0.5 but within the 2 m gate
    g, d = car(0.0, 10.0), car(1.5, 10.0, score=0.5)
    res = evaluate({"0": [g]}, {"0": [d]}, classes=["Car"])
    assert res.errors["iou3d"]["Car"]["all"]["n"] == 0
    assert res.errors["centre"]["Car"]["all"]["n"] == 1
    # 3 m off: out of the gate at 10 m (max(2, 1.0)), inside it at 40 m (max(2, 4.0))
    assert evaluate({"0": [g]}, {"0": [car(3.0, 10.0, score=0.5)]},
                    classes=["Car"]).errors["centre"]["Car"]["all"]["n"] == 0
    assert evaluate({"0": [car(0.0, 40.0)]}, {"0": [car(3.0, 40.0, score=0.5)]},
                    classes=["Car"]).errors["centre"]["Car"]["all"]["n"] == 1


def test_one_to_one_matching_takes_the_best_pair_first():
    # two cars 2.5 m apart, two detections: each truth gets its own nearest detection
    g = [car(0.0, 20.0), car(2.5, 20.0)]
    d = [car(2.3, 20.0, score=0.9), car(0.1, 20.0, score=0.8)]
    res = evaluate({"0": g}, {"0": d}, classes=["Car"])
    for how in ("iou3d", "centre"):
        e = res.errors[how]["Car"]["all"]
        assert e["n"] == 2
        assert e["centre"]["mean"] == pytest.approx(0.15)
    # other classes never pair up
    res = evaluate({"0": [car(0, 20.0, t="Van")]}, {"0": [car(0, 20.0, score=1.0)]}, classes=["Car"])
    assert res.errors["centre"]["Car"]["all"]["n"] == 0


def test_json_shape_and_table():
    gt = spread(3, 10.0, 5.0)
    res = evaluate(gt, exact(gt), range_bins=[0, 20, 40])
    js = res.to_json()
    assert set(js["ap"]) == {"Car", "Pedestrian", "Cyclist"}
    for cls in js["ap"]:
        for m in ("2d", "bev", "3d", "aos"):
            assert set(js["ap"][cls][m]) == {"R11", "R40"}
            assert all(len(v) == 3 for v in js["ap"][cls][m].values())
    import json
    json.dumps(js)  # plain types only
    text = res.table()
    assert "Car AP_R40@0.70, 0.70, 0.70:" in text and "Car AP@0.70, 0.50, 0.50:" in text
    assert "bbox AP:" in text and "Volumetric" in text and "0-20" in text
