"""`testbed lift` end to end on a small KITTI-layout dataset: every method, oracle and detection
boxes, complete result lines for every frame of the split, clear errors on bad input."""

import shutil
from collections import OrderedDict

import imageio.v3 as imageio
import numpy as np
import pytest
from click.testing import CliRunner

import lifter.fit
import lifter.mono
import lifter.pipeline
import lifter.predictor
import lifter.types
from kitti.iou import iou_3d
from kitti.labels import read_label, write_label
from lifter.pipeline import lift_dataset
from testbed.cli import cli
from tests.lifter.synth import make_frame, write_dataset


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("lift")
    frames = [make_frame([[-3.0, 1.65, 12.0, 1.5, 1.7, 4.2, 0.2], [4.0, 1.65, 22.0, 1.6, 1.8, 4.5, -1.3]]),
              make_frame([[1.0, 1.65, 15.0, 1.5, 1.7, 4.0, 2.5]]),
              make_frame([])]
    write_dataset(root, frames, split="val")
    return root


@pytest.mark.parametrize("method,min_iou", [("fit", 0.75), ("mono", 0.99), ("roadside", 0.99),
                                            ("frustum", 0.3)])
def test_every_method_writes_every_frame(dataset, tmp_path, method, min_iou, monkeypatch):
    # the synthetic objects are plain boxes: they touch the road at their corners, not on tyres
    monkeypatch.setattr("lifter.mono.CONTACT", {})
    n = lift_dataset(dataset, None, method, tmp_path, "val", priors="truth", progress=False)
    assert n == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["000000.txt", "000001.txt", "000002.txt"]
    assert (tmp_path / "000002.txt").read_text() == ""
    for fid in ("000000", "000001"):
        gt = read_label(dataset / "training" / "label_2" / f"{fid}.txt")
        dt = read_label(tmp_path / f"{fid}.txt")
        assert all(len(o.to_line().split()) == 16 for o in dt)
        ious = iou_3d(np.array([o.box7 for o in gt]), np.array([o.box7 for o in dt]))
        assert np.diag(ious).min() > min_iou, ious


