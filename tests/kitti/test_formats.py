"""Round trips and bad-input errors of every KITTI file format."""

from __future__ import annotations

import os

import numpy as np
import pytest

from kitti import (
    Calibration,
    KittiDataset,
    KittiFormatError,
    Object3D,
    read_calib,
    read_label,
    read_plane,
    read_split,
    read_velodyne,
    write_calib,
    write_label,
    write_plane,
    write_split,
    write_velodyne,
)
from kitti.io import atomic_write_text
from kitti.labels import parse_label_line

CAR = "Car 0.00 0 -1.5800 614.2400 181.7800 727.3100 284.7700 1.5700 1.7300 4.1500 1.0000 1.7500 13.2200 -1.6200"


def test_label_line_fields():
    o = parse_label_line(CAR)
    assert o.type == "Car" and o.occluded == 0 and o.score is None
    assert o.bbox.tolist() == [614.24, 181.78, 727.31, 284.77]
    assert (o.h, o.w, o.l) == (1.57, 1.73, 4.15)
    assert o.location.tolist() == [1.0, 1.75, 13.22]
    assert o.box7.tolist() == [1.0, 1.75, 13.22, 1.57, 1.73, 4.15, -1.62]
    assert o.to_line() == CAR


def test_small_negative_values_keep_their_sign_and_negative_zero_loses_it():
    o = Object3D("Car", 0.0, 0, -0.0049, [1, 2, 3, 4], 1.5, 1.6, 3.9, [-0.0051, -0.00004, 20.0], -0.009)
    fields = o.to_line().split()
    assert fields[3] == "-0.0049" and fields[11:13] == ["-0.0051", "0.0000"] and fields[14] == "-0.0090"
    back = parse_label_line(o.to_line())
    assert back.location[0] == -0.0051 and back.rotation_y == -0.009


def test_label_round_trip_with_scores_and_dontcare(tmp_path):
    rng = np.random.default_rng(1)
    objs = [Object3D("Pedestrian", 0.25, 1, 0.3, [1.5, 2.25, 30.125, 80.5], 1.76, 0.66, 0.84,
                     [-3.5, 1.6, 22.75], 0.1, score=0.875),
            Object3D.dont_care([100, 150, 130, 170])]
    for _ in range(20):
        objs.append(Object3D("Car", round(rng.uniform(0, 1), 2), int(rng.integers(0, 3)),
                             *np.round(rng.uniform(-3, 3, 1), 4), np.round(rng.uniform(0, 500, 4), 4),
                             *np.round(rng.uniform(0.5, 5, 3), 4), np.round(rng.uniform(-20, 60, 3), 4),
                             round(rng.uniform(-3, 3), 4), score=None))
    path = tmp_path / "000001.txt"
    write_label(path, objs)
    back = read_label(path)
    assert len(back) == len(objs) > 0
    for a, b in zip(objs, back):
        assert a.type == b.type and a.occluded == b.occluded and a.score == b.score
        np.testing.assert_array_equal(a.box7, b.box7)
        np.testing.assert_array_equal(a.bbox, b.bbox)
        assert (a.truncated, a.alpha) == (b.truncated, b.alpha)
    assert back[1].to_line() == "DontCare -1.00 -1 -10.0000 100.0000 150.0000 130.0000 170.0000 " \
                                "-1.0000 -1.0000 -1.0000 -1000.0000 -1000.0000 -1000.0000 -10.0000"
    first = path.read_bytes()
    write_label(path, back)
    assert path.read_bytes() == first


@pytest.mark.parametrize("line,field", [
    ("Car 0 0 0 1 2 3 4 1 1 1 1 1 1", "field count"),
    (CAR + " 0.5 7", "field count"),
    (CAR.replace("614.2400", "abc"), "x1"),
    (CAR.replace("1.7300", "-1.73"), "w"),
    (CAR.replace("Car 0.00 0", "Car 0.00 1.5"), "occluded"),
    (CAR.replace("13.2200", "nan"), "z"),
])
def test_label_errors_name_file_line_field(tmp_path, line, field):
    path = tmp_path / "000002.txt"
    path.write_text(CAR + "\n" + line + "\n")
    with pytest.raises(KittiFormatError) as e:
        read_label(path)
    assert e.value.line == 2 and e.value.field == field and e.value.path == str(path)
    assert str(path) in str(e.value) and "line 2" in str(e.value) and field in str(e.value)


