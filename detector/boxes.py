"""Box geometry for the detector: letterboxing (image <-> network input), box formats, and the
IoU family used by the box loss (IoU, GIoU, DIoU, CIoU).

Pixel convention: continuous coordinates with pixel i covering [i, i + 1), which is what an
area/linear resize preserves: a source edge at x lands at x * (new_w / w) in the resized image.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import torch

PAD_VALUE = 114  # grey padding: the mean-ish colour, so padding does not look like an object


@dataclass(frozen=True)
class Letterbox:
    """A resize that keeps the aspect ratio, then a pad to the network input size.

    The resized size is rounded to whole pixels, so the x and y scales are each exactly
    resized / source size; mapping uses those, which makes forward/inverse exact inverses.
    """
    src_w: int
    src_h: int
    dst_w: int
    dst_h: int
    new_w: int
    new_h: int
    pad_x: int
    pad_y: int

    @staticmethod
    def fit(src_w: int, src_h: int, dst_w: int, dst_h: int) -> "Letterbox":
        if min(src_w, src_h, dst_w, dst_h) <= 0:
            raise ValueError(f"letterbox sizes must be positive: src {src_w}x{src_h}, dst {dst_w}x{dst_h}")
        r = min(dst_w / src_w, dst_h / src_h)
        new_w = min(dst_w, max(1, round(src_w * r)))
        new_h = min(dst_h, max(1, round(src_h * r)))
        return Letterbox(src_w, src_h, dst_w, dst_h, new_w, new_h,
                         (dst_w - new_w) // 2, (dst_h - new_h) // 2)

    @property
    def scale(self) -> tuple[float, float]:
        return self.new_w / self.src_w, self.new_h / self.src_h

    def apply(self, img: np.ndarray) -> np.ndarray:
        """HxWx3 uint8 image -> dst_h x dst_w x 3, resized and centred on grey padding."""
        h, w = img.shape[:2]
        if (w, h) != (self.src_w, self.src_h):
            raise ValueError(f"letterbox made for {self.src_w}x{self.src_h}, image is {w}x{h}")
        interp = cv2.INTER_AREA if self.new_w < w else cv2.INTER_LINEAR
        resized = img if (self.new_w, self.new_h) == (w, h) else cv2.resize(img, (self.new_w, self.new_h), interpolation=interp)
        out = np.full((self.dst_h, self.dst_w, 3), PAD_VALUE, dtype=np.uint8)
        out[self.pad_y:self.pad_y + self.new_h, self.pad_x:self.pad_x + self.new_w] = resized
        return out

    def forward(self, boxes: np.ndarray) -> np.ndarray:
        """Source-image xyxy boxes (N,4) -> network-input pixels."""
        sx, sy = self.scale
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        return b * np.array([sx, sy, sx, sy]) + np.array([self.pad_x, self.pad_y, self.pad_x, self.pad_y])

    def inverse(self, boxes: np.ndarray, clip: bool = True) -> np.ndarray:
        """Network-input xyxy boxes (N,4) -> source-image pixels, clipped as KITTI labels are
        (to [0, w - 1] x [0, h - 1], see kitti.boxes.project_boxes)."""
        sx, sy = self.scale
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        out = (b - np.array([self.pad_x, self.pad_y, self.pad_x, self.pad_y])) / np.array([sx, sy, sx, sy])
        if clip:
            out[:, [0, 2]] = out[:, [0, 2]].clip(0, self.src_w - 1)
            out[:, [1, 3]] = out[:, [1, 3]].clip(0, self.src_h - 1)
        return out


def input_size_for(src_w: int, src_h: int, width: int, stride: int = 32) -> tuple[int, int]:
    """Network input (w, h) of the given width whose height fits the scaled image, rounded up to the stride."""
    h = src_h * width / src_w
    return width, int(math.ceil(h / stride) * stride)


def cxcywh_to_xyxy(b: torch.Tensor) -> torch.Tensor:
    return torch.stack((b[..., 0] - b[..., 2] / 2, b[..., 1] - b[..., 3] / 2,
                        b[..., 0] + b[..., 2] / 2, b[..., 1] + b[..., 3] / 2), -1)


def box_iou_matrix(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """(N,4) x (M,4) xyxy -> (N,M) IoU."""
    area_a = (a[:, 2] - a[:, 0]).clamp(min=0) * (a[:, 3] - a[:, 1]).clamp(min=0)
    area_b = (b[:, 2] - b[:, 0]).clamp(min=0) * (b[:, 3] - b[:, 1]).clamp(min=0)
    lt = torch.maximum(a[:, None, :2], b[None, :, :2])
    rb = torch.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = (rb - lt).clamp(min=0).prod(-1)
    union = area_a[:, None] + area_b[None, :] - inter
    return torch.where(union > 0, inter / union.clamp(min=1e-12), torch.zeros_like(inter))


def aligned_iou(a: torch.Tensor, b: torch.Tensor, kind: str = "diou", eps: float = 1e-7) -> torch.Tensor:
    """Element-wise IoU variant between matching rows of two (N,4) xyxy tensors.

    giou: IoU - (enclosing area - union) / enclosing area
    diou: IoU - centre distance^2 / enclosing diagonal^2
    ciou: DIoU - alpha * v, v the aspect-ratio mismatch (4/pi^2)(atan(w/h) - atan(w'/h'))^2
    """
    if kind not in ("iou", "giou", "diou", "ciou"):
        raise ValueError(f"unknown IoU kind {kind!r}; choose iou, giou, diou or ciou")
    w1, h1 = a[:, 2] - a[:, 0], a[:, 3] - a[:, 1]
    w2, h2 = b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]
    iw = (torch.minimum(a[:, 2], b[:, 2]) - torch.maximum(a[:, 0], b[:, 0])).clamp(min=0)
    ih = (torch.minimum(a[:, 3], b[:, 3]) - torch.maximum(a[:, 1], b[:, 1])).clamp(min=0)
    inter = iw * ih
    union = w1 * h1 + w2 * h2 - inter + eps
    iou = inter / union
    if kind == "iou":
        return iou
    cw = torch.maximum(a[:, 2], b[:, 2]) - torch.minimum(a[:, 0], b[:, 0])
    ch = torch.maximum(a[:, 3], b[:, 3]) - torch.minimum(a[:, 1], b[:, 1])
    if kind == "giou":
        c_area = cw * ch + eps
        return iou - (c_area - union) / c_area
    c2 = cw ** 2 + ch ** 2 + eps
    rho2 = ((a[:, 0] + a[:, 2] - b[:, 0] - b[:, 2]) ** 2 + (a[:, 1] + a[:, 3] - b[:, 1] - b[:, 3]) ** 2) / 4
    if kind == "diou":
        return iou - rho2 / c2
    v = (4 / math.pi ** 2) * (torch.atan(w2 / (h2 + eps)) - torch.atan(w1 / (h1 + eps))) ** 2
    with torch.no_grad():
        alpha = v / (v - iou + (1 + eps))
    return iou - (rho2 / c2 + v * alpha)
