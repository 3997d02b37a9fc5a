"""Letterbox mapping, IoU-family losses, NMS and k-means anchors against exact references."""
import math

import numpy as np
import pytest
import torch

from detector.anchors import best_possible_recall, kmeans_anchors, wh_iou
from detector.boxes import Letterbox, aligned_iou, box_iou_matrix, input_size_for
from detector.nms import batched_nms, nms, postprocess


# ---------------------------------------------------------------- letterbox
@pytest.mark.parametrize("src,dst", [((1242, 375), (640, 224)), ((1224, 370), (640, 224)),
                                     ((1242, 375), (1248, 384)), ((300, 500), (320, 320)),
                                     ((640, 224), (640, 224))])
def test_letterbox_round_trips(src, dst):
    lb = Letterbox.fit(*src, *dst)
    assert lb.new_w <= dst[0] and lb.new_h <= dst[1]
    assert lb.new_w == dst[0] or lb.new_h == dst[1]  # fills one side
    rng = np.random.default_rng(0)
    b = np.sort(rng.uniform(0, 1, (50, 4)) * np.array(src * 2), axis=0)
    b = np.column_stack((np.minimum(b[:, 0], b[:, 2]), np.minimum(b[:, 1], b[:, 3]),
                         np.maximum(b[:, 0], b[:, 2]), np.maximum(b[:, 1], b[:, 3])))
    back = lb.inverse(lb.forward(b), clip=False)
    np.testing.assert_allclose(back, b, rtol=0, atol=1e-9)


def test_letterbox_scales_are_the_real_resize_factors():
    lb = Letterbox.fit(1242, 375, 640, 224)
    assert (lb.new_w, lb.new_h) == (640, 193)
    assert (lb.pad_x, lb.pad_y) == (0, 15)
    assert lb.scale == (640 / 1242, 193 / 375)
    np.testing.assert_allclose(lb.forward([[0, 0, 1242, 375]]), [[0, 15, 640, 208]], atol=1e-12)
    # inverse clips like KITTI labels: to the last pixel
    np.testing.assert_allclose(lb.inverse([[-5, 0, 700, 300]]), [[0, 0, 1241, 374]], atol=1e-12)


def test_letterbox_image_lands_where_the_boxes_say():
    """A white rectangle with edges on even pixels, halved by the resize, must appear at the
    forward-mapped box (area resampling is exact for a factor of 2)."""
    img = np.zeros((100, 200, 3), np.uint8)
    img[20:60, 40:120] = 255
    lb = Letterbox.fit(200, 100, 128, 50)  # scale 0.5 -> 100x50 centred in 128x50
    out = lb.apply(img)
    assert (lb.new_w, lb.new_h, lb.pad_x, lb.pad_y) == (100, 50, 14, 0)
    x1, y1, x2, y2 = lb.forward([[40, 20, 120, 60]])[0]
    ys, xs = np.nonzero(out[..., 0] == 255)
    assert (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1) == (x1, y1, x2, y2)
    assert (out[:, :lb.pad_x] == 114).all() and (out[:, lb.pad_x + lb.new_w:] == 114).all()


def test_input_size_for_kitti():
    assert input_size_for(1242, 375, 640) == (640, 224)
    assert input_size_for(1242, 375, 1248) == (1248, 384)


