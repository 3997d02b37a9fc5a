"""`testbed fidelity`: the report's numbers against values computed by hand on a real KITTI frame,
generated frames against real ones, skipped corrupt frames, absent groups, the tolerance file."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import imageio.v3 as iio
import numpy as np
import pytest
from click.testing import CliRunner
from scipy import ndimage

from kitti.calib import read_calib
from kitti.labels import read_label
from lifter.ground import fit_ground_plane, height_above
from simgen.generate import generate
from simgen.spec import load_spec
from testbed.cmd_fidelity import fidelity
from fidelity import ToleranceError, Tolerances, compare, compute_stats, load_tolerances, write_report
from fidelity.catalog import STAT_KEYS
from fidelity.images import car_look_stats
from fidelity.stats import Acc
from fidelity.compare import verdict

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def sim_root(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("sim") / "street"
    generate(load_spec(ROOT / "scenes/golden/street.yaml"), root, frames=2)
    return root


@pytest.fixture(scope="module")
def sim_vs_real(sim_root, real_root):
    return compare(compute_stats(sim_root), compute_stats(real_root, frames=4))


def _statistics(out: Path) -> dict:
    return json.loads((out / "fidelity.json").read_text())["statistics"]


def _hand_proj_gap(label_path: Path, calib_path: Path, size: tuple[int, int]) -> float:
    """Max side gap of the frame's single label: 8 corners rotated about y, projected with P2."""
    (obj,) = [o for o in read_label(label_path) if o.type != "DontCare"]
    P2 = read_calib(calib_path).P2
    xs = np.array([1, 1, -1, -1, 1, 1, -1, -1]) * obj.l / 2
    zs = np.array([1, -1, -1, 1, 1, -1, -1, 1]) * obj.w / 2
    ys = np.array([0, 0, 0, 0, -1, -1, -1, -1]) * obj.h
    c, s = np.cos(obj.rotation_y), np.sin(obj.rotation_y)
    pts = np.stack([c * xs + s * zs, ys, -s * xs + c * zs, np.ones(8)]) + np.r_[obj.location, 0][:, None]
    uvw = P2 @ pts
    u, v = uvw[0] / uvw[2], uvw[1] / uvw[2]
    box = np.array([max(u.min(), 0), max(v.min(), 0), min(u.max(), size[0] - 1),
                    min(v.max(), size[1] - 1)])
    return float(np.abs(box - obj.bbox).max())


def _high_pass(x: np.ndarray) -> np.ndarray:
    return x - ndimage.gaussian_filter(x, 3.0, mode="mirror", truncate=4.0)


def _robust_sd(x: np.ndarray) -> float:
    return 1.4826 * np.median(np.abs(x - np.median(x)))


