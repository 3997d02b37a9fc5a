"""`testbed rescan` and `testbed reduce-beams` on a generated one-frame dataset."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from kitti.velodyne import read_velodyne
from kitti.velodyne_info import read_scan_info
from simgen.lidar import read_scan
from testbed.cli import cli

FID = "000000"


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    from simgen.generate import generate
    from simgen.spec import load_spec

    root = tmp_path_factory.mktemp("lidar_src")
    generate(load_spec("scenes/urban.yaml"), root, frames=1)
    assert (root / "training" / "velodyne" / f"{FID}.bin").exists()
    return root


def _run(*args):
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


def _files(root):
    return sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())


def test_rescan_same_sensor_reproduces_the_dataset(source, tmp_path):
    out = tmp_path / "same"
    # urban.yaml's sensor: the HDL-64E cut at 80 m, as KITTI's scans are
    _run("rescan", "--data", source, "--out", out, "--lidar", "hdl64e", "--max-range", 80, "--workers", 1)
    files = _files(source)
    assert len(files) >= 8  # image, depth, instance, label, calib, plane, scan, side file, meta...
    for rel in files:
        assert (out / rel).read_bytes() == (source / rel).read_bytes(), rel


def test_rescan_other_sensor_changes_only_the_lidar(source, tmp_path):
    out = tmp_path / "vlp16"
    _run("rescan", "--data", source, "--out", out, "--lidar", "vlp16", "--workers", 1)
    changed = {r for r in _files(source) if (out / r).read_bytes() != (source / r).read_bytes()}
    assert {r.parts[1] for r in changed if r.parts[0] == "training"} == \
        {"velodyne", "velodyne_info", "meta"}
    # images and labels are the very same files (hard links)
    img = "training/image_2/000000.png"
    assert (out / img).stat().st_ino == (source / img).stat().st_ino
    s = read_scan(out / "training", FID)
    assert set(np.unique(s.ring)) <= set(range(16)) and len(s) > 10_000
    meta = json.loads((out / "training/meta/000000.json").read_text())
    assert meta["lidar"]["preset"] == "vlp16"
    counts = s.point_counts()
    for a in meta["actors"]:
        assert a["lidar_points"] == counts.get(a["id"], 0)
    assert any(a["lidar_points"] > 0 for a in meta["actors"])
    # resumable: a second run is a no-op; another request into the same root is refused
    before = (out / "training/velodyne/000000.bin").stat().st_mtime_ns
    _run("rescan", "--data", source, "--out", out, "--lidar", "vlp16", "--workers", 1)
    assert (out / "training/velodyne/000000.bin").stat().st_mtime_ns == before
    res = CliRunner().invoke(cli, ["rescan", "--data", str(source), "--out", str(out), "--lidar", "hdl32e"])
    assert res.exit_code != 0 and "different request" in res.output


def test_reduce_beams_keeps_every_other_ring_with_or_without_side_files(source, tmp_path):
    out = tmp_path / "r32"
    (source / ".done").write_text("{}")  # a pipeline stage's marker must not be inherited
    _run("reduce-beams", "--data", source, "--beams", 32, "--out", out, "--workers", 1)
    pts = read_velodyne(source / "training/velodyne/000000.bin")
    info = read_scan_info(source / "training/velodyne_info/000000.npz", len(pts))
    keep = info["ring"] % 2 == 0
    red = read_scan(out / "training", FID)
    assert np.array_equal(red.points, pts[keep])
    assert np.array_equal(red.ring, info["ring"][keep] // 2)
    assert np.array_equal(red.actor_id, info["actor_id"][keep])
    meta = json.loads((out / "training/meta/000000.json").read_text())
    assert meta["lidar"]["beams"] == 32
    counts = red.point_counts()
    assert all(a["lidar_points"] == counts.get(a["id"], 0) for a in meta["actors"])
    assert (out / "training/label_2/000000.txt").read_bytes() == \
        (source / "training/label_2/000000.txt").read_bytes()
    assert not (out / ".done").exists()
    (source / ".done").unlink()

    # a real-KITTI-like copy: no side files, no meta; rings come from the point order
    kitti = tmp_path / "kitti"
    shutil.copytree(source, kitti, ignore=shutil.ignore_patterns("velodyne_info", "meta",
                                                                 "simgen.json"))
    out2 = tmp_path / "k32"
    _run("reduce-beams", "--data", kitti, "--beams", 32, "--out", out2, "--workers", 1)
    assert np.array_equal(read_velodyne(out2 / "training/velodyne/000000.bin"), pts[keep])
    res = CliRunner().invoke(cli, ["reduce-beams", "--data", str(kitti), "--beams", "24",
                                   "--out", str(tmp_path / "bad")])
    assert res.exit_code != 0 and "must divide" in res.output
    assert not (tmp_path / "bad").exists()  # refused before writing anything


def test_actor_points_lie_in_their_boxes_and_the_calibration_maps_the_lidar_frame(source):
    """With motion off, every point of an actor, taken to the actor's frame through the
    world's LiDAR pose, lies within the actor's mesh extent (the label box's h, w, l); and the
    calibration's velodyne frame is that LiDAR pose, so calib.lidar_to_rect takes points to
    the rect frame the labels are written in."""
    from kitti.calib import read_calib
    from simgen.lidar import preset, scan
    from simgen.meta import world_from_meta

    meta = json.loads((source / "training/meta/000000.json").read_text())
    calib = read_calib(source / "training/calib/000000.txt")
    world = world_from_meta(meta)
    np.testing.assert_array_equal(world.rig.reference_pose, world.lidar_pose)
    rect_from_world = calib.velo_to_rect @ np.linalg.inv(world.lidar_pose)
    s = scan(world, preset("hdl64e").ideal(), 0)
    checked = 0
    for a in meta["actors"]:
        pts = s.points[s.actor_id == a["id"], :3].astype(np.float64)
        if len(pts) < 20:
            continue
        actor = world.actor(a["id"])
        p_world = pts @ world.lidar_pose[:3, :3].T + world.lidar_pose[:3, 3]
        inv = np.linalg.inv(actor.pose)
        p_actor = p_world @ inv[:3, :3].T + inv[:3, 3]
        lo, hi = actor.mesh().bounds
        assert np.all(p_actor >= lo - 1e-4) and np.all(p_actor <= hi + 1e-4), a["id"]
        h, w, l = a["box7"][3:6]
        np.testing.assert_allclose(hi - lo, [l, w, h], atol=1e-9)
        rect = calib.lidar_to_rect(pts)
        np.testing.assert_allclose(rect, p_world @ rect_from_world[:3, :3].T
                                   + rect_from_world[:3, 3], atol=1e-9)
        checked += 1
    assert checked >= 3


def test_rescan_with_lidar_weather_keeps_the_images_and_loses_far_returns(source, tmp_path):
    """--fog-extinction changes what the LiDAR sees only: beta = 0.03/m (visibility 100 m) takes the
    two-way loss exp(-2 beta d) to 0.09 at 40 m, so far returns vanish and scatter appears near."""
    out = tmp_path / "fog"
    _run("rescan", "--data", source, "--out", out, "--lidar", "hdl64e", "--fog-extinction", 0.03,
         "--workers", 1)
    for rel in ("training/image_2/000000.png", "training/label_2/000000.txt", "training/calib/000000.txt"):
        assert (out / rel).read_bytes() == (source / rel).read_bytes()
    clear = read_velodyne(source / "training/velodyne/000000.bin")
    fog = read_velodyne(out / "training/velodyne/000000.bin")
    far = lambda p: int((np.linalg.norm(p[:, :2], axis=1) > 40).sum())  # noqa: E731
    assert far(clear) > 0 and far(fog) < far(clear) / 4
    assert json.loads((out / "lidar.json").read_text())["lidar"]["weather"] == {"fog_extinction": 0.03}
