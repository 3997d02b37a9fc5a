"""Real KITTI frames in CI: every lifting method on the 11 real dev frames (oracle 2D boxes), scored
by the official evaluation, against floors measured there with a margin of a few cars
(`results/lifter_real.md` has the figures and how they were made).

The frames live beside the repository (`../shared/kitti_real_dev`, never copied into it). With 14
moderate cars the devkit's AP|R40 cannot exceed 32.5 (slot t of the precision curve is the t-th
true positive), so the floors on AP sit a couple of cars under what the lifters reach, and the
per-object floors count cars placed within an IoU.
"""

from pathlib import Path

import numpy as np
import pytest

from kitti.dataset import KittiDataset
from kitti.eval import evaluate_folders
from kitti.iou import iou_3d
from kitti.labels import read_label
from lifter.methods import METHODS
from lifter.pipeline import lift_dataset

REAL = Path(__file__).resolve().parents[3] / "shared" / "kitti_real_dev"
pytestmark = pytest.mark.skipif(not (REAL / "training" / "label_2").is_dir(),
                                reason=f"the real KITTI dev frames are not at {REAL}")

# (method, priors): floors on Car 3D AP|R40 moderate at IoU 0.7 and 0.5, and on the untruncated
# cars (truncation < 0.3; 25 of them) placed within 3D IoU 0.5 and 0.7, each a few cars under
# what the shipped code and networks measure there (`benchmarks/lifter_real.py --data
# ../shared/kitti_real_dev --objects`; results/lifter_real.md): fit with true / network priors
# 31.3 / 32.2 at both IoUs, mono with true priors 11.7 / 19.1 and with the network's 2.2 / 15.2
# (no floor at 0.7: hardly a moderate car reaches it, and the network's orientation on the 41 real
# crops moves more between two fine-tunes than a floor could hold; lifter/weights/README.md).
FLOORS = {
    ("fit", "truth"): (25.0, 27.5, 20, 19),
    ("fit", "net"): (27.5, 27.5, 20, 20),
    ("mono", "truth"): (6.5, 14.0, 11, 7),
    ("mono", "net"): (0.0, 10.0, 10, 2),
    ("frustum", "truth"): (0.0, 5.0, 7, 2),
    ("roadside", "truth"): (0.0, 5.0, 7, 2),
}


@pytest.fixture(scope="module")
def lifted(tmp_path_factory):
    out = tmp_path_factory.mktemp("real")
    for method, priors in FLOORS:
        lift_dataset(REAL, None, method, out / f"{method}_{priors}", None, priors=priors,
                     progress=False)
    return out


def _untruncated_ious(pred_dir: Path) -> np.ndarray:
    """3D IoU of each untruncated labelled car with the box lifted from its 2D box."""
    ds = KittiDataset(REAL)
    ious = []
    for fid in ds.ids():
        preds = read_label(pred_dir / f"{fid}.txt")
        for o in ds.labels(fid):
            if o.type == "Car" and o.truncated < 0.3:
                match = [p for p in preds if np.allclose(p.bbox, o.bbox, atol=1e-3)]
                ious.append(iou_3d(o.box7, match[0].box7)[0, 0] if match else 0.0)
    return np.array(ious)


def test_the_dev_frames_are_real_kitti():
    ds = KittiDataset(REAL)
    assert len(ds.ids()) == 11 and not (REAL / "training" / "planes").exists()
    assert set(FLOORS) >= {(m, "truth") for m in METHODS}  # every method is checked


@pytest.mark.parametrize("method,priors", list(FLOORS))
def test_lifting_real_frames_holds_its_floor(lifted, method, priors):
    pred = lifted / f"{method}_{priors}"
    ids = KittiDataset(REAL).ids()
    assert sorted(p.stem for p in pred.glob("*.txt")) == ids  # every frame written
    r = evaluate_folders(REAL / "training" / "label_2", pred, classes=("Car",), progress=False)
    assert r.n_gt["Car"][1] == 14
    ap7, ap5 = r.ap["Car"]["3d"]["R40"][1], r.ap_loose["Car"]["3d"]["R40"][1]
    ious = _untruncated_ious(pred)
    floor7, floor5, n5, n7 = FLOORS[(method, priors)]
    assert len(ious) == 25
    assert ap7 >= floor7 and ap5 >= floor5, (ap7, ap5)
    assert (ious >= 0.5).sum() >= n5 and (ious >= 0.7).sum() >= n7, np.round(ious, 2)