def test_report_numbers_match_a_hand_computation_on_one_real_frame(real_root, tmp_path):
    stats = compute_stats(real_root, frames=1)
    assert stats.frames == ["000000"]
    write_report(compare(stats, stats), tmp_path)
    got = _statistics(tmp_path)
    t = real_root / "training"
    scan = np.fromfile(t / "velodyne/000000.bin", "<f4").reshape(-1, 4)
    r = np.sqrt((scan[:, :3].astype(np.float64) ** 2).sum(axis=1))
    rgb = iio.imread(t / "image_2/000000.png")[..., :3].astype(np.float64)
    grey = np.round(rgb @ [0.299, 0.587, 0.114])  # ITU-R BT.601, as cv2's BGR2GRAY
    dx = np.abs(np.diff(grey, axis=1))
    rect = read_calib(t / "calib/000000.txt").lidar_to_rect(scan[:, :3].astype(np.float64))
    height = height_above(rect, fit_ground_plane(rect))
    ground = np.abs(height) < 0.2
    near = np.hypot(scan[:, 0], scan[:, 1]) < 8.0
    far = r > 40
    bearing = np.degrees(np.abs(np.arctan2(scan[:, 1].astype(np.float64), scan[:, 0].astype(np.float64))))
    # the road surface at 5-10 m: the pixels (each once) the returns within 0.1 m of the road plane
    # project to with P2, 5-10 m from camera 0 on the ground
    road = rect[(np.abs(height) < 0.1) & (rect[:, 2] > 1.0)]
    uvw = np.c_[road, np.ones(len(road))] @ read_calib(t / "calib/000000.txt").P2.T
    u, v = (np.round(uvw[:, i] / uvw[:, 2]).astype(int) for i in (0, 1))
    band = np.hypot(road[:, 0], road[:, 2])
    rows, cols = grey.shape
    keep = (u >= 0) & (u < cols) & (v >= 0) & (v < rows) & (band >= 5) & (band < 10)
    pix = np.unique(v[keep] * cols + u[keep])
    assert len(pix) > 100
    hand = {
        "lidar.points_per_sweep": (t / "velodyne/000000.bin").stat().st_size / 16,
        "lidar.beyond_40m_share": np.mean(far),
        "lidar.beyond_40m_ahead_share": np.mean(far & (bearing < 30)),
        "lidar.beyond_40m_beside_share": np.mean(far & (bearing >= 30) & (bearing < 150)),
        "lidar.beyond_40m_behind_share": np.mean(far & (bearing >= 150)),
        "lidar.far_height_m": np.median(height[far]),
        "lidar.far_reflectance_nonzero_median": np.median(scan[far & (scan[:, 3] > 0), 3]),
        "lidar.range_p50_m": np.median(r),
        "lidar.reflectance_zero_share": np.mean(scan[:, 3] == 0),
        "lidar.reflectance_mean": scan[:, 3].astype(np.float64).mean(),
        "lidar.near_ground_share_left": ground[near & (scan[:, 1] > 0)].mean(),
        "lidar.near_ground_share_right": ground[near & (scan[:, 1] < 0)].mean(),
        # the pixels as libpng stores them with the Paeth filter, run-length coding, zlib level 3
        "images.png_bytes": len(cv2.imencode(".png", rgb[..., ::-1].astype(np.uint8), [
            cv2.IMWRITE_PNG_COMPRESSION, 3, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_PAETH,
            cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE])[1]),
        "images.mean_abs_dx": dx.mean(),
        "images.grey_sd": grey.std(),
        "images.flat_share": np.mean(dx < 1),
        # the bottom fifth (this frame is 370 rows tall: rows 296-369), less a Gaussian of 3 px
        # (scipy's, mirrored at the edges as cv2's default), as 1.4826 x the median absolute deviation
        "images.road_colour_noise": _robust_sd(_high_pass(rgb[296:, :, 0] - rgb[296:, :, 1])),
        "images.road_detail": _robust_sd(_high_pass(grey[296:])),
        "images.road_surface_detail_5_10m": _robust_sd(_high_pass(grey).ravel()[pix]),
        "images.road_surface_colour_noise_5_10m":
            _robust_sd(_high_pass(rgb[..., 0] - rgb[..., 1]).ravel()[pix]),
        "labels.objects_per_frame": 1,
        "labels.proj_gap_px": _hand_proj_gap(t / "label_2/000000.txt", t / "calib/000000.txt",
                                             (rgb.shape[1], rgb.shape[0])),
    }
    for key, value in hand.items():
        rtol = 5e-3 if key.startswith("images.") and key != "images.png_bytes" else 1e-5
        assert got[key]["real"] == pytest.approx(value, rel=rtol), key
        assert got[key]["rel_diff"] == 0 and got[key]["verdict"] == "pass"
    assert got["labels.proj_gap_px"]["real"] == pytest.approx(9.56, abs=0.01)  # a tight pedestrian box
    # every pixel's channel means and SDs (numpy's own; fidelity.json keeps 6 significant digits)
    pixels = json.loads((tmp_path / "fidelity.json").read_text())["pixels_by_channel"]
    flat = rgb.reshape(-1, 3)
    assert pixels["real"]["mean"] == pytest.approx(flat.mean(axis=0), rel=1e-5)
    assert pixels["real"]["sd"] == pytest.approx(flat.std(axis=0), rel=1e-5)
    assert pixels["kitti_training_set"]["mean"] == [93.83, 98.76, 95.88]
    # the frame holds one Pedestrian and no DontCare region; KITTI's training set 28,742 Cars and
    # 4,487 Pedestrians in 7,481 frames
    by_class = json.loads((tmp_path / "fidelity.json").read_text())["objects_per_frame_by_class"]
    assert by_class["real"]["Pedestrian"] == 1 and by_class["real"]["Car"] == 0
    assert by_class["kitti_training_set"]["Car"] == pytest.approx(28742 / 7481)
    report = (tmp_path / "report.md").read_text()
    assert "| Pedestrian | 1 | 1 | 0.5998 |" in report and "| Car | 0 | 0 | 3.842 |" in report
    assert "| DontCare regions | 0 | 0 | 1.51 |" in report
    assert "| channel means | 79.3 / 93.8 / 98.4 | 79.3 / 93.8 / 98.4 | 93.8 / 98.8 / 95.9 |" in report