def test_calib_round_trip_exact(tmp_path):
    c = Calibration.kitti_default()
    c.R0_rect[0, 1] = 0.1234567890123456789
    path = tmp_path / "calib.txt"
    write_calib(path, c)
    lines = path.read_text().splitlines()
    assert [ln.split(":")[0] for ln in lines] == ["P0", "P1", "P2", "P3", "R0_rect", "Tr_velo_to_cam",
                                                  "Tr_imu_to_velo"]
    assert all("  " not in ln for ln in lines)
    back = read_calib(path)
    for key in ("P0", "P1", "P2", "P3", "R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo"):
        np.testing.assert_array_equal(getattr(back, key), getattr(c, key))


def test_calib_missing_key_and_bad_number(tmp_path):
    path = tmp_path / "calib.txt"
    write_calib(path, Calibration.kitti_default())
    lines = path.read_text().splitlines()
    (tmp_path / "a.txt").write_text("\n".join(ln for ln in lines if not ln.startswith("R0_rect")))
    with pytest.raises(KittiFormatError, match="R0_rect") as e:
        read_calib(tmp_path / "a.txt")
    assert e.value.field == "R0_rect" and "a.txt" in str(e.value)
    lines[5] = lines[5].replace(lines[5].split()[3], "x1y", 1)
    (tmp_path / "b.txt").write_text("\n".join(lines))
    with pytest.raises(KittiFormatError) as e:
        read_calib(tmp_path / "b.txt")
    assert (e.value.line, e.value.field) == (6, "Tr_velo_to_cam")
    lines[5] = "Tr_velo_to_cam: 1 2 3"
    (tmp_path / "c.txt").write_text("\n".join(lines))
    with pytest.raises(KittiFormatError, match="expected 12 numbers"):
        read_calib(tmp_path / "c.txt")


def test_velodyne_round_trip_and_bad_size(tmp_path):
    pts = np.random.default_rng(0).normal(size=(1000, 4)).astype(np.float32)
    write_velodyne(tmp_path / "000000.bin", pts)
    np.testing.assert_array_equal(read_velodyne(tmp_path / "000000.bin"), pts)
    (tmp_path / "bad.bin").write_bytes(b"\0" * 20)
    with pytest.raises(KittiFormatError, match="multiple of 16") as e:
        read_velodyne(tmp_path / "bad.bin")
    assert e.value.field == "size"


def test_split_and_plane_round_trip(tmp_path):
    write_split(tmp_path / "val.txt", ["000003", "12", "000007"])
    assert read_split(tmp_path / "val.txt") == ["000003", "000012", "000007"]
    (tmp_path / "bad.txt").write_text("000001\nfoo\n")
    with pytest.raises(KittiFormatError) as e:
        read_split(tmp_path / "bad.txt")
    assert e.value.line == 2
    write_plane(tmp_path / "p.txt", [0, -1, 0, 1.65])
    np.testing.assert_allclose(read_plane(tmp_path / "p.txt"), [0, -1, 0, 1.65])


def test_failed_write_keeps_the_old_file(tmp_path):
    path = tmp_path / "000000.txt"
    write_label(path, [parse_label_line(CAR)])
    before = path.read_bytes()
    with pytest.raises(AttributeError):
        write_label(path, [parse_label_line(CAR), None])
    assert path.read_bytes() == before
    from kitti.io import atomic_path
    with pytest.raises(RuntimeError):
        with atomic_path(path) as tmp:
            tmp.write_text("half")
            raise RuntimeError("crash mid-write")
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["000000.txt"]


