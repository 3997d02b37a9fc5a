"""The command line's one grammar (testbed/options.py): --version, the commands in the order of
the work, --data for every dataset read, one --split and one --workers default, and a frame that
cannot be read stopping a command with its file named (fidelity: unless --skip-unreadable)."""

from __future__ import annotations

import importlib.metadata
import json
import shutil

import click
import imageio.v3 as iio
import numpy as np
import pytest
from click.testing import CliRunner

from kitti import Calibration, Object3D, write_calib, write_label, write_velodyne
from kitti.splits import write_split
from testbed.cli import COMMANDS, DISTRIBUTION, cli
from testbed.options import DEFAULT_SPLIT, DEFAULT_WORKERS, LIDAR_PRESETS

ORDER = ["generate", "show", "rescan", "reduce-beams", "relabel", "detect", "lift", "evaluate",
         "run", "sweep", "fidelity", "train-detector", "train-lifter"]
READ_A_DATASET = ["show", "rescan", "reduce-beams", "relabel", "detect", "lift", "evaluate",
                  "fidelity", "train-detector", "train-lifter"]
WITH_WORKERS = ["generate", "rescan", "reduce-beams", "relabel", "run", "sweep", "fidelity"]


def _command(name: str) -> click.Command:
    return cli.get_command(click.Context(cli), name)


def _params(name: str) -> dict[str, click.Parameter]:
    return {p.name: p for p in _command(name).params}


def _invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_version_prints_the_installed_distributions():
    res = _invoke("--version")
    assert res.exit_code == 0 and res.output == f"testbed {importlib.metadata.version(DISTRIBUTION)}\n"


def test_the_commands_are_listed_in_the_order_of_the_work():
    assert list(COMMANDS) == ORDER
    assert cli.list_commands(click.Context(cli)) == ORDER
    listing = _invoke("--help").output.split("Commands:")[1].split()
    assert [w for w in listing if w in COMMANDS] == ORDER


@pytest.mark.parametrize("name", READ_A_DATASET)
def test_every_command_that_reads_a_dataset_takes_it_as_data(name):
    params = _command(name).params
    (data,) = [p for p in params if "--data" in p.opts]
    assert data.name == "data" and isinstance(data.type, click.Path)
    assert data.type.exists and not data.type.file_okay
    assert not [p for p in params if isinstance(p, click.Argument)], "the dataset is no argument"


def test_one_split_default_and_one_meaning():
    defaults = {name: p.default for name in ORDER for key, p in _params(name).items() if key == "split"}
    assert set(defaults) == {"detect", "lift", "evaluate", "fidelity"}
    assert set(defaults.values()) == {DEFAULT_SPLIT} == {"all"}
    for name in ("train-detector", "train-lifter"):  # which frames train, which evaluate
        params = _params(name)
        assert (params["train_split"].default, params["val_split"].default) == ("train", "val")


def test_one_workers_default():
    defaults = {name: p.default for name in ORDER for key, p in _params(name).items() if key == "workers"}
    assert set(defaults) == set(WITH_WORKERS)
    assert set(defaults.values()) == {DEFAULT_WORKERS}


def test_the_former_spellings_still_parse():
    assert "--sim" in _params("fidelity")["data"].opts  # fidelity --data SIM --real REAL
    assert {"--data-dir", "--data"} <= set(_params("sweep")["data_dir"].opts)  # where it writes


def test_progress_bars_count_frames_where_a_job_is_a_frame():
    from testbed.backends import _unit

    stages = ["generate urban", "rescan vlp16", "relabel", "reduce to 16 beams", "reduce beams",
              "points", "bootstrap", "fidelity urban (40 frames)"]
    assert [_unit(d) for d in stages] == ["frame"] * 5 + ["point", "point", "chunk"]


def test_the_lidar_presets_listed_are_the_simulators():
    from simgen.lidar import PRESETS

    assert LIDAR_PRESETS == tuple(PRESETS)
    for name in ("generate", "rescan"):
        assert all(p in _params(name)["lidar_preset"].help for p in PRESETS)


