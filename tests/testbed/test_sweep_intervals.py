"""How sure a sweep report is: AP intervals over bootstrap draws of the frames, paired per-object
changes against the reference point, and the files that carry them, on tiny hand-made KITTI
folders whose intervals are known by hand (no generator, no lifter)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from kitti.eval import evaluate, evaluate_folders
from kitti.eval.intervals import drawn_evaluations
from kitti.eval.paired import frame_counts, paired_change, truth_overlaps
from kitti.jobs import InProcess
from kitti.labels import Object3D, write_label
from kitti.splits import write_split
from testbed.report import CSV_COLS, PAIRED_COLS, write_report
from testbed.sweep import Axes, SceneRef, SweepSpec, load_sweep, plan
from testbed.uncertainty import DrawJob, comparisons, draw_point, measure

ROOT = Path(__file__).resolve().parents[2]
BINS = (0.0, 20.0, float("inf"))


def _car(x: float, z: float, score: float | None = None, dx: float = 0.0) -> Object3D:
    """A moderate Car (50 px tall, unoccluded) at (x, z), ry = 0, so its length (4 m) lies along x;
    `dx` moves the 3D box along x and leaves the 2D box: 3D IoU (4 - dx) / (4 + dx)."""
    u = 600.0 + 40.0 * x
    return Object3D("Car", 0.0, 0, 0.0, [u, 150.0, u + 60.0, 200.0], 1.5, 1.6, 4.0,
                    [x + dx, 1.6, z], 0.0, score)


def _frames(found: dict[str, list[Object3D]]) -> dict[str, list[Object3D]]:
    """Detections: each truth Car found exactly (scores falling in frame order)."""
    return {f: [_car(o.location[0], o.location[2], 0.9 - 0.1 * k) for k, o in enumerate(objs)]
            for f, objs in found.items()}


# frame A: one Car, found; frame B: one Car, missed
GT = {"000000": [_car(0.0, 10.0)], "000001": [_car(3.0, 30.0)]}
FOUND_A = {"000000": [_car(0.0, 10.0, 0.9)], "000001": []}


def _write_points(root: Path, gt: dict, preds: list[dict]) -> tuple[Path, Path, list[Path]]:
    labels, split = root / "training" / "label_2", root / "ImageSets" / "val.txt"
    for fid, objs in gt.items():
        write_label(labels / f"{fid}.txt", objs)
    write_split(split, sorted(gt))
    dirs = []
    for k, dt in enumerate(preds):
        for fid, objs in dt.items():
            write_label(root / f"pred{k}" / f"{fid}.txt", objs)
        dirs.append(root / f"pred{k}")
    return labels, split, dirs


def _job(tmp_path: Path, gt: dict, dt: dict, drives=None, draws: int = 200) -> DrawJob:
    labels, split, (pred,) = _write_points(tmp_path, gt, [dt])
    return DrawJob(labels, pred, split, ("Car",), ("2d", "bev", "3d"), BINS, draws, drives)


def test_ap_interval_of_one_found_and_one_missed_car_is_known_by_hand(tmp_path):
    """Draws of {A, B}: AA scores 100 on the measured recall, BB 0, AB 50; the devkit's AP|R40
    on two truth boxes is at most 1/40 (2.5: AA), else 0. 200 seeded draws hold AA and BB."""
    d = draw_point(_job(tmp_path, GT, FOUND_A))
    r40, r11, measured = d.intervals["strict", "Car", "3d", "moderate", "all"]
    assert measured == (0.0, 100.0)
    assert r40 == (0.0, 2.5)
    assert r11 == (0.0, pytest.approx(100 / 11, rel=1e-6))  # slot 0 of 11: AA and AB
    # the 0-20 m bin holds A's car alone: whenever a draw holds it, it is found
    assert d.intervals["strict", "Car", "3d", "moderate", "0-20"][2] == (100.0, 100.0)
    assert d.truth["Car"].iou == pytest.approx([1.0, 0.0])


def test_draws_of_whole_drives_take_both_frames_together(tmp_path):
    """A and B on one drive: every draw takes both, so the AP cannot move (50 on the measured
    recall, AB)."""
    d = draw_point(_job(tmp_path, GT, FOUND_A, drives={"000000": "d1", "000001": "d1"}))
    assert d.intervals["strict", "Car", "3d", "moderate", "all"][2] == (50.0, 50.0)


def test_a_draw_of_every_frame_once_is_the_evaluation_itself():
    gt = {"000000": [_car(0.0, 10.0), _car(-4.0, 25.0)], "000001": [_car(3.0, 30.0)]}
    dt = {"000000": [_car(0.0, 10.0, 0.8, dx=0.5)], "000001": [_car(3.0, 30.0, 0.6)]}
    ev = evaluate(gt, dt, classes=["Car"], range_bins=list(BINS)).to_json()
    drawn = next(drawn_evaluations(gt, dt, [np.arange(2)], ["Car"], range_bins=BINS))
    for key in ("ap", "ap_loose", "n_gt", "ap_r40_measured_recall"):
        assert drawn[key] == ev[key]
    assert [b["ap"] for b in drawn["range_bins"]["bins"]] == [b["ap"] for b in ev["range_bins"]["bins"]]


GT3 = {"000000": [_car(0.0, 10.0), _car(-4.0, 25.0)], "000001": [_car(3.0, 30.0)]}


def test_paired_change_of_identical_points_is_exactly_zero_and_not_decided():
    a = truth_overlaps(GT3, _frames(GT3), "Car")
    counts = frame_counts(np.random.default_rng(1).integers(2, size=(200, 2)), 2)
    c = paired_change(a.iou, a.iou, a.frame, counts)
    assert (c.n, c.mean, c.lo, c.hi, c.decided) == (3, 0.0, 0.0, 0.0, False)


def test_shifting_one_cars_box_moves_the_paired_mean_by_the_hand_computed_amount():
    """The first car's box 1 m along its 4 m length: IoU 3/5, so the mean IoU of three cars
    falls by 0.4 / 3 and the share above 0.7 by 1/3. Draws {A, A}: -0.2 (its two cars twice),
    {B, B}: 0, {A, B}: -0.4 / 3, so the central 95 % is [-0.2, 0]: not decided."""
    before = truth_overlaps(GT3, _frames(GT3), "Car")
    shifted = _frames(GT3)
    shifted["000000"][0] = _car(0.0, 10.0, 0.9, dx=1.0)
    after = truth_overlaps(GT3, shifted, "Car")
    assert after.iou == pytest.approx([0.6, 1.0, 1.0], abs=1e-9)
    counts = frame_counts(np.random.default_rng(2).integers(2, size=(200, 2)), 2)
    c = paired_change(after.iou, before.iou, before.frame, counts)
    assert c.mean == pytest.approx(-0.4 / 3, abs=1e-9)
    assert (c.lo, c.hi) == (pytest.approx(-0.2, abs=1e-9), 0.0)
    assert not c.decided
    share = paired_change(after.iou > 0.7, before.iou > 0.7, before.frame, counts)
    assert share.mean == pytest.approx(-1 / 3)
    # every car shifted: every draw moves by -0.4, decided
    every = {f: [_car(o.location[0], o.location[2], 0.5, dx=1.0) for o in objs] for f, objs in GT3.items()}
    c = paired_change(truth_overlaps(GT3, every, "Car").iou, before.iou, before.frame, counts)
    assert (c.lo, c.hi) == (pytest.approx(-0.4, abs=1e-9), pytest.approx(-0.4, abs=1e-9))
    assert c.decided


def test_a_box_claims_its_car_by_the_2d_box_and_an_unclaimed_car_scores_zero():
    gt = {"000000": [_car(0.0, 10.0), _car(-4.0, 25.0)]}
    far_off = _car(-4.0, 25.0, 0.5)
    far_off.bbox = far_off.bbox + [200.0, 0.0, 200.0, 0.0]  # the 2D box no longer overlaps its car
    t = truth_overlaps(gt, {"000000": [_car(0.0, 10.0, 0.9, dx=1.0), far_off]}, "Car")
    assert t.iou == pytest.approx([0.6, 0.0])


def test_reference_is_each_axis_first_value_and_a_dropped_scan_its_64_beam_parent():
    p = plan(load_sweep(ROOT / "scenes" / "sweeps" / "beam_range_sweep.yaml"))
    found = {(axis, pt.key.split("/", 1)[1], ref.key.split("/", 1)[1]) for axis, pt, ref in comparisons(p)}
    assert ("beams", "uniform-16b-native-max/fit-gt", "uniform-128b-native-max/fit-gt") in found
    assert ("beams", "hdl64e-16b-dropped-max/fit-gt", "hdl64e-64b-native-max/fit-gt") in found
    assert ("beam_mode", "hdl64e-16b-dropped-max/fit-gt", "uniform-16b-native-max/fit-gt") in found
    assert ("method", "uniform-16b-native-max/fit-gt", "uniform-16b-native-max/frustum-gt") in found
    assert ("method", "no-lidar/mono-gt", "uniform-128b-native-max/frustum-gt") in found
    assert ("boxes", "no-lidar/mono-detector", "no-lidar/mono-gt") in found
    # the references themselves, and an image-only method along a LiDAR axis, compare nothing
    assert not [f for f in found if f[1] == f[2] or (f[0] == "beams" and f[1].startswith("no-lidar"))]
    assert len(found) == 28 + 12 + 18 + 17


def _tiny_sweep(tmp_path: Path, shifted: list[Object3D] | None = None):
    """A two-point sweep (64 and 16 beams, fit, oracle boxes) laid out as `execute` leaves it,
    the 16-beam point with `shifted` as frame A's boxes; the points' evaluations."""
    spec = SweepSpec(name="t", scenes=[SceneRef(spec=tmp_path / "scene.yaml")],
                     axes=Axes(beams=[64, 16], method=["fit"], boxes=["gt"]), range_bins=list(BINS))
    p = plan(spec, tmp_path / "sweep")
    p.versions = ("g", "m")  # the folders below, as `execute` names them
    results = []
    for pt in p.points:
        data, out = p.data_dir(pt, "g"), p.point_dir(pt, "g", "m")
        dt = _frames(GT3)
        if shifted is not None and pt.scan.beams == 16:
            dt["000000"] = shifted
        _write_points(data, GT3, [])
        for fid, objs in dt.items():
            write_label(out / "pred" / f"{fid}.txt", objs)
        ev = evaluate_folders(data / "training" / "label_2", out / "pred", data / "ImageSets" / "val.txt",
                              range_bins=list(BINS), progress=False)
        results.append((pt, ev.to_json()))
    return p, results


def _read(path: Path) -> list[dict]:
    with open(path) as f:
        return list(csv.DictReader(f))


def test_sweep_report_carries_intervals_and_paired_changes(tmp_path):
    shifted = [_car(0.0, 10.0, 0.9, dx=1.0), _car(-4.0, 25.0, 0.8)]
    p, results = _tiny_sweep(tmp_path, shifted)
    u = measure(p, results, InProcess(), draws=50)
    write_report(results, tmp_path / "a", "t", uncertainty=u)
    with open(tmp_path / "a" / "metrics.csv") as f:
        header = f.readline().strip().split(",")
    assert header == list(CSV_COLS)
    assert header[:15] == ["scene", "lidar", "beams", "beam_mode", "max_range", "lidar_weather", "method",
                           "boxes", "class", "metric", "iou", "difficulty", "range_m", "n_gt", "ap_r40"]
    assert header[15:] == ["ap_r11", "ap_r40_measured", "ap_r40_lo", "ap_r40_hi", "ap_r11_lo", "ap_r11_hi",
                           "ap_r40_measured_lo", "ap_r40_measured_hi"]
    car = [r for r in _read(tmp_path / "a" / "metrics.csv") if r["class"] == "Car" and r["beams"] == "64"
           and r["metric"] == "3d" and r["difficulty"] == "moderate" and r["range_m"] == "all"
           and r["iou"] == "strict"]
    assert float(car[0]["ap_r40_measured_lo"]) <= float(car[0]["ap_r40_measured"]) <= float(car[0]["ap_r40_measured_hi"])
    paired = _read(tmp_path / "a" / "paired.csv")
    assert list(paired[0]) == list(PAIRED_COLS)
    iou = [r for r in paired if r["class"] == "Car" and r["measure"] == "mean_iou_3d" and r["range_m"] == "all"]
    assert len(iou) == 1
    assert (iou[0]["axis"], iou[0]["beams"], iou[0]["reference"]) == ("beams", "16", "hdl64e-64b-native-max/fit-gt")
    assert (iou[0]["n"], iou[0]["change"], iou[0]["value"], iou[0]["reference_value"]) == (
        "3", "-0.1333", "0.8667", "1.0000")
    assert iou[0]["decided"] == "no"
    md = (tmp_path / "a" / "report.md").read_text()
    assert md.index("## What the sweep settles") < md.index("## Car 3D AP|R40 (IoU 0.7)")
    assert "| fit, gt boxes, uniform 16 beams | hdl64e 64 beams | 3 | 0.867 / 1.000 | -0.133 [" in md
    for png in ("paired_changes.png", "ap_vs_axis.png", "ap_vs_distance_3d.png"):
        assert (tmp_path / "a" / png).stat().st_size > 1000


def test_same_inputs_give_the_same_bytes(tmp_path):
    p, results = _tiny_sweep(tmp_path, [_car(0.0, 10.0, 0.9, dx=1.0), _car(-4.0, 25.0, 0.8)])
    for out in ("a", "b"):
        write_report(results, tmp_path / out, "t", uncertainty=measure(p, results, InProcess(), draws=30))
    files = sorted(f.name for f in (tmp_path / "a").iterdir())
    assert {"metrics.csv", "paired.csv", "report.md", "paired_changes.png"} <= set(files)
    assert [f for f in files if (tmp_path / "a" / f).read_bytes() != (tmp_path / "b" / f).read_bytes()] == []


def test_a_report_without_the_points_files_says_it_has_no_intervals(tmp_path):
    _, results = _tiny_sweep(tmp_path)
    rows = write_report(results, tmp_path / "r", "t")
    assert all(r["ap_r40_lo"] == "" for r in rows)
    assert not (tmp_path / "r" / "paired.csv").exists()
    assert "No intervals" in (tmp_path / "r" / "report.md").read_text()


def test_a_drives_file_in_the_scenes_data_makes_the_draws_take_whole_drives(tmp_path):
    """Frames A and B on one drive: every draw takes both, so the shifted car's change has no
    spread left and is decided (over frames it is not: the test above)."""
    p, results = _tiny_sweep(tmp_path, [_car(0.0, 10.0, 0.9, dx=1.0), _car(-4.0, 25.0, 0.8)])
    base = p.base_dir(p.points[0].scene, "g")
    base.mkdir(parents=True)
    (base / "drives.txt").write_text("000000 d1\n000001 d1\n")
    u = measure(p, results, InProcess(), draws=20)
    assert list(u.units.values()) == ["the 2 frames' 1 drive"]
    c = next(c.change for c in u.changes if c.cls == "Car" and c.measure == "mean_iou_3d" and c.range_m == "all")
    assert (c.lo, c.hi) == (pytest.approx(-0.4 / 3), pytest.approx(-0.4 / 3))
    assert c.decided