def test_dataset_root(tmp_path):
    import imageio.v3 as iio

    root = tmp_path / "ds"
    img = np.zeros((375, 1242, 3), np.uint8)
    (root / "training" / "image_2").mkdir(parents=True)
    for fid in ("000000", "000001"):
        iio.imwrite(root / "training" / "image_2" / f"{fid}.png", img)
        write_label(root / "training" / "label_2" / f"{fid}.txt", [parse_label_line(CAR)])
        write_calib(root / "training" / "calib" / f"{fid}.txt", Calibration.kitti_default())
    write_velodyne(root / "training" / "velodyne" / "000001.bin", np.ones((5, 4), np.float32))
    write_split(root / "ImageSets" / "val.txt", ["000001"])
    ds = KittiDataset(root)
    assert ds.ids() == ["000000", "000001"] and ds.ids("val") == ["000001"]
    assert ds.image_size("000000") == (1242, 375) and ds.image("000000").shape == (375, 1242, 3)
    assert ds.velodyne("000000") is None and ds.velodyne("000001").shape == (5, 4)
    assert ds.labels("000001")[0].type == "Car"
    with pytest.raises(KittiFormatError, match="split file not found"):
        ds.ids("test")
    with pytest.raises(KittiFormatError, match="testing"):
        KittiDataset(root, "testing")


def test_atomic_write_text_creates_folders(tmp_path):
    atomic_write_text(tmp_path / "a" / "b" / "c.txt", "x")
    assert (tmp_path / "a" / "b" / "c.txt").read_text() == "x"


def test_a_truncated_image_is_named(tmp_path):
    from kitti import KittiDataset, KittiFormatError

    folder = tmp_path / "training" / "image_2"
    folder.mkdir(parents=True)
    (folder / "000000.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20)
    ds = KittiDataset(tmp_path)
    for read in (ds.image, ds.image_size):
        with pytest.raises(KittiFormatError, match=r"000000\.png: cannot be read as an image"):
            read("000000")


def _resident_pages(path) -> int:
    """Pages of `path` in the page cache (mincore(2) over a mapping of the file)."""
    import ctypes
    import mmap

    libc = ctypes.CDLL(None, use_errno=True)
    libc.mincore.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p]
    size = os.path.getsize(path)
    with open(path, "r+b") as f, mmap.mmap(f.fileno(), size) as m:
        buf = ctypes.c_char.from_buffer(m)
        vec = (ctypes.c_ubyte * ((size + mmap.PAGESIZE - 1) // mmap.PAGESIZE))()
        try:
            if libc.mincore(ctypes.addressof(buf), size, vec) != 0:
                pytest.skip(f"mincore failed: errno {ctypes.get_errno()}")
            return sum(v & 1 for v in vec)
        finally:
            del buf


@pytest.mark.skipif(not hasattr(os, "posix_fadvise"), reason="no posix_fadvise")
def test_write_behind_lets_a_batch_go_at_the_next(tmp_path):
    """A batch handed over leaves the cache at the next batch's hand-over, written back by then
    (pages still dirty cannot leave); a file that was never written is skipped; others stay."""
    from kitti.io import WriteBehind

    def batch(name):
        paths = [tmp_path / f"{name}{k}.bin" for k in range(2)]
        for p in paths:
            write_velodyne(p, np.ones((65536, 4), np.float32))  # 1 MiB, 256 pages
        return paths

    def written_back(paths):
        for p in paths:
            with open(p, "rb") as f:
                os.fsync(f.fileno())

    kept = batch("kept")
    written_back(kept)
    if min(_resident_pages(p) for p in kept) < 256:
        pytest.skip("this file system does not keep written pages cached")
    wb = WriteBehind()
    first = batch("a")
    wb.written(first + [tmp_path / "never_written.bin"])
    written_back(first)
    wb.written(batch("b"))
    assert [_resident_pages(p) for p in first] == [0, 0]
    assert [_resident_pages(p) for p in kept] == [256, 256]