def test_cli_with_detection_files_and_a_trained_checkpoint(dataset, tmp_path):
    det = tmp_path / "det"
    for fid in ("000000", "000001", "000002"):
        objs = read_label(dataset / "training" / "label_2" / f"{fid}.txt")
        for k, o in enumerate(objs):  # 2D-only detections: alpha -10, 3D placeholders
            o.alpha, o.h, o.w, o.l, o.rotation_y, o.score = -10.0, -1.0, -1.0, -1.0, -10.0, 0.9 - 0.1 * k
            o.location = np.array([-1000.0, -1000.0, -1000.0])
        write_label(det / f"{fid}.txt", objs)
    runner = CliRunner()
    r = runner.invoke(cli, ["train-lifter", "--data", str(dataset), "--out", str(tmp_path / "run"),
                            "--epochs", "1", "--crop-size", "32", "--width", "0.25", "--threads", "1"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(cli, ["lift", "--data", str(dataset), "--boxes", str(det), "--method", "fit",
                            "--split", "val", "--out", str(tmp_path / "out"),
                            "--weights", str(tmp_path / "run" / "best.pt")])
    assert r.exit_code == 0, r.output
    dt = read_label(tmp_path / "out" / "000000.txt")
    assert len(dt) == 2 and all(o.h > 0 and o.location[2] > 5 for o in dt)
    # one 3D box per detection, in the detection file's order, scored by the detection's score
    # times the fit's quality (at most 1)
    src = read_label(det / "000000.txt")
    for o, d in zip(dt, src):
        np.testing.assert_allclose(o.bbox, d.bbox, atol=1e-2)
        assert 0 < o.score <= d.score + 1e-6


def test_lift_passes_mirror_to_the_network(dataset, tmp_path, monkeypatch):
    """`testbed lift` reads crops mirrored too unless --no-mirror (the network's outputs:
    tests/lifter/test_network.py)."""
    seen = []

    class Recording(lifter.predictor.Predictor):
        def __init__(self, *a, mirror=True, **kw):
            seen.append(mirror)
            super().__init__(*a, mirror=mirror, **kw)

    monkeypatch.setattr(lifter.predictor, "Predictor", Recording)
    for flags in ([], ["--no-mirror"], ["--mirror"]):
        r = CliRunner().invoke(cli, ["lift", "--data", str(dataset), "--boxes", "gt", "--method", "fit",
                                     "--split", "val", "--out", str(tmp_path / "o"), *flags])
        assert r.exit_code == 0, r.output
    assert seen == [True, False, True]


def test_a_frame_s_priors_are_computed_once_for_every_lift_of_it(dataset, tmp_path, monkeypatch):
    """A sweep lifts the same frames and boxes once per scan and method: the network runs once
    per frame, the files are those of lifts without the cache, and a changed image is read anew."""
    calls = []
    run = lifter.predictor.Predictor.__call__
    monkeypatch.setattr(lifter.predictor.Predictor, "__call__",
                        lambda self, image, boxes: calls.append(len(boxes)) or run(self, image, boxes))
    monkeypatch.setattr(lifter.mono, "CONTACT", {})
    cache = OrderedDict()
    monkeypatch.setattr(lifter.pipeline, "_priors", cache)
    for method, out in (("fit", "a"), ("fit", "b"), ("frustum", "c"), ("mono", "d")):
        lift_dataset(dataset, None, method, tmp_path / out, "val", progress=False)
    assert calls == [2, 1]  # frames 000000 and 000001; 000002 has no box
    monkeypatch.setattr(lifter.pipeline, "_priors", OrderedDict())
    monkeypatch.setattr(lifter.pipeline, "PRIOR_CACHE", 0)
    for method, out in (("fit", "a0"), ("mono", "d0")):
        lift_dataset(dataset, None, method, tmp_path / out, "val", progress=False)
    assert calls == [2, 1, 2, 1, 2, 1]
    for a, b in (("a", "b"), ("a", "a0"), ("d", "d0")):
        for fid in ("000000", "000001"):
            assert (tmp_path / a / f"{fid}.txt").read_bytes() == (tmp_path / b / f"{fid}.txt").read_bytes()
    monkeypatch.setattr(lifter.pipeline, "_priors", cache)
    monkeypatch.setattr(lifter.pipeline, "PRIOR_CACHE", 4096)
    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    image = copy / "training" / "image_2" / "000001.png"
    pixels = imageio.imread(image)
    pixels[0, 0] ^= 1
    imageio.imwrite(image, pixels)
    lift_dataset(copy, None, "fit", tmp_path / "e", "val", progress=False)
    assert calls == [2, 1, 2, 1, 2, 1, 1]  # the first frame's image bytes are the dataset's



def test_side_sd_sets_the_sigma_fit_weighs_detected_sides_by(dataset, tmp_path, monkeypatch):
    """Detected boxes reach `fit` with the shipped detector's side errors for their class (a
    Student-t), or the --side-sd given (Student-t with --side-dof, else Gaussian; 0: as a
    label's), each with a label's 2 px in quadrature; labels with a label's own. --side-sd or
    --side-dof without detection files, or --side-dof alone, is refused."""
    det = tmp_path / "det"
    objs = read_label(dataset / "training" / "label_2" / "000000.txt")
    for o in objs:
        o.score = 0.9
    write_label(det / "000000.txt", objs)
    seen = []
    lift = lifter.fit.lift_fit
    monkeypatch.setattr(lifter.fit, "lift_fit",
                        lambda boxes, *a, **kw: seen.append([(b.side_sigma, b.side_dof) for b in boxes])
                        or lift(boxes, *a, **kw))
    base = ["lift", "--data", str(dataset), "--method", "fit", "--split", "val", "--priors", "truth"]
    for flags in (["--boxes", str(det)], ["--boxes", str(det), "--side-sd", "0"],
                  ["--boxes", str(det), "--side-sd", "1.5"],
                  ["--boxes", str(det), "--side-sd", "1.5", "--side-dof", "2"], ["--boxes", "gt"]):
        r = CliRunner().invoke(cli, [*base, *flags, "--out", str(tmp_path / "o")])
        assert r.exit_code == 0, r.output
    label, inf = lifter.types.LABEL_SIDE_SIGMA_PX, float("inf")
    scale, dof = lifter.pipeline.SHIPPED_SIDE_ERRORS["Car"]
    assert [s for s, _ in seen[0]] == pytest.approx([np.hypot(label, scale)] * 2)
    assert [d for _, d in seen[0]] == [dof] * 2
    assert seen[1] == [(label, inf)] * 2  # hypot(2, 1.5) = 2.5 below
    assert [s for s, _ in seen[2]] == pytest.approx([2.5] * 2) and [d for _, d in seen[2]] == [inf] * 2
    assert [s for s, _ in seen[3]] == pytest.approx([2.5] * 2) and [d for _, d in seen[3]] == [2.0] * 2
    assert seen[4] == [(label, inf)] * 2 and seen[5] == [(label, inf)]  # frames 000000 and 000001
    for flags in (["--boxes", "gt", "--side-sd", "3"], ["--boxes", str(det), "--side-dof", "2"]):
        r = CliRunner().invoke(cli, [*base, *flags, "--out", str(tmp_path / "x")])
        assert r.exit_code != 0 and "--side-" in r.output


def test_missing_detection_file_is_an_empty_frame(dataset, tmp_path):
    # (this pinned the opposite before: a frame without a detection file was an error; a detector
    # may write only the frames where it found something, and the evaluation reads a missing
    # result file as an empty frame, so the lifter does too)
    det = tmp_path / "det"
    objs = read_label(dataset / "training" / "label_2" / "000000.txt")
    for o in objs:
        o.score = 0.9
    write_label(det / "000000.txt", objs)
    r = CliRunner().invoke(cli, ["lift", "--data", str(dataset), "--boxes", str(det), "--method", "mono",
                                 "--split", "val", "--out", str(tmp_path / "o"), "--priors", "truth"])
    assert r.exit_code == 0, r.output
    assert len(read_label(tmp_path / "o" / "000000.txt")) == 2
    assert (tmp_path / "o" / "000001.txt").read_text() == ""


def test_unreadable_frame_is_named_and_earlier_results_stay(dataset, tmp_path):
    det = tmp_path / "det"
    for fid in ("000000", "000001"):
        objs = read_label(dataset / "training" / "label_2" / f"{fid}.txt")
        for o in objs:
            o.score = 0.9
        write_label(det / f"{fid}.txt", objs)
    (det / "000001.txt").write_text("Car 0 0 0 10 20 30 40 1 1 1 0 0 0 0 high\n")
    out = tmp_path / "o"
    r = CliRunner().invoke(cli, ["lift", "--data", str(dataset), "--boxes", str(det), "--method", "mono",
                                 "--split", "val", "--out", str(out), "--priors", "truth"])
    assert r.exit_code != 0
    assert "000001.txt" in r.output and "score" in r.output, r.output
    assert len(read_label(out / "000000.txt")) == 2  # the frame before it is complete
    assert not (out / "000001.txt").exists()
