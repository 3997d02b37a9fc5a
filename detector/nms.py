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
    if boxes.numel() == 0:
        return torch.zeros(0, dtype=torch.long)
    order = torch.sort(scores, descending=True, stable=True).indices
    iou = box_iou_matrix(boxes[order], boxes[order]).cpu().numpy()
    n = len(order)
    over = np.triu(iou > iou_threshold, k=1)
    alive = np.ones(n, dtype=bool)
    keep = []
    for i in range(n):
        if alive[i]:
            keep.append(i)
            alive &= ~over[i]
    return order[torch.as_tensor(keep, dtype=torch.long)]


def batched_nms(boxes: torch.Tensor, scores: torch.Tensor, classes: torch.Tensor,
                iou_threshold: float) -> torch.Tensor:
    """Per-class NMS in one pass: boxes of different classes are shifted apart so they never overlap."""
    if boxes.numel() == 0:
        return torch.zeros(0, dtype=torch.long)
    offset = classes.to(boxes.dtype)[:, None] * (boxes.max() - boxes.min() + 1)
    return nms(boxes + offset, scores, iou_threshold)


def postprocess(pred: torch.Tensor, conf_threshold: float = 0.001, iou_threshold: float = 0.6,
                max_det: int = 100, max_candidates: int = 3000) -> list[torch.Tensor]:
    """Decoded predictions (B, N, 5 + nc) -> per image (K, 6): x1, y1, x2, y2, score, class.

    Score = objectness x class probability; every class above the threshold is a candidate
    (an ambiguous Van-like car can be reported once per plausible class, NMS is per class).
    """
    out = []
    for p in pred:
        p = p[p[:, 4] > conf_threshold]
        if p.shape[0] == 0:
            out.append(torch.zeros((0, 6)))
            continue
        scores = p[:, 5:] * p[:, 4:5]
        i, j = torch.nonzero(scores > conf_threshold, as_tuple=True)
        boxes = cxcywh_to_xyxy(p[i, :4])
        s = scores[i, j]
        if s.numel() > max_candidates:
            top = torch.topk(s, max_candidates).indices
            boxes, s, j = boxes[top], s[top], j[top]
        keep = batched_nms(boxes, s, j, iou_threshold)[:max_det]
        out.append(torch.cat((boxes[keep], s[keep, None], j[keep, None].to(boxes.dtype)), 1))
    return out