def test_sim_against_real_writes_every_number_and_the_same_bytes_twice(sim_vs_real, tmp_path):
    write_report(sim_vs_real, tmp_path / "a")
    write_report(sim_vs_real, tmp_path / "b")
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == ["fidelity.json", "frames.png", "images.png", "labels.png", "lidar.png", "report.md"]
    for name in names:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    doc = json.loads((tmp_path / "a/fidelity.json").read_text())
    assert set(doc["statistics"]) == STAT_KEYS
    assert doc["sim"]["frames_read"] == 2 and doc["real"]["frames_read"] == 4
    for key, h in doc["histograms"].items():
        assert len(h["edges"]) == len(h["sim"]) + 1
        assert sum(h["sim"]) == pytest.approx(1) and sum(h["real"]) == pytest.approx(1), key
    assert len(doc["rings"]["returns"]["sim"]) == 64
    row = doc["statistics"]["lidar.points_per_sweep"]
    assert row["rel_diff"] == pytest.approx((row["sim"] - row["real"]) / row["real"], rel=1e-3)
    report = (tmp_path / "a/report.md").read_text()
    assert "frames skipped: 0" in report and "`lidar.points_per_sweep`" in report
    assert doc["bootstrap"]["draws"] == 1000 and "| 95 % interval |" in report
    lo, hi = row["interval"]
    assert lo <= row["rel_diff"] <= hi and row["decided"] in (True, False)
    undecided = sum(r["decided"] is False for r in doc["statistics"].values())
    assert f"; {undecided} undecided." in report and report.count(", undecided |") == undecided


@pytest.mark.parametrize("kind", ["png", "bin", "label"])
def test_an_unreadable_frame_is_skipped_named_and_counted(sim_root, tmp_path, kind):
    root = tmp_path / "ds"
    shutil.copytree(sim_root, root)
    t = root / "training"
    bad = {"png": t / "image_2/000001.png", "bin": t / "velodyne/000001.bin",
           "label": t / "label_2/000001.txt"}[kind]
    if kind == "bin":
        bad.write_bytes(bad.read_bytes()[:-3])  # truncated: not a multiple of 16
    elif kind == "png":
        bad.write_bytes(bad.read_bytes()[:40] + b"\0" * 200)
    else:
        bad.write_text("Car 0.0 0 oops\n")
    with pytest.warns(UserWarning, match=f"000001.*{bad.name}"):
        stats = compute_stats(root)
    assert stats.frames == ["000000"]
    assert [fid for fid, _ in stats.skipped] == ["000001"] and str(bad) in stats.skipped[0][1]
    write_report(compare(stats, stats), tmp_path / "out")
    report = (tmp_path / "out/report.md").read_text()
    assert "frames skipped: 2" in report and f"sim 000001: {bad}" in report  # once per side