# ---------------------------------------------------------------- IoU family
def test_iou_variants_hand_computed():
    a = torch.tensor([[0.0, 0.0, 2.0, 2.0]])
    b = torch.tensor([[1.0, 1.0, 3.0, 3.0]])
    iou = 1 / 7
    assert aligned_iou(a, b, "iou").item() == pytest.approx(iou, abs=1e-6)
    # enclosing box 3x3 = 9, union 7
    assert aligned_iou(a, b, "giou").item() == pytest.approx(iou - 2 / 9, abs=1e-6)
    # centres (1,1) and (2,2): distance^2 2; enclosing diagonal^2 18
    assert aligned_iou(a, b, "diou").item() == pytest.approx(iou - 2 / 18, abs=1e-6)
    # same aspect ratio: CIoU == DIoU
    assert aligned_iou(a, b, "ciou").item() == pytest.approx(iou - 2 / 18, abs=1e-6)
    c = torch.tensor([[0.0, 0.0, 4.0, 1.0]])
    d = torch.tensor([[0.0, 0.0, 1.0, 4.0]])
    v = 4 / math.pi ** 2 * (math.atan(1 / 4) - math.atan(4)) ** 2
    iou_cd = 1 / 7
    alpha = v / (v - iou_cd + 1)
    rho2_over_c2 = (1.5 ** 2 * 2) / 32
    assert aligned_iou(c, d, "ciou").item() == pytest.approx(iou_cd - rho2_over_c2 - alpha * v, abs=1e-6)


def test_identical_boxes_give_one_for_every_variant():
    a = torch.tensor([[10.0, 5.0, 30.0, 50.0]])
    for kind in ("iou", "giou", "diou", "ciou"):
        assert aligned_iou(a, a.clone(), kind).item() == pytest.approx(1.0, abs=1e-6)


# ---------------------------------------------------------------- NMS
def _brute_force_nms(boxes, scores, thr):
    order = sorted(range(len(scores)), key=lambda i: (-scores[i], i))
    keep = []
    for i in order:
        ok = True
        for j in keep:
            x1, y1 = max(boxes[i][0], boxes[j][0]), max(boxes[i][1], boxes[j][1])
            x2, y2 = min(boxes[i][2], boxes[j][2]), min(boxes[i][3], boxes[j][3])
            inter = max(0.0, x2 - x1) * max(0.0, y2 - y1)
            ai = (boxes[i][2] - boxes[i][0]) * (boxes[i][3] - boxes[i][1])
            aj = (boxes[j][2] - boxes[j][0]) * (boxes[j][3] - boxes[j][1])
            if inter / (ai + aj - inter) > thr:
                ok = False
                break
        if ok:
            keep.append(i)
    return keep


@pytest.mark.parametrize("seed", range(6))
def test_nms_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    n = 120
    xy = rng.uniform(0, 100, (n, 2))
    wh = rng.uniform(5, 40, (n, 2))
    boxes = np.column_stack((xy, xy + wh))
    scores = rng.uniform(0, 1, n)
    scores[:10] = scores[10:20]  # ties: lower index first
    for thr in (0.3, 0.5, 0.7):
        got = nms(torch.tensor(boxes), torch.tensor(scores), thr).tolist()
        assert got == _brute_force_nms(boxes.tolist(), scores.tolist(), thr)


def test_batched_nms_never_suppresses_across_classes():
    boxes = torch.tensor([[0.0, 0, 10, 10], [0.5, 0, 10.5, 10], [0, 0, 10, 10]])
    scores = torch.tensor([0.9, 0.8, 0.7])
    classes = torch.tensor([0, 0, 1])
    assert batched_nms(boxes, scores, classes, 0.5).tolist() == [0, 2]


def test_postprocess_scores_and_boxes():
    # one image, two predictions (cx, cy, w, h, obj, 3 class probs)
    pred = torch.tensor([[[50.0, 40, 20, 10, 0.9, 0.1, 0.8, 0.1],
                          [51.0, 40, 20, 10, 0.5, 0.1, 0.8, 0.1]]])
    out = postprocess(pred, conf_threshold=0.3, iou_threshold=0.5)[0]
    assert out.shape == (1, 6)
    np.testing.assert_allclose(out[0].numpy(), [40, 35, 60, 45, 0.72, 1], atol=1e-6)


