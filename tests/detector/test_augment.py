"""Augmentation keeps boxes on their objects; Mixup variants follow 004; samples are seeded."""
import numpy as np
import pytest

from detector.augment import AugmentConfig, Augmenter, clip_boxes, mix
from detector.data import CLASSES, DetectionData, labels_to_arrays
from tests.detector.toydata import TOY_CLASSES, toy_object, write_toy_dataset


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    root = write_toy_dataset(tmp_path_factory.mktemp("toy") / "ds", 6, seed=11, size=(256, 96))
    return DetectionData(str(root), "train", (256, 96), progress=False)


def test_several_roots_give_their_frames_in_order(toy, tmp_path):
    other = write_toy_dataset(tmp_path / "other", 4, seed=12, size=(256, 96))
    one = DetectionData(str(other), "train", (256, 96), progress=False)
    both = DetectionData([toy.roots[0], str(other)], "train", (256, 96), progress=False)
    assert len(both) == len(toy) + len(one) and len(toy) > 0 and len(one) > 0
    for a, b in zip(both.samples, toy.samples + one.samples):
        assert np.array_equal(a.image, b.image) and np.array_equal(a.boxes, b.boxes)
        assert np.array_equal(a.classes, b.classes)


def _colour_inside(img, box):
    """Median colour of the inner half of a box."""
    x1, y1, x2, y2 = box
    cx, cy, w, h = (x1 + x2) / 2, (y1 + y2) / 2, x2 - x1, y2 - y1
    patch = img[int(np.ceil(cy - h / 4)):int(cy + h / 4) + 1, int(np.ceil(cx - w / 4)):int(cx + w / 4) + 1]
    return np.median(patch.reshape(-1, 3), axis=0)


def test_labels_map_van_to_car_and_skip_others():
    objs = [toy_object(t, [0, 0, 10, 10]) for t in ("Car", "Van", "Truck", "Pedestrian", "Person_sitting",
                                                    "Cyclist", "DontCare")]
    boxes, classes = labels_to_arrays(objs)
    assert classes.tolist() == [0, 0, 1, 2]
    assert boxes.shape == (4, 4)
    assert CLASSES == ("Car", "Pedestrian", "Cyclist")


@pytest.mark.parametrize("epoch", range(4))
def test_mosaic_zoom_flip_keep_boxes_on_their_objects(toy, epoch):
    cfg = AugmentConfig(mosaic=1.0, scale=0.4, translate=0.1, fliplr=0.5, hsv=(0, 0, 0), photometric=False)
    aug = Augmenter(toy, cfg, seed=3)
    n_boxes = 0
    for i in range(len(toy)):
        s = aug(i, epoch)
        assert s.image.shape == (96, 256, 3) and s.image.dtype == np.uint8
        assert (s.boxes[:, :2] >= 0).all() and (s.boxes[:, 2] <= 256).all() and (s.boxes[:, 3] <= 96).all()
        for box, c in zip(s.boxes, s.classes):
            want = TOY_CLASSES[CLASSES[c]][0]
            if min(box[2] - box[0], box[3] - box[1]) >= 6:
                np.testing.assert_allclose(_colour_inside(s.image, box), want, atol=25)
                n_boxes += 1
    assert n_boxes > 5


def test_samples_are_seeded(toy):
    cfg = AugmentConfig(mixup="mixup")
    a, b = Augmenter(toy, cfg, seed=5), Augmenter(toy, cfg, seed=5)
    for i in range(3):
        s1, s2 = a(i, 2), b(i, 2)
        assert np.array_equal(s1.image, s2.image) and np.array_equal(s1.boxes, s2.boxes)
    assert not np.array_equal(a(0, 2).image, a(0, 3).image)


def test_off_is_the_plain_letterbox(toy):
    s = Augmenter(toy, AugmentConfig.off(), seed=0)(2, 0)
    assert np.array_equal(s.image, toy.samples[2].image)
    np.testing.assert_allclose(s.boxes, toy.samples[2].boxes)


def _sample(boxes, value):
    from detector.data import Sample
    return Sample(np.full((20, 40, 3), value, np.uint8), np.array(boxes, float).reshape(-1, 4),
                  np.zeros(len(boxes), np.int64))


def test_mixup_blends_with_beta_lambda_and_keeps_both_box_sets():
    a, b = _sample([[0, 0, 10, 10]], 200), _sample([[5, 0, 15, 10]], 100)
    rng = np.random.default_rng(0)
    lam = np.random.default_rng(0).beta(8, 8)
    m = mix(a, b, AugmentConfig(mixup="mixup"), rng)
    assert m.image[0, 0, 0] == round(200 * lam + 100 * (1 - lam))
    assert m.boxes.tolist() == [[0, 0, 10, 10], [5, 0, 15, 10]]


def test_thresholded_mixup_needs_low_overlap():
    cfg = AugmentConfig(mixup="thresholded", mixup_iou=0.4)
    a = _sample([[0, 0, 10, 10]], 200)
    overlapping = _sample([[2, 0, 12, 10]], 100)       # IoU 8/12 = 0.67 >= 0.4: not mixed
    apart = _sample([[6, 0, 16, 10]], 100)             # IoU 4/16 = 0.25 < 0.4: mixed
    rng = np.random.default_rng(1)
    assert mix(a, overlapping, cfg, rng) is a
    m = mix(a, apart, cfg, rng)
    assert len(m.boxes) == 2 and m.image[0, 0, 0] != 200


def test_clip_boxes_drops_slivers():
    boxes = np.array([[-10, 0, 10, 10], [-10, 0, 1, 10], [5, 5, 6, 30]], float)
    kept, mask = clip_boxes(boxes, (0, 0, 100, 20), min_size=2, min_area_kept=0.2)
    assert mask.tolist() == [True, False, False]
    assert kept.tolist() == [[0, 0, 10, 10]]


def test_bad_config_is_named():
    with pytest.raises(ValueError, match="mixup"):
        AugmentConfig(mixup="cutmix")
    with pytest.raises(ValueError, match="mosaic"):
        AugmentConfig(mosaic=1.5)