def _write_dataset(root, frames=2):
    """A tiny KITTI-format root: noise images, a Car each, scans of scattered points."""
    rng = np.random.default_rng(0)
    t = root / "training"
    (t / "image_2").mkdir(parents=True)
    for i in range(frames):
        fid = f"{i:06d}"
        iio.imwrite(t / "image_2" / f"{fid}.png", rng.integers(0, 255, (375, 1242, 3), dtype=np.uint8))
        write_calib(t / "calib" / f"{fid}.txt", Calibration.kitti_default())
        write_label(t / "label_2" / f"{fid}.txt", [Object3D("Car", 0.0, 0, -1.7, [500, 150, 600, 220],
                                                             1.5, 1.6, 3.9, [2.0, 1.65, 15.0], -1.57)])
        pts = np.c_[rng.uniform(2, 40, (500, 1)), rng.uniform(-10, 10, (500, 1)),
                    rng.uniform(-1.8, 1, (500, 1)), rng.uniform(0, 1, (500, 1))]
        write_velodyne(t / "velodyne" / f"{fid}.bin", pts.astype(np.float32))
    write_split(root / "ImageSets" / "val.txt", [f"{i:06d}" for i in range(frames)][-1:])
    return root


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return _write_dataset(tmp_path_factory.mktemp("cli") / "good")


@pytest.fixture
def truncated(good, tmp_path):
    """The dataset with frame 000001's scan cut short (not a multiple of 16 bytes)."""
    root = tmp_path / "bad"
    shutil.copytree(good, root)
    bad = root / "training/velodyne/000001.bin"
    bad.write_bytes(bad.read_bytes()[:-3])
    return root, bad


def test_fidelity_stops_at_a_frame_it_cannot_read_unless_told_to_skip_it(good, truncated, tmp_path):
    root, bad = truncated
    args = ["fidelity", "--data", root, "--real", good, "--workers", 1, "--draws", 0]
    res = _invoke(*args, "--out", tmp_path / "stopped")
    assert res.exit_code == 1 and "000001" in res.output and str(bad) in res.output
    assert "--skip-unreadable" in res.output and not (tmp_path / "stopped").exists()
    res = _invoke(*args, "--out", tmp_path / "skipped", "--skip-unreadable")
    assert res.exit_code == 0, res.output
    assert f"skipped sim frame 000001: {bad}" in res.output
    assert f"sim 000001: {bad}" in (tmp_path / "skipped/report.md").read_text()


def test_an_unreadable_frame_is_an_error_on_a_line_of_its_own(truncated, tmp_path):
    root, bad = truncated
    for args in (["show", "--data", root, "--frame", 1, "--out", tmp_path / "f.png"],
                 ["reduce-beams", "--data", root, "--beams", 16, "--out", tmp_path / "r", "--workers", 1]):
        res = _invoke(*args)
        assert res.exit_code == 1 and isinstance(res.exception, SystemExit), res.output  # no traceback
        (error,) = [line for line in res.output.splitlines() if "Error" in line]
        assert error.startswith("Error: ") and str(bad) in error, res.output


def test_evaluate_reads_the_truth_and_the_split_of_data(good, tmp_path):
    pred = tmp_path / "pred"
    for fid in ("000000", "000001"):
        write_label(pred / f"{fid}.txt", [Object3D("Car", 0.0, 0, -1.7, [500, 150, 600, 220], 1.5, 1.6,
                                                   3.9, [2.0, 1.65, 15.0], -1.57, 0.9)])
    res = _invoke("evaluate", "--data", good, "--pred", pred, "--split", "val", "--classes", "Car",
                  "--json", tmp_path / "val.json")
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "val.json").read_text())["n_gt"]["Car"][0] == 1  # ImageSets/val.txt
    res = _invoke("evaluate", "--gt", good / "training/label_2", "--pred", pred, "--classes", "Car",
                  "--json", tmp_path / "all.json", "--bootstrap", 5)
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "all.json").read_text())["n_gt"]["Car"][0] == 2  # 'all': every file
    assert not res.output.endswith("\n\n") and "\n\nAP|R40 with its 95% interval" in res.output
    res = _invoke("evaluate", "--gt", good / "training/label_2", "--pred", pred, "--split", "val",
                  "--json", tmp_path / "gt_val.json")  # a NAME next to --gt: ROOT/ImageSets
    assert res.exit_code == 0 and json.loads((tmp_path / "gt_val.json").read_text())["n_gt"]["Car"][0] == 1
    res = _invoke("evaluate", "--data", good, "--gt", good / "training/label_2", "--pred", pred)
    assert res.exit_code == 2 and "--data ROOT or as --gt LABEL_DIR" in res.output
    res = _invoke("evaluate", "--data", good, "--pred", pred, "--split", "test")
    assert res.exit_code == 2 and str(good / "ImageSets/test.txt") in res.output
