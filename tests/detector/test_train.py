"""End to end on a toy KITTI folder: a tiny run overfits, resume is exact, detect writes KITTI results."""

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from detector.augment import AugmentConfig
from detector.infer import Detector
from detector.train import TrainConfig, train
from kitti.dataset import KittiDataset
from kitti.iou import iou_2d
from kitti.labels import read_label
from tests.detector.toydata import write_toy_dataset


@pytest.fixture(scope="module")
def overfit_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("det")
    root = write_toy_dataset(tmp / "ds", 16, seed=3, size=(256, 96))
    cfg = TrainConfig(data=str(root), out=str(tmp / "run"), epochs=80, img_size=(256, 96), batch=8,
                      lr=0.02, augment=AugmentConfig.off(), close_mosaic=0, eval_every=0,
                      warmup_epochs=1, threads=1, progress=False)
    train(cfg)
    return root, tmp / "run"


# A box counts as found at KITTI's overlap for its class (the devkit's: Car 0.7, Pedestrian and
# Cyclist 0.5). Demanding 0.7 of every class holds on some machines and fails on a 2-core AMD EPYC
# for one pedestrian, 8-14 px wide: IoU 0.64 after 80 epochs, 0.72 after 120. Why the run differs
# there is not known (torch's AVX2 kernels, forced with ATEN_CPU_CAPABILITY=avx2, give the same 0.64).
FOUND_AT = {"Car": 0.7, "Pedestrian": 0.5, "Cyclist": 0.5}


def test_tiny_run_overfits(overfit_run):
    root, run = overfit_run
    hist = (run / "history.csv").read_text().splitlines()
    losses = [float(line.split(",")[2]) for line in hist[1:]]
    assert len(losses) == 80
    assert np.mean(losses[-5:]) < 0.3 * np.mean(losses[:5])
    det = Detector.load(run / "weights.pt")
    ds = KittiDataset(root)
    n = 0
    for fid in ds.ids("train"):
        gt = ds.labels(fid)
        d = det.detect([ds.image(fid)], conf_threshold=0.3)[0]
        iou = iou_2d(np.array([o.bbox for o in gt]), d[:, :4])
        for k, o in enumerate(gt):
            best = int(np.argmax(iou[k]))
            assert iou[k, best] > FOUND_AT[o.type], (fid, o.type, iou[k])
            assert det.classes[int(d[best, 5])] == o.type
            n += 1
    assert n >= 25
    assert (run / "history.png").is_file() and (run / "anchors.txt").is_file()


def test_detect_cli_writes_kitti_results(overfit_run, tmp_path):
    from testbed.cli import cli
    root, run = overfit_run
    res = CliRunner().invoke(cli, ["detect", "--data", str(root), "--out", str(tmp_path / "pred"),
                                   "--weights", str(run / "weights.pt"), "--split", "train", "--conf", "0.3"])
    assert res.exit_code == 0, res.output
    files = sorted((tmp_path / "pred").glob("*.txt"))
    assert len(files) == 16
    line = files[0].read_text().splitlines()[0].split()
    assert len(line) == 16
    assert line[1:4] == ["-1.00", "-1", "-10.0000"]
    assert line[8:15] == ["-1.0000"] * 3 + ["-1000.0000"] * 3 + ["-10.0000"]
    objs = read_label(files[0])
    assert all(o.score is not None and 0 < o.score <= 1 for o in objs)
    assert all(0 <= o.bbox[0] < o.bbox[2] <= 255 and 0 <= o.bbox[1] < o.bbox[3] <= 95 for o in objs)
    # --no-mirror: one pass, as Detector(mirror=False) gives it
    res = CliRunner().invoke(cli, ["detect", "--data", str(root), "--out", str(tmp_path / "single"),
                                   "--weights", str(run / "weights.pt"), "--split", "train", "--conf", "0.3",
                                   "--no-mirror"])
    assert res.exit_code == 0, res.output
    fid = files[0].stem
    d = Detector.load(run / "weights.pt", mirror=False).detect([KittiDataset(root).image(fid)], 0.3)[0]
    single = read_label(tmp_path / "single" / f"{fid}.txt")
    np.testing.assert_allclose([o.bbox for o in single], d[:, :4], atol=1e-2)
    # --fuse-boxes: the two reads' boxes fused, as Detector(fuse_boxes=True) gives them
    res = CliRunner().invoke(cli, ["detect", "--data", str(root), "--out", str(tmp_path / "fused"),
                                   "--weights", str(run / "weights.pt"), "--split", "train", "--conf", "0.3",
                                   "--fuse-boxes"])
    assert res.exit_code == 0, res.output
    d = Detector.load(run / "weights.pt", fuse_boxes=True).detect([KittiDataset(root).image(fid)], 0.3)[0]
    fused = read_label(tmp_path / "fused" / f"{fid}.txt")
    np.testing.assert_allclose([o.bbox for o in fused], d[:, :4], atol=1e-2)
    np.testing.assert_allclose([o.score for o in fused], [o.score for o in objs], atol=1e-4)