def test_a_dataset_without_velodyne_or_labels_reports_the_groups_absent(sim_root, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(sim_root, root)
    shutil.rmtree(root / "training/velodyne")
    shutil.rmtree(root / "training/label_2")
    stats = compute_stats(root)
    assert stats.groups == {"images": True, "lidar": False, "labels": False}
    comp = compare(stats, compute_stats(sim_root))
    verdicts = {r.key: r.verdict for r in comp.rows}
    # the road surface's statistics read the image where the scan's road returns fall: no scan, none
    needs_scan = {k for k in verdicts if k.startswith("images.road_surface_")}
    assert len(needs_scan) == 4
    assert all(v == "n/a" for k, v in verdicts.items() if not k.startswith("images.") or k in needs_scan)
    assert all(v != "n/a" for k, v in verdicts.items() if k.startswith("images.") and k not in needs_scan)
    write_report(comp, tmp_path / "out")
    report = (tmp_path / "out/report.md").read_text()
    assert "LiDAR: absent in sim (no velodyne/)" in report
    assert "Labels: absent in sim (no label_2/)" in report


def test_the_png_size_reads_the_pixels_not_the_file(sim_root, tmp_path):
    """The same pixels written by another encoder (libpng's filter search, zlib level 9): other
    file sizes, the same statistic."""
    root = tmp_path / "ds"
    shutil.copytree(sim_root, root)
    sizes = []
    for path in sorted((root / "training/image_2").glob("*.png")):
        before = path.stat().st_size
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(path), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        assert np.array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), img)
        sizes.append((before, path.stat().st_size))
    assert all(abs(a - b) > 0.02 * a for a, b in sizes)
    key = "images.png_bytes"
    rewritten, written = compute_stats(root).get(key), compute_stats(sim_root).get(key)
    assert len(written) == 2 and np.array_equal(rewritten, written)


def test_an_unknown_statistic_in_the_tolerance_file_names_the_file_and_the_key(tmp_path):
    path = tmp_path / "tol.yaml"
    path.write_text("default: 0.2\nstatistics:\n  lidar.points_per_sweeep: 0.1\n")
    with pytest.raises(ToleranceError, match=rf"{path}.*'lidar\.points_per_sweeep'"):
        load_tolerances(path)
    path.write_text("defualt: 0.2\n")
    with pytest.raises(ToleranceError, match=rf"{path}: key 'defualt'"):
        load_tolerances(path)
    assert load_tolerances().default == 0.15  # the shipped file validates


def test_the_verdict_flips_at_the_tolerance(sim_vs_real):
    key = "images.png_bytes"
    sim, real = (getattr(r, side) for r in sim_vs_real.rows if r.key == key for side in ("sim", "real"))
    rel = abs(sim - real) / real
    at = compare(sim_vs_real.sim, sim_vs_real.real, Tolerances(statistics={key: rel}))
    below = compare(sim_vs_real.sim, sim_vs_real.real, Tolerances(statistics={key: rel * 0.999}))
    assert [r.verdict for r in at.rows if r.key == key] == ["pass"]
    assert [r.verdict for r in below.rows if r.key == key] == ["fail"]
    assert verdict(1.15, 1.0, 0.15)[1] == "pass" and verdict(1.1501, 1.0, 0.15)[1] == "fail"
    assert verdict(0.0, 0.0, 0.15) == (0.0, "pass") and verdict(1.0, 0.0, 0.15) == (None, "fail")
    assert verdict(float("nan"), 1.0, 0.15)[1] == "n/a"


