"""`testbed show` draws projected boxes where the geometry puts them."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
from click.testing import CliRunner

from kitti import Calibration, Object3D, write_calib, write_label, write_velodyne
from kitti.boxes import box_corners
from testbed.cli import cli
from testbed.draw import image_edges

CALIB = Calibration.kitti_default()


def _car(x, z, ry=-np.pi / 2):
    return Object3D("Car", 0.0, 0, 0.0, [0, 0, 10, 10], 1.5, 1.6, 3.9, [x, 1.65, z], ry)


def test_image_edges_are_the_projected_corners_and_cut_at_the_near_plane():
    car = _car(2.0, 15.0)
    segs = image_edges(car, CALIB)
    assert len(segs) == 12
    uv, _ = CALIB.rect_to_image(box_corners(car.box7[None])[0])
    ends = np.concatenate(segs)
    np.testing.assert_allclose(np.sort(ends[:, 0]), np.sort(np.repeat(uv[:, 0], 3)), atol=1e-9)
    straddling = _car(2.0, 0.5)  # 3.9 m long box centred 0.5 m ahead: rear part behind the camera
    cut = image_edges(straddling, CALIB)
    # the 4 rear-face edges lie wholly behind the camera; the 4 long edges are cut at z = 0.1
    assert len(cut) == 8 and all(np.isfinite(s).all() for s in cut)


def test_show_writes_a_picture(tmp_path):
    root = tmp_path / "ds" / "training"
    (root / "image_2").mkdir(parents=True)
    iio.imwrite(root / "image_2" / "000003.png", np.full((375, 1242, 3), 90, np.uint8))
    write_calib(root / "calib" / "000003.txt", CALIB)
    write_label(root / "label_2" / "000003.txt",
                [_car(2.0, 15.0), _car(-4.0, 30.0, 0.3), Object3D.dont_care([100, 150, 130, 170])])
    pts = np.random.default_rng(0).uniform([0, -20, -1.7, 0], [60, 20, 1, 1], (2000, 4))
    write_velodyne(root / "velodyne" / "000003.bin", pts.astype(np.float32))
    out = tmp_path / "frame.png"
    res = CliRunner().invoke(cli, ["show", "--data", str(tmp_path / "ds"), "--frame", "3", "--out", str(out)])
    assert res.exit_code == 0, res.output
    img = iio.imread(out)
    assert img.shape[1] > 2 * img.shape[0] and img.shape[2] in (3, 4)
    res = CliRunner().invoke(cli, ["show", "--data", str(tmp_path / "ds"), "--frame", "4", "--out", str(out)])
    assert res.exit_code != 0 and "000004.png" in res.output