def test_resume_is_exact(tmp_path):
    root = write_toy_dataset(tmp_path / "ds", 8, seed=4, size=(128, 64), max_objects=3)
    base = dict(data=str(root), img_size=(128, 64), epochs=2, batch=4, eval_every=0, progress=False, threads=1,
                augment=AugmentConfig(mixup="thresholded"), close_mosaic=1)
    train(TrainConfig(out=str(tmp_path / "a"), **base))
    train(TrainConfig(out=str(tmp_path / "b"), **base), stop_after=1)
    assert not (tmp_path / "b" / "weights.pt").exists()
    train(TrainConfig(out=str(tmp_path / "b"), **base), resume=True)
    a = torch.load(tmp_path / "a" / "weights.pt", weights_only=True)["model"]
    b = torch.load(tmp_path / "b" / "weights.pt", weights_only=True)["model"]
    assert a.keys() == b.keys() and len(a) > 50  # every tensor of the model
    for k in a:
        assert torch.equal(a[k], b[k]), k


def test_missing_weights_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.pt"):
        Detector.load(tmp_path / "nope.pt")


def test_init_starts_from_given_weights(overfit_run, tmp_path):
    root, run = overfit_run
    cfg = TrainConfig(data=str(root), out=str(tmp_path / "ft"), epochs=1, batch=8, lr=0.0, eval_every=0,
                      augment=AugmentConfig.off(), close_mosaic=0, init=str(run / "weights.pt"),
                      threads=1, progress=False)
    train(cfg)
    src = torch.load(run / "weights.pt", weights_only=True)
    ft = torch.load(tmp_path / "ft" / "weights.pt", weights_only=True)
    assert ft["input_size"] == src["input_size"] and ft["model_cfg"] == src["model_cfg"]
    # lr 0: every learned tensor is unchanged (only BN running statistics move)
    learned = [k for k in src["model"] if "running" not in k and "num_batches" not in k]
    assert len(learned) > 50
    for k in learned:
        assert torch.equal(src["model"][k], ft["model"][k]), k


def test_shipped_weights_load_and_stay_small():
    from detector.infer import DEFAULT_WEIGHTS
    assert DEFAULT_WEIGHTS.stat().st_size < 20 * 2 ** 20
    det = Detector.load()
    assert det.classes == ("Car", "Pedestrian", "Cyclist")
    assert det.input_size[0] % 32 == 0 and det.input_size[1] % 32 == 0
    img = np.full((375, 1242, 3), 114, np.uint8)
    assert det.detect([img], conf_threshold=0.5)[0].shape[1] == 6


def test_mirrored_inference_reads_an_image_and_its_mirror_alike(street):
    """With `mirror`, both passes' candidates share one NMS, so a mirrored street frame gets the
    mirror images of the same boxes with the same scores (1242 px letterboxes to the full input
    width at every scale of the shipped read: no padding breaks the symmetry); a single pass is
    not symmetric."""
    img = street

    def boxes(det, flip):
        d = det.detect([img[:, ::-1].copy() if flip else img], conf_threshold=0.05)[0]
        if flip:
            d[:, [0, 2]] = 1242 - d[:, [2, 0]]
        return d

    def paired(a, b):
        """Each box of a, its best match in b (same class): IoU and score difference."""
        iou = iou_2d(a[:, :4], b[:, :4]) * (a[:, None, 5] == b[None, :, 5])
        j = iou.argmax(1)
        return iou[np.arange(len(a)), j], np.abs(a[:, 4] - b[j, 4])

    a, b = boxes(Detector.load(), False), boxes(Detector.load(), True)
    assert len(a) >= 10 and len(a) == len(b)
    iou, dscore = paired(a, b)
    assert iou.min() > 0.99 and dscore.max() < 1e-3  # rounding: the letterbox resizes uint8 pixels
    single = Detector.load(mirror=False)
    iou, dscore = paired(boxes(single, False), boxes(single, True))
    assert iou.min() < 0.9 or dscore.max() > 1e-2
