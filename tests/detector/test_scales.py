"""Reads at other input scales (`Detector.scales`): each a view of the one NMS, its boxes moved
into the first read's input pixels through the source image."""

import numpy as np
import pytest
import torch

from detector.boxes import Letterbox, box_iou_matrix, cxcywh_to_xyxy
from detector.infer import DEFAULT_SCALES, DEFAULT_WEIGHTS, Detector, _moved
from detector.nms import postprocess


def xyxy_to_cxcywh(b: np.ndarray) -> np.ndarray:
    return np.c_[(b[:, :2] + b[:, 2:]) / 2, b[:, 2:] - b[:, :2]]


@pytest.mark.parametrize("src", [(1242, 375), (1224, 370), (1241, 376)])
def test_moved_boxes_land_where_the_other_letterbox_puts_them(src):
    """A source-image box forwarded through a scaled letterbox and moved is the box forwarded
    through the full-size one (KITTI's image sizes; 0.67 of 1408 x 448 is 928 x 288)."""
    full, small = Letterbox.fit(*src, 1408, 448), Letterbox.fit(*src, 928, 288)
    rng = np.random.default_rng(0)
    xy = rng.uniform([0, 0], src, size=(50, 2))
    b = np.c_[xy, xy + rng.uniform(2, 300, size=(50, 2))]
    raw = torch.zeros(1, 50, 8, dtype=torch.float64)
    raw[0, :, :4] = torch.from_numpy(xyxy_to_cxcywh(small.forward(b)))
    raw[0, :, 4:] = torch.from_numpy(rng.uniform(size=(50, 4)))
    out = _moved(raw, [small], [full])
    np.testing.assert_allclose(cxcywh_to_xyxy(out[0, :, :4]).numpy(), full.forward(b), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(out[..., 4:], raw[..., 4:])


def test_views_given_one_by_one_read_as_equal_blocks():
    rng = np.random.default_rng(1)
    p = torch.from_numpy(rng.uniform(size=(2, 600, 8))).float()
    p[..., :2] *= 300
    p[..., 2:4] = p[..., 2:4] * 60 + 5
    a = postprocess(p, 0.05, 0.6, views=3)
    b = postprocess(p, 0.05, 0.6, views=torch.arange(600) // 200)
    for x, y in zip(a, b):
        torch.testing.assert_close(x, y, rtol=0, atol=0)


def test_a_second_read_at_full_scale_reads_as_the_first(street):
    """Scale 1 twice: four views that are two identical pairs, so the mean over them is the mean
    over the pair, box for box."""
    once, twice = Detector.load(scales=(1.0,)), Detector.load(scales=(1.0, 1.0))
    assert twice.views == 4 and twice.scaled_size(1.0) == once.input_size
    a, b = once.detect([street], 0.05)[0], twice.detect([street], 0.05)[0]
    assert len(a) >= 10
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-5)


def test_a_smaller_read_alone_lands_on_the_same_cars(street):
    """The read at 0.67 by itself, mirrored and moved into the full input's pixels as `detect`
    moves it: every Car 40 px or taller that the read at 1 finds above 0.5 on the quickstart
    street has a box of the small read within IoU 0.7."""
    det = Detector.load(scales=(1.0,))
    full = det.detect([street], 0.05)[0]
    size = det.scaled_size(0.67)
    assert size == (928, 288)
    lb1 = Letterbox.fit(street.shape[1], street.shape[0], *det.input_size)
    lb = Letterbox.fit(street.shape[1], street.shape[0], *size)
    x = torch.from_numpy(lb.apply(street)[None]).permute(0, 3, 1, 2).float().div_(255)
    with torch.no_grad():
        raw = _moved(det._raw(x, size[0]), [lb], [lb1])
    small = postprocess(raw, 0.05, 0.6, views=2)[0].double().numpy()
    small[:, :4] = lb1.inverse(small[:, :4])
    cars = full[(full[:, 5] == 0) & (full[:, 4] > 0.5) & (full[:, 3] - full[:, 1] >= 40)]
    assert len(cars) >= 2
    iou = box_iou_matrix(torch.from_numpy(cars[:, :4]), torch.from_numpy(small[small[:, 5] == 0, :4]))
    assert bool((iou.max(1).values > 0.7).all()), iou.max(1).values


@pytest.mark.parametrize("scales", [(), (0.83,), (1.0, 0.0), (1.0, -0.5)])
def test_bad_scales_are_refused(scales):
    with pytest.raises(ValueError, match="scales"):
        Detector.load(scales=scales)


def test_the_shipped_weights_are_read_at_their_judged_scales(tmp_path):
    """The read judged for the shipped network is its default; another file (the same bytes
    elsewhere, as a user's own run) is read at 1 unless asked."""
    assert Detector.load().scales == DEFAULT_SCALES == (1.0, 1.25, 0.83)
    copy = tmp_path / "mine.pt"
    copy.write_bytes(DEFAULT_WEIGHTS.read_bytes())
    assert Detector.load(copy).scales == (1.0,)
    assert Detector.load(copy, scales=DEFAULT_SCALES).views == 6
    assert not Detector.load().fuse_boxes  # judged on generated frames, not adopted


def test_fused_boxes_move_only_the_sides(street):
    """The six views' boxes fused (`fuse_boxes`): the same boxes kept, with the same scores and
    classes, in the same order; their sides move, each box staying on its car: above the NMS's IoU
    0.6 with the best view's box, as each box it is the mean of is."""
    det = Detector.load()
    cand = det.candidates([street])
    det.fuse_boxes = False
    best = det.finish(*cand, 0.05)[0]
    det.fuse_boxes = True
    fused = det.finish(*cand, 0.05)[0]
    assert len(best) >= 10 and fused.shape == best.shape
    np.testing.assert_array_equal(fused[:, 4:], best[:, 4:])
    assert np.abs(fused[:, :4] - best[:, :4]).max() > 0.5
    iou = box_iou_matrix(torch.from_numpy(fused[:, :4]), torch.from_numpy(best[:, :4])).diagonal()
    assert bool((iou > 0.6).all()), iou