def test_the_command_writes_the_report_and_turns_a_bad_tolerance_file_into_a_message(real_root,
                                                                                     tmp_path):
    args = ["--sim", str(real_root), "--real", str(real_root), "--frames", "1", "--workers", "1"]
    res = CliRunner().invoke(fidelity, [*args, "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert "0 fail" in res.output and (tmp_path / "out/report.md").exists()
    # one frame against itself: every draw is that frame, so every interval is [0, 0]
    assert "(0 undecided by these frames)" in res.output
    res = CliRunner().invoke(fidelity, [*args, "--out", str(tmp_path / "o0"), "--draws", "0"])
    doc = json.loads((tmp_path / "o0/fidelity.json").read_text())
    assert res.exit_code == 0 and doc["bootstrap"]["draws"] == 0
    assert all(r["interval"] is None and r["decided"] is None for r in doc["statistics"].values())
    bad = tmp_path / "tol.yaml"
    bad.write_text("statistics: {nope: 0.1}\n")
    res = CliRunner().invoke(fidelity, [*args, "--out", str(tmp_path / "o2"), "--tolerances", str(bad)])
    assert res.exit_code == 1 and "'nope'" in res.output and str(bad) in res.output


def test_the_command_draws_the_real_frames_by_drive(real_root, tmp_path):
    """The committed drives file puts four of the eleven dev frames (one traffic jam) on one
    drive: the real side is drawn as eight drives; a file with a bad line is named, line and all."""
    args = ["--sim", str(real_root), "--real", str(real_root), "--workers", "1", "--draws", "20"]
    drives = str(ROOT / "results/fidelity/kitti_real_dev_drives.txt")
    res = CliRunner().invoke(fidelity, [*args, "--out", str(tmp_path / "out"), "--real-drives", drives])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "out/fidelity.json").read_text())
    assert doc["bootstrap"]["units"] == {"sim": 11, "real": 8}
    assert "| drawn as | frames | 8 drives |" in (tmp_path / "out/report.md").read_text()
    bad = tmp_path / "drives.txt"
    bad.write_text("001206 jam\n001497\n")
    res = CliRunner().invoke(fidelity, [*args, "--out", str(tmp_path / "o2"), "--real-drives", str(bad)])
    assert res.exit_code == 1 and f"{bad}, line 2" in res.output and not (tmp_path / "o2").exists()


def test_points_on_cars_by_distance_and_on_the_fully_visible_ones():
    """Medians by hand: the visible statistic keeps the occlusion-0 Cars of its distance bin."""
    from fidelity.catalog import car_points
    from fidelity.stats import DatasetStats

    d = DatasetStats("x", None, ["0"], [], {"lidar": True, "labels": True}, {
        "lidar.car_points": np.array([500.0, 120.0, 30.0, 100.0, 9.0, 2.0, 40.0]),
        "lidar.car_distance_m": np.array([10.0, 25.0, 30.0, 39.0, 45.0, 70.0, 20.0]),
        "lidar.car_occluded": np.array([0.0, 0.0, 2.0, 0.0, 0.0, 1.0, 1.0])}, {}, {})
    assert car_points(20, 40)(d) == np.median([120.0, 30.0, 100.0, 40.0])  # 70
    assert car_points(20, 40, visible=True)(d) == np.median([120.0, 100.0])  # 110
    assert car_points(40, 80)(d) == 5.5 and car_points(40, 80, visible=True)(d) == 9.0


def test_points_on_each_car_and_their_zero_readings_by_hand(real_root):
    """Frame 001206's Cars: the returns inside each label box, found here with the box's own
    frame written out (x along its length, z across, y down to its bottom face), and how many of
    them read 0."""
    from fidelity.lidar import lidar_stats

    t = real_root / "training"
    scan = np.fromfile(t / "velodyne/001206.bin", "<f4").reshape(-1, 4)
    calib = read_calib(t / "calib/001206.txt")
    labels = read_label(t / "label_2/001206.txt")
    acc = Acc(frames=["001206"])
    lidar_stats(acc, scan, calib, labels)
    rect = calib.lidar_to_rect(scan[:, :3].astype(np.float64))
    counts, zeros = [], []
    for o in (o for o in labels if o.type == "Car"):
        d = rect - o.location
        c, s = np.cos(o.rotation_y), np.sin(o.rotation_y)
        along, across = c * d[:, 0] - s * d[:, 2], s * d[:, 0] + c * d[:, 2]
        inside = ((np.abs(along) <= o.l / 2) & (np.abs(across) <= o.w / 2) & (d[:, 1] <= 0)
                  & (d[:, 1] >= -o.h))
        counts.append(inside.sum())
        zeros.append(np.mean(scan[inside, 3] == 0) if inside.any() else np.nan)
    got_counts = np.concatenate(acc.values["lidar.car_points"])
    got_zeros = np.concatenate(acc.values["lidar.car_zero_share"])
    assert len(counts) >= 3 and np.abs(got_counts - counts).max() <= 2  # points on a face may go either way
    ok = np.isfinite(zeros)
    assert np.allclose(got_zeros[ok], np.array(zeros)[ok], atol=0.01)
    assert np.array_equal(np.isfinite(got_zeros), ok)