def test_postprocess_over_two_views_scores_each_box_by_the_views_mean():
    # view 0: a car at x 40-60 (0.8) and a car at x 200-220 (0.9); view 1: the first car again,
    # 1 px to the right (0.6), a near duplicate of it (0.5), and a pedestrian on the second car (0.4)
    def row(cx, score, cls):
        probs = [0.0, 0.0, 0.0]
        probs[cls] = 1.0
        return [cx, 40, 20, 10, score, *probs]
    pred = torch.tensor([[row(50, 0.8, 0), row(210, 0.9, 0), row(0, 0.0, 0),
                          row(51, 0.6, 0), row(50.5, 0.5, 0), row(210, 0.4, 1)]])
    out = postprocess(pred, conf_threshold=0.3, iou_threshold=0.5, views=2)[0].numpy()
    # the first car (0.8 + 0.6) / 2; the second car and the pedestrian, one view each, half
    np.testing.assert_allclose(out, [[40, 35, 60, 45, 0.7, 0], [200, 35, 220, 45, 0.45, 0],
                                     [200, 35, 220, 45, 0.2, 1]], atol=1e-6)
    one = postprocess(pred, conf_threshold=0.3, iou_threshold=0.5)[0].numpy()
    np.testing.assert_allclose(one[:, 4], [0.9, 0.8, 0.4], atol=1e-6)  # one view: scores as they are


def test_fused_boxes_are_the_score_weighted_mean_of_each_views_best():
    """Three views of one car: view 0 at x 40-60 (0.8) and a weaker box 2 px to the right (0.3,
    suppressed, not its view's best); view 1 at x 43-63 (0.4); view 2 sees nothing there. A second
    car in view 2 alone keeps its own box. Scores and order are those of the plain read."""
    def row(cx, score):
        return [cx, 40, 20, 10, score, 1.0, 0.0, 0.0]
    pred = torch.tensor([[row(50, 0.8), row(52, 0.3), row(53, 0.4), row(300, 0.6)]])
    view = torch.tensor([0, 0, 1, 2])
    plain = postprocess(pred, conf_threshold=0.1, iou_threshold=0.5, views=view)[0].numpy()
    fused = postprocess(pred, conf_threshold=0.1, iou_threshold=0.5, views=view, fuse_boxes=True)[0].numpy()
    x1 = (0.8 * 40 + 0.4 * 43) / 1.2  # 41.0
    np.testing.assert_allclose(fused, [[x1, 35, x1 + 20, 45, 0.4, 0], [290, 35, 310, 45, 0.2, 0]], atol=1e-5)
    np.testing.assert_array_equal(fused[:, 4:], plain[:, 4:])
    np.testing.assert_allclose(plain[:, :4], [[40, 35, 60, 45], [290, 35, 310, 45]], atol=1e-5)


def test_box_iou_matrix():
    a = torch.tensor([[0.0, 0, 2, 2], [0, 0, 1, 1]])
    b = torch.tensor([[1.0, 1, 3, 3], [5, 5, 6, 6]])
    np.testing.assert_allclose(box_iou_matrix(a, b).numpy(), [[1 / 7, 0], [0, 0]], atol=1e-7)


# ---------------------------------------------------------------- anchors
def test_kmeans_recovers_planted_clusters():
    rng = np.random.default_rng(7)
    planted = np.array([[8, 20], [14, 36], [30, 18], [24, 60], [60, 30], [50, 110],
                        [120, 70], [100, 200], [260, 150]], dtype=float)
    wh = np.concatenate([c * rng.uniform(0.95, 1.05, (80, 2)) for c in planted])
    got = kmeans_anchors(wh, 9, np.random.default_rng(0))
    want = planted[np.argsort(planted.prod(1))]
    np.testing.assert_allclose(got, want, rtol=0.03)
    assert best_possible_recall(wh, got) == 1.0


def test_kmeans_distance_is_one_minus_iou():
    a = np.array([[10.0, 10.0]])
    assert wh_iou(np.array([[10.0, 20.0]]), a)[0, 0] == pytest.approx(0.5)
    assert wh_iou(np.array([[5.0, 5.0]]), a)[0, 0] == pytest.approx(0.25)
    with pytest.raises(ValueError, match="at least 9"):
        kmeans_anchors(np.ones((5, 2)), 9)
