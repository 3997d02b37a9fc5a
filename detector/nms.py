"""Non-maximum suppression (plain torch/numpy, no torchvision) and the post-processing that turns
decoded network outputs into per-image detections."""
from __future__ import annotations

import numpy as np
import torch

from detector.boxes import box_iou_matrix, cxcywh_to_xyxy


def nms(boxes: torch.Tensor, scores: torch.Tensor, iou_threshold: float) -> torch.Tensor:
    """Greedy NMS: indices of kept boxes, highest score first.

    A box is dropped when its IoU with an already kept, higher-scoring box is > iou_threshold.
    Ties in score keep the lower index first (stable sort), so the result is deterministic.
    The IoU matrix is computed once; the greedy pass only visits boxes still alive.
    """
    return nms_clusters(boxes, scores, iou_threshold)[0]


def nms_clusters(boxes: torch.Tensor, scores: torch.Tensor,
                 iou_threshold: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Greedy NMS (as `nms`) that also says which kept box took each box: (kept indices, highest
    score first; for every box, the position in the kept list of the box that suppressed it, or
    its own position if kept)."""
    if boxes.numel() == 0:
        return torch.zeros(0, dtype=torch.long), torch.zeros(0, dtype=torch.long)
    order = torch.sort(scores, descending=True, stable=True).indices
    iou = box_iou_matrix(boxes[order], boxes[order]).cpu().numpy()
    n = len(order)
    over = np.triu(iou > iou_threshold, k=1)
    alive = np.ones(n, dtype=bool)
    cluster = np.empty(n, dtype=np.int64)
    keep = []
    for i in range(n):
        if alive[i]:
            taken = alive & over[i]
            cluster[taken] = cluster[i] = len(keep)
            keep.append(i)
            alive &= ~over[i]
    by_box = torch.empty(n, dtype=torch.long)
    by_box[order] = torch.from_numpy(cluster)
    return order[torch.as_tensor(keep, dtype=torch.long)], by_box


def batched_nms(boxes: torch.Tensor, scores: torch.Tensor, classes: torch.Tensor,
                iou_threshold: float) -> torch.Tensor:
    """Per-class NMS in one pass: boxes of different classes are shifted apart so they never overlap."""
    return batched_nms_clusters(boxes, scores, classes, iou_threshold)[0]


def batched_nms_clusters(boxes: torch.Tensor, scores: torch.Tensor, classes: torch.Tensor,
                         iou_threshold: float) -> tuple[torch.Tensor, torch.Tensor]:
    """`nms_clusters` per class in one pass (boxes of different classes shifted apart)."""
    if boxes.numel() == 0:
        return torch.zeros(0, dtype=torch.long), torch.zeros(0, dtype=torch.long)
    offset = classes.to(boxes.dtype)[:, None] * (boxes.max() - boxes.min() + 1)
    return nms_clusters(boxes + offset, scores, iou_threshold)


def postprocess(pred: torch.Tensor, conf_threshold: float = 0.001, iou_threshold: float = 0.6,
                max_det: int = 100, max_candidates: int = 3000,
                views: int | torch.Tensor = 1, fuse_boxes: bool = False) -> list[torch.Tensor]:
    """Decoded predictions (B, N, 5 + nc) -> per image (K, 6): x1, y1, x2, y2, score, class.

    Score = objectness x class probability; every class above the threshold is a candidate
    (an ambiguous Van-like car can be reported once per plausible class, NMS is per class).

    `views` > 1: each image was read that many ways (the image and its mirror, boxes mapped
    back), their candidates in equal blocks along N. One NMS runs over all of them, and each kept
    box is scored by the mean over the views of the best score among the candidates it
    suppressed (itself included; 0 for a view with none): a box that only one read finds scores
    half, so what one view alone fires on ranks below what both see. Views of unequal size (reads
    at other scales have other grids) come as a tensor: each candidate's view, (N,) int64.
    `fuse_boxes` (views > 1): each kept box's sides become the mean of the views' best boxes in its
    cluster, each weighted by its score (the boxes that give the view-mean score), instead of the
    one best box's.
    """
    if isinstance(views, torch.Tensor):
        view_of, views = views, int(views.max()) + 1
    else:
        view_of = torch.arange(pred.shape[1]) // (pred.shape[1] // views)
    out = []
    for p in pred:
        view = view_of
        m = p[:, 4] > conf_threshold
        p, view = p[m], view[m]
        if p.shape[0] == 0:
            out.append(torch.zeros((0, 6)))
            continue
        scores = p[:, 5:] * p[:, 4:5]
        i, j = torch.nonzero(scores > conf_threshold, as_tuple=True)
        boxes = cxcywh_to_xyxy(p[i, :4])
        s, view = scores[i, j], view[i]
        if s.numel() > max_candidates:
            top = torch.topk(s, max_candidates).indices
            boxes, s, j, view = boxes[top], s[top], j[top], view[top]
        if views > 1:
            keep, s_keep, fused = _view_mean_scores(s, view, *batched_nms_clusters(boxes, s, j, iou_threshold),
                                                    views, boxes if fuse_boxes else None)
        else:
            keep, fused = batched_nms(boxes, s, j, iou_threshold), None
            s_keep = s[keep]
        keep, s_keep = keep[:max_det], s_keep[:max_det]
        kept = boxes[keep] if fused is None else fused[:max_det]
        out.append(torch.cat((kept, s_keep[:, None], j[keep, None].to(boxes.dtype)), 1))
    return out


def _view_mean_scores(s: torch.Tensor, view: torch.Tensor, keep: torch.Tensor, cluster: torch.Tensor,
                      views: int, boxes: torch.Tensor | None = None
                      ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
    """Kept boxes re-scored by the mean over views of their cluster's best score, best first (a
    box's cluster: the kept box that suppressed it in the greedy pass, or itself); given the
    candidates' `boxes`, also each kept box fused: the score-weighted mean of its views' best boxes
    (on a tie, the first candidate)."""
    slot = cluster * views + view
    best = torch.zeros(len(keep) * views, dtype=s.dtype)
    best.scatter_reduce_(0, slot, s, reduce="amax")
    score = best.view(len(keep), views).mean(1)
    order = torch.sort(score, descending=True, stable=True).indices
    if boxes is None:
        return keep[order], score[order], None
    top = torch.nonzero(s == best[slot]).squeeze(1)
    first = torch.full((len(keep) * views,), len(s), dtype=torch.long)
    first.scatter_reduce_(0, slot[top], top, reduce="amin")
    seen = first < len(s)
    weighted = torch.zeros(len(keep) * views, 4, dtype=boxes.dtype)
    weighted[seen] = boxes[first[seen]] * best[seen, None]
    fused = weighted.view(len(keep), views, 4).sum(1) / best.view(len(keep), views).sum(1, keepdim=True)
    return keep[order], score[order], fused[order]
