"""Bootstrap intervals of AP: the draws by hand on two frames, and the command's output."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from kitti.eval.bootstrap import bootstrap_ap, draw_frames, resampled
from kitti.labels import Object3D, write_label
from testbed.cmd_evaluate import evaluate
from tests.kitti.eval.test_reference import random_set


def car(score: float | None = None) -> Object3D:
    """A moderate (here easy too) Car: 100 px tall, untruncated, unoccluded, 20 m ahead."""
    return Object3D("Car", 0.0, 0, 0.0, np.array([500.0, 150.0, 600.0, 250.0]), 1.5, 1.6, 3.9,
                    np.array([0.0, 1.6, 20.0]), 0.0, score)


def test_a_draw_keeps_each_frame_whole_and_counts_repeats():
    ids = ["a", "b", "c"]
    objs = {"a": [car()], "c": [car(), car()]}  # b: no detections, absent
    draw = resampled(objs, ids, np.array([2, 1, 2, 0]))
    assert list(draw) == ["000000", "000002", "000003"] and [len(v) for v in draw.values()] == [2, 2, 1]
    picks = draw_frames(ids, draws=5, seed=1)
    assert picks.shape == (5, 3) and np.array_equal(picks, draw_frames(ids, draws=5, seed=1))


def test_frames_of_one_drive_are_drawn_together():
    """Frames a and b on one drive, c alone: a draw takes two units, so it holds 2, 3 or 4 frames,
    a and b always equally often; every frame on a drive of its own draws exactly as no drives."""
    ids = ["a", "b", "c"]
    draws = draw_frames(ids, draws=200, seed=1, drives={"a": "x", "b": "x"})
    assert {len(p) for p in draws} == {2, 3, 4}
    assert all(np.count_nonzero(p == 0) == np.count_nonzero(p == 1) for p in draws)
    alone = draw_frames(ids, draws=5, seed=1, drives={"a": "x", "b": "y", "c": "z"})
    assert np.array_equal(alone, draw_frames(ids, draws=5, seed=1))


def test_intervals_by_hand_on_two_frames():
    """One car a frame; "half" finds frame A's only, "both" finds both. A draw holds AA, AB or BB
    (a quarter, a half, a quarter). The devkit's AP|R40 with two truth boxes both found at
    precision 1 is 2.5 (its recall points come from the found boxes' scores: (n - 1) / 40), with
    one of two found 0. So "half" scores 2.5 on AA and 0 otherwise, "both" 2.5 every time: "half"
    lies in [0, 2.5], "both" in [2.5, 2.5], and their paired difference in [0, 2.5]."""
    gt = {"A": [car()], "B": [car()]}
    runs = {"half": {"A": [car(0.9)]}, "both": {"A": [car(0.9)], "B": [car(0.8)]}}
    boot = bootstrap_ap(gt, runs)
    b = boot["Car", "2d", False]
    assert set(boot) == {("Car", "2d", False)}
    assert sorted(set(b.ap[:, 0, 1].tolist())) == [0.0, 2.5] and set(b.ap[:, 1, 1].tolist()) == {2.5}
    assert 0.2 < np.mean(b.ap[:, 0, 1] == 2.5) < 0.3  # AA: a quarter of the draws
    assert b.interval("half") == (0.0, 2.5) and b.interval("both") == (2.5, 2.5)
    assert b.difference("both", "half") == (0.0, 2.5)
    with pytest.raises(ValueError, match="no truth frames"):
        bootstrap_ap({}, runs)


def test_evaluate_prints_and_writes_the_intervals(tmp_path):
    gt, pred = tmp_path / "gt", tmp_path / "pred"
    gt.mkdir(), pred.mkdir()
    for fid in ("000000", "000001"):
        write_label(gt / f"{fid}.txt", [car()])
    write_label(pred / "000000.txt", [car(0.9)])
    out = tmp_path / "e.json"
    res = CliRunner().invoke(evaluate, ["--gt", str(gt), "--pred", str(pred), "--classes", "Car",
                                        "--bootstrap", "200", "--json", str(out)])
    assert res.exit_code == 0, res.output
    assert "95% interval over 200 bootstrap draws of the 2 frames" in res.output
    assert "Car         2d       0.00 [ 0.00,  2.50]  0.00 [ 0.00,  2.50]" in res.output
    doc = json.loads(out.read_text())["bootstrap"]
    assert doc["draws"] == 200 and doc["R40"]["Car"]["2d"][1] == [0.0, 2.5]
    # both frames on one drive: every draw holds both, one of two cars found: AP 0 in each
    drives = tmp_path / "drives.txt"
    drives.write_text("000000 d\n000001 d\n")
    res = CliRunner().invoke(evaluate, ["--gt", str(gt), "--pred", str(pred), "--classes", "Car",
                                        "--bootstrap", "50", "--drives", str(drives), "--json", str(out)])
    assert res.exit_code == 0, res.output
    assert "50 bootstrap draws of the 2 frames' 1 drive (" in res.output
    doc = json.loads(out.read_text())["bootstrap"]
    assert doc["units"] == 1 and doc["R40"]["Car"]["2d"][1] == [0.0, 0.0]


def test_each_draw_scores_as_evaluate_scores_the_drawn_frames():
    """The bootstrap packs each result set once and takes a draw's rows from it; every AP of
    every draw must equal `evaluate` on the drawn frames (`resampled`), bit for bit, for each
    metric, strict and loose, with frames drawn twice, a frame without a result file and tied
    scores (the devkit transliteration's random sets)."""
    from kitti.eval.evaluate import evaluate as evaluate_frames

    gt, dt = random_set(11, frames=30)
    runs = {"a": dt, "b": {k: v[::2] for k, v in dt.items()}}
    classes, metrics = ["Car", "Pedestrian"], ["2d", "aos", "bev", "3d"]
    boot = bootstrap_ap(gt, runs, classes, metrics, draws=8, seed=3)
    ids = sorted(gt)
    assert set(boot) == {(c, m, loose) for c in classes for m in metrics
                         for loose in ((False, True) if m in ("bev", "3d") else (False,))}
    for d, picks in enumerate(draw_frames(ids, draws=8, seed=3)):
        for j, name in enumerate(runs):
            res = evaluate_frames(resampled(gt, ids, picks), resampled(runs[name], ids, picks),
                                  classes=classes, metrics=metrics)
            for (c, m, loose), b in boot.items():
                want = (res.ap_loose if loose else res.ap)[c][m]["R40"]
                assert b.ap[d, j].tolist() == want, (d, name, c, m, loose)