def test_the_look_of_a_near_whole_car_by_hand(real_root):
    """Frame 001206: one Car is near (175 px tall), untruncated and fully visible; the others are
    truncated, occluded, Vans or a Truck. Its box's pixels, by hand: columns 551-736, rows 186-361."""
    t = real_root / "training"
    acc = Acc(frames=["001206"])
    grey = cv2.cvtColor(cv2.imread(str(t / "image_2/001206.png")), cv2.COLOR_BGR2GRAY)
    car_look_stats(acc, grey, read_label(t / "label_2/001206.txt"))
    rgb = iio.imread(t / "image_2/001206.png")[..., :3].astype(np.float64)
    patch = np.round(rgb @ [0.299, 0.587, 0.114])[186:362, 551:737]  # BT.601, as cv2's BGR2GRAY
    hand = {"labels.car_grey_mean": patch.mean(), "labels.car_grey_sd": patch.std(),
            "labels.car_abs_dx": np.abs(np.diff(patch, axis=1)).mean(),
            "labels.car_bottom_darkening": patch.mean() - patch[-22:].mean()}  # 176 rows / 8
    for key, value in hand.items():
        (got,) = np.concatenate(acc.values[key])
        assert got == pytest.approx(value, rel=5e-3, abs=0.05), key
    # a dark car, darker still below
    assert hand["labels.car_grey_mean"] < 100 and hand["labels.car_bottom_darkening"] > 10


def test_group_medians_are_numpys_median_per_group():
    from kitti.median import group_medians

    rng = np.random.default_rng(0)
    for trial in range(100):
        n = int(rng.integers(0, 300))
        group, values = rng.integers(0, 70, n), rng.normal(size=n)
        if trial % 3 == 0:
            values = np.round(values, 1)  # ties
        want = [np.median(values[group == k]) if np.any(group == k) else np.nan for k in range(64)]
        np.testing.assert_array_equal(group_medians(group, values, 64), want)


def test_a_car_labels_bottom_above_the_scans_road_by_geometry():
    """A flat road scanned on a grid, one Car label standing on it and one 0.1 m above it: the
    statistic reads each label's bottom above the road the lifter finds under it."""
    from kitti.calib import Calibration
    from kitti.labels import Object3D
    from fidelity.lidar import lidar_stats

    calib = Calibration.kitti_default()
    x, z = np.meshgrid(np.arange(-15.0, 15.0, 0.2), np.arange(3.0, 50.0, 0.2))
    road = np.stack([x.ravel(), np.full(x.size, 1.65), z.ravel()], axis=1)  # rect y points down
    scan = np.c_[calib.rect_to_lidar(road), np.full(len(road), 0.2)].astype(np.float32)

    def car(y: float, z: float) -> Object3D:
        return Object3D("Car", 0.0, 0, 0.0, np.array([500.0, 150.0, 560.0, 190.0]), 1.5, 1.7, 4.0,
                        np.array([2.0, y, z]), 0.0)

    acc = Acc(frames=["0"])
    lidar_stats(acc, scan, calib, [car(1.65, 20.0), car(1.55, 30.0)])
    got = np.concatenate(acc.values["lidar.car_bottom_above_road_m"])
    np.testing.assert_allclose(got, [0.0, 0.1], atol=1e-4)
