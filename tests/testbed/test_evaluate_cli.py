"""`testbed evaluate` on folders of label and result files."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from kitti.labels import Object3D, write_label
from kitti.splits import write_split
from testbed.cli import cli


def _car(k: int, score=None, t="Car") -> Object3D:
    return Object3D(t, 0.0, 0, 0.5, np.array([10.0 * k, 100, 10.0 * k + 8, 160]), 1.5, 1.6, 3.9,
                    np.array([5.0 * k, 1.6, 10.0 + 1.5 * k]), 0.3, score)


def _write(tmp_path, n_frames=50):
    gt_dir, dt_dir = tmp_path / "label_2", tmp_path / "results"
    for f in range(n_frames):
        fid = f"{f:06d}"
        write_label(gt_dir / f"{fid}.txt",
                    [_car(0), _car(1, t="Pedestrian"), Object3D.dont_care([500, 0, 600, 50])])
        if f % 10 != 9:  # every 10th result file missing: no detections there
            write_label(dt_dir / f"{fid}.txt",
                        [_car(0, score=1 - f / 100), _car(1, score=0.5, t="Pedestrian")])
    return gt_dir, dt_dir


def test_evaluate_writes_the_table_and_json(tmp_path):
    gt_dir, dt_dir = _write(tmp_path)
    out = tmp_path / "eval.json"
    res = CliRunner().invoke(cli, ["evaluate", "--gt", str(gt_dir), "--pred", str(dt_dir),
                                   "--json", str(out), "--range-bins", "0,20,40,60,80"])
    assert res.exit_code == 0, res.output
    assert "Car AP_R40@0.70, 0.70, 0.70:" in res.output
    js = json.loads(out.read_text())
    # 45 of 50 cars found, every hit above every score of a miss; recall 45/50 -> 36 slots of 40
    assert js["n_gt"]["Car"] == [50, 50, 50]
    assert js["ap"]["Car"]["3d"]["R40"] == [90.0, 90.0, 90.0]
    assert js["recall"]["Car"]["2d"] == [0.9, 0.9, 0.9]
    assert set(js["ap"]["Car"]) == {"2d", "bev", "3d", "aos"}
    assert js["range_bins"]["edges"] == [0, 20, 40, 60, 80]
    assert js["errors"]["iou3d"]["Car"]["all"]["n"] == 45
    assert js["volumetric"]["iou3d"]["Car"]["all"]["size_precision"] == 100.0


def test_split_selects_frames_and_bad_files_name_the_line(tmp_path):
    gt_dir, dt_dir = _write(tmp_path, 3)
    write_split(tmp_path / "val.txt", ["000001"])
    out = tmp_path / "e.json"
    res = CliRunner().invoke(cli, ["evaluate", "--gt", str(gt_dir), "--pred", str(dt_dir), "--split",
                                   str(tmp_path / "val.txt"), "--json", str(out), "--classes", "Car"])
    assert res.exit_code == 0, res.output
    assert json.loads(out.read_text())["n_gt"] == {"Car": [1, 1, 1]}
    (dt_dir / "000001.txt").write_text("Car 0 0 0.5 0 100 8 160 1.5 1.6 3.9 0 1.6 10 0.3 high\n")
    res = CliRunner().invoke(cli, ["evaluate", "--gt", str(gt_dir), "--pred", str(dt_dir)])
    assert res.exit_code != 0
    assert "000001.txt" in res.output and "line 1" in res.output and "score" in res.output
    res = CliRunner().invoke(cli, ["evaluate", "--gt", str(gt_dir), "--pred", str(dt_dir),
                                   "--range-bins", "0,a"])
    assert res.exit_code != 0 and "comma-separated" in res.output