# The whole chain on the real frames: the shipped detector's boxes, lifted by `fit`, evaluated. The
# shipped file read at the input size alone (as seen and mirrored) overlaps 25 of the 42 labelled
# Cars and Vans at 2D IoU 0.5 by a Car detection of score 0.3, with 3.4 false positives a frame,
# and lifts 11 Cars within 3D IoU 0.5; at its default six views it reads 1.8 false positives a
# frame (`benchmarks/detector_real.py`, results/detector.md). Floors a few cars under, the lifted
# one a car under. They guard the shipped file; they choose no weights: fine-tunes of one recipe
# read 5.3-7.3 false positives a frame, a spread the eleven frames cannot rank.
DETECTED_AT_05, FALSE_POSITIVES_A_FRAME, LIFTED_AT_05 = 17, 6.0, 3
# The project's real target, Car 2D AP|R40 moderate >= 40, read on the measured recall: the devkit's
# own figure cannot exceed 32.5 on these frames' 14 moderate Cars (kitti.eval.ap). The shipped read
# scores 78.0 there. The number is the target's, not one read off these frames.
REAL_CAR_2D_TARGET = 40.0


def test_detect_lift_evaluate_on_real_frames(tmp_path):
    from detector.augment import pairwise_iou
    from detector.infer import detect_dataset

    ds = KittiDataset(REAL)
    pred = detect_dataset(REAL, tmp_path / "det", split=None, progress=False)
    found, false_pos = 0, []
    for fid in ds.ids():
        dets = [o.bbox for o in pred[fid] if o.type == "Car" and o.score >= 0.3]
        dets = np.array(dets).reshape(-1, 4)
        labels = ds.labels(fid)
        every = np.array([o.bbox for o in labels]).reshape(-1, 4)
        cars = np.array([o.bbox for o in labels if o.type in ("Car", "Van")]).reshape(-1, 4)
        if len(dets):
            found += int((pairwise_iou(cars, dets).max(axis=1, initial=0.0) >= 0.5).sum())
            false_pos.append(int((pairwise_iou(dets, every).max(axis=1, initial=0.0) < 0.5).sum()))
        else:
            false_pos.append(0)
    assert found >= DETECTED_AT_05, found
    assert np.mean(false_pos) <= FALSE_POSITIVES_A_FRAME, false_pos
    det = evaluate_folders(REAL / "training" / "label_2", tmp_path / "det", classes=("Car",),
                           progress=False)
    assert det.ap["Car"]["2d"]["R40"][1] <= 32.5 < REAL_CAR_2D_TARGET  # why the measured recall
    assert det.measured["Car"]["strict"]["2d"][1] >= REAL_CAR_2D_TARGET, det.measured["Car"]

    lift_dataset(REAL, tmp_path / "det", "fit", tmp_path / "fit", None, progress=False)
    r = evaluate_folders(REAL / "training" / "label_2", tmp_path / "fit", classes=("Car",),
                         progress=False)
    assert r.n_gt["Car"][1] == 14 and 0.0 <= r.ap_loose["Car"]["3d"]["R40"][1] <= 32.5
    placed = 0
    for fid in ds.ids():
        lifted = [p for p in read_label(tmp_path / "fit" / f"{fid}.txt") if p.score >= 0.3]
        for o in ds.labels(fid):
            if o.type == "Car" and lifted:
                placed += max(iou_3d(o.box7, p.box7)[0, 0] for p in lifted) >= 0.5
    assert placed >= LIFTED_AT_05
