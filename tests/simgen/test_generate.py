"""The dataset writer: exact rebuild from meta/, same seed same bytes, resume, KITTI layout."""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from kitti.dataset import KittiDataset
from kitti.derived import dump_json
from kitti.planes import read_plane
from simgen.generate import (PNG_CAMERA, PNG_DEPTH, PNG_INSTANCE, Job, decode_depth, encode_png, frame_files,
                             generate, make_frame)
from simgen.meta import world_from_meta, world_to_meta
from simgen.road import RoadLayout
from simgen.sample import sample_world
from simgen.spec import load_spec, spec_to_dict
from testbed.backends import LocalBackend

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def spec():
    s = load_spec(ROOT / "scenes/quickstart.yaml")
    return s.model_copy(update={"lidar": None})


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_world_rebuilt_from_meta_equals_the_original(spec):
    world = sample_world(spec, 9, 1)
    meta = json.loads(dump_json(world_to_meta(world, spec_to_dict(spec))))
    again = world_from_meta(meta)
    assert len(again.actors) == len(world.actors) > 0
    for a, b in zip(world.actors, again.actors):
        assert (a.id, a.cls) == (b.id, b.cls)
        assert np.array_equal(a.pose, b.pose) and np.array_equal(a.velocity, b.velocity)
        assert a.yaw_rate == b.yaw_rate
        for p, q in zip(a.parts, b.parts, strict=True):
            assert np.array_equal(p.mesh.vertices, q.mesh.vertices)
            assert np.array_equal(p.mesh.faces, q.mesh.faces) and p.material == q.material
    for p, q in zip(world.static, again.static, strict=True):
        assert np.array_equal(p.mesh.vertices, q.mesh.vertices) and p.material == q.material
    assert again.weather == world.weather and again.light == world.light
    assert np.array_equal(again.lidar_pose, world.lidar_pose)
    assert np.array_equal(again.rig.calib.P2, world.rig.calib.P2)
    assert np.array_equal(again.rig.cam2_from_world(), world.rig.cam2_from_world())


def test_two_runs_with_one_seed_give_identical_files_and_resume_completes(spec, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    generate(spec, a, frames=2, seed=4)
    with LocalBackend(2) as pool:  # a process pool: same bytes
        generate(spec, b, frames=2, seed=4, backend=pool)
    fa = _files(a)
    assert fa == _files(b)
    training = a / "training"
    assert len(frame_files(training, "000001", False)) == 6
    # Interrupt frame 1 half way: its meta (written last) and its image are gone.
    (training / "meta" / "000001.json").unlink()
    (training / "image_2" / "000001.png").unlink()
    before = (training / "label_2" / "000000.txt").stat().st_mtime_ns
    generate(spec, a, frames=2, seed=4)
    assert _files(a) == fa
    assert (training / "label_2" / "000000.txt").stat().st_mtime_ns == before  # done frames kept
    assert not list(a.rglob("*.tmp"))
    with pytest.raises(ValueError, match="different seed"):
        generate(spec, a, frames=2, seed=5)


def test_dataset_reads_back_with_the_kitti_package(spec, tmp_path):
    make_frame(Job(spec, 0, 3, tmp_path))
    ds = KittiDataset(tmp_path)
    labels = ds.labels("000003")
    assert ds.image("000003").shape == (375, 1242, 3)
    assert any(o.type == "Car" for o in labels)
    meta = json.loads((tmp_path / "training/meta/000003.json").read_text())
    world = world_from_meta(meta)
    plane = read_plane(tmp_path / "training/planes/000003.txt")
    road = RoadLayout(**world.scenery["road"])  # the street rises or falls: a fitted plane
    np.testing.assert_allclose(plane, world.rig.road_plane_rect(road.fitted_plane()), atol=1e-6)
    depth = decode_depth(cv2.imread(str(tmp_path / "training/depth_2/000003.png"), cv2.IMREAD_UNCHANGED))
    inst = cv2.imread(str(tmp_path / "training/instance_2/000003.png"), cv2.IMREAD_UNCHANGED)
    assert inst.dtype == np.uint16 and depth.shape == inst.shape == (375, 1242)
    labelled = [a for a in meta["actors"] if a.get("label") == "label"]
    assert len(labelled) == sum(o.type != "DontCare" for o in labels) > 0
    for a in labelled:  # every labelled actor owns exactly its visible pixels in instance_2
        assert int((inst == a["id"]).sum()) == a["visible_px"] > 0
        assert np.all(depth[inst == a["id"]] > 0)


def _row_filters(png: bytes, row_bytes: int) -> set[int]:
    """The filter type byte that starts each row of a PNG's decompressed image data."""
    pos, idat = 8, b""
    while pos < len(png):
        (n,), kind = struct.unpack(">I", png[pos:pos + 4]), png[pos + 4:pos + 8]
        if kind == b"IDAT":
            idat += png[pos + 8:pos + 8 + n]
        pos += 12 + n
    raw = zlib.decompress(idat)
    return {raw[i] for i in range(0, len(raw), row_bytes + 1)}


@pytest.mark.parametrize("kind", ["camera", "depth", "instance"])
def test_png_files_hold_the_exact_pixels_with_one_row_filter(kind):
    rng = np.random.default_rng(3)
    img, setting, row_filter = {
        "camera": (rng.integers(0, 256, (37, 53, 3), dtype=np.uint8), PNG_CAMERA, 4),  # Paeth
        "depth": (np.where(rng.random((37, 53)) < 0.2, 0, rng.integers(1, 65536, (37, 53))).astype(np.uint16),
                  PNG_DEPTH, 2),  # Up
        "instance": (np.repeat(rng.integers(0, 65536, (37, 1)), 53, axis=1).astype(np.uint16),
                     PNG_INSTANCE, 2),
    }[kind]
    png = encode_png(img, setting)
    np.testing.assert_array_equal(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED), img)
    assert _row_filters(png, img[0].size * img.itemsize) == {row_filter}  # every row
