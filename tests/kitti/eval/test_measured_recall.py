"""AP|R40 on the measured recall (`kitti.eval.ap.Curve.r40_measured`), hand-counted: up to 40
truth boxes the devkit's slot t stands for recall t/40 and caps AP|R40 at (n - 1)/40; the
measured figure reads each threshold at its own recall (t found of n), as AP|R40 is defined."""

from __future__ import annotations

import pytest

from kitti.eval import evaluate
from kitti.eval.bootstrap import bootstrap_ap, interval_table

from .test_protocol import cars, copy_as, obj, perfect


def test_fourteen_cars_all_found_are_capped_by_the_devkit_and_perfect_when_measured():
    # 14 thresholds fill devkit slots 0..13: R40 = 13/40 = 32.5; measured: every slot k/40 <= 14/14
    gt = cars(14, frame_size=7)
    res = evaluate(gt, perfect(gt), classes=["Car"])
    assert res.ap["Car"]["2d"]["R40"] == [pytest.approx(32.5, abs=1e-4)] * 3
    for group in ("strict", "loose"):
        for metric, v in res.measured["Car"][group].items():
            assert v == [100.0] * 3, (group, metric)
    assert res.capped("Car")


def test_a_false_positive_and_a_miss_by_hand():
    # 4 cars; detections TP 0.9, FP 0.8, TP 0.7, TP 0.6 (the 4th car missed). Thresholds at the
    # three TP scores: recall 1/4, 2/4, 3/4 with precision 1, 2/3, 3/4. Slots k/40 <= 1/4 (10
    # of them) take max(1, 2/3, 3/4) = 1; 11..20 and 21..30 take 3/4; 31..40 reach no threshold
    # and read 0: (10 + 7.5 + 7.5) / 40 = 62.5. Devkit: slots 0..2 = 1, 3/4, 3/4 -> 1.5 / 40.
    gt = {"000000": [obj(slot=k) for k in range(4)]}
    g = gt["000000"]
    dt = {"000000": [copy_as(g[0], 0.9), obj(slot=7, score=0.8), copy_as(g[1], 0.7), copy_as(g[2], 0.6)]}
    res = evaluate(gt, dt, classes=["Car"])
    assert res.ap["Car"]["2d"]["R40"][1] == pytest.approx(3.75, abs=1e-4)
    for metric in ("2d", "bev", "3d", "aos"):
        assert res.measured["Car"]["strict"][metric] == [pytest.approx(62.5, abs=1e-9)] * 3


def test_with_enough_cars_the_two_agree():
    # 80 cars all found, a false positive above all: precision (k + 1) / (k + 2) rises with the
    # threshold, monotone 80/81 everywhere: both read 100 * 80 / 81 (the devkit in float32)
    gt = cars(80)
    dt = perfect(gt)
    dt["000000"].append(obj(slot=12, score=2.0))
    res = evaluate(gt, dt, classes=["Car"])
    assert res.ap["Car"]["2d"]["R40"][1] == pytest.approx(100 * 80 / 81, abs=1e-4)
    assert res.measured["Car"]["strict"]["2d"][1] == pytest.approx(100 * 80 / 81, abs=1e-9)
    assert not res.capped("Car")
    assert "on the measured recall" not in res.table()


def test_printout_and_bootstrap_give_the_measured_figure_only_where_the_devkit_caps():
    gt = cars(14, frame_size=7)
    res = evaluate(gt, perfect(gt), classes=["Car"])
    text = res.table()
    assert "cannot exceed 32.50, 32.50, 32.50" in text
    assert "bbox AP:100.00, 100.00, 100.00" in text
    boot = bootstrap_ap(gt, {"p": perfect(gt)}, metrics=["2d"], draws=50)
    assert boot["Car", "2d", False].interval("p", measured=True) == (100.0, 100.0)  # every car found
    _, doc = interval_table(gt, perfect(gt), res, draws=50)
    assert doc["R40_measured_recall"]["Car"]["2d"][1] == [100.0, 100.0]
    forty = cars(40)  # the devkit's cap is 97.5 at 40 truth boxes, 100 from 41
    assert evaluate(forty, perfect(forty), classes=["Car"]).capped("Car")
    big = cars(41)
    _, doc = interval_table(big, perfect(big), evaluate(big, perfect(big), classes=["Car"]), draws=20)
    assert "R40_measured_recall" not in doc


def test_distance_bins_carry_the_measured_figure():
    # 14 perfect hits 30-37 m away (five a frame: x = 0..24 m at z = 30 m), none in the other bin:
    # the bin's devkit AP|R40 is its count's cap, 32.5; on the measured recall 100; the empty bin
    # reads None
    gt = cars(14, frame_size=5)
    res = evaluate(gt, perfect(gt), classes=["Car"], range_bins=[0, 40, 80])
    near, far = res.range_bins["bins"]
    assert near["ap"]["Car"]["3d"]["R40"] == [pytest.approx(32.5, abs=1e-4)] * 3
    assert near["ap_r40_measured"]["Car"]["3d"] == [100.0] * 3
    assert far["ap_r40_measured"]["Car"]["3d"] == [None] * 3
    text = res.table()
    assert "AP_R40 by distance, on the measured recall" in text
    assert "Car              0-40     14  100.00  100.00  100.00  100.00" in text
