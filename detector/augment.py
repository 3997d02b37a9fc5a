"""Training-time augmentation: mosaic, scale/translate, horizontal flip, HSV colour jitter, and
the two Mixup variants of 004 (plain: lambda ~ Beta(8, 8), both images' boxes kept;
thresholded: mixed only when no box of one image overlaps a box of the other at IoU >= 0.4).

Every sample draws from its own generator seeded by (seed, epoch, index): the same settings
give the same batches whatever order or process builds them.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from detector.boxes import PAD_VALUE
from detector.data import DetectionData, Sample

MIXUP_MODES = ("none", "mixup", "thresholded")


@dataclass(frozen=True)
class AugmentConfig:
    mosaic: float = 1.0          # probability of a 4-image mosaic
    scale: float = 0.4           # zoom drawn from [1 - scale, 1 + scale]
    translate: float = 0.1       # shift drawn from +-translate x output size
    fliplr: float = 0.5
    hsv: tuple[float, float, float] = (0.015, 0.7, 0.4)  # hue, saturation, value gains
    mixup: str = "none"          # none | mixup | thresholded
    mixup_prob: float = 0.5      # 004 does not give one; half the samples are offered a partner
    mixup_alpha: float = 8.0     # Beta(alpha, alpha), 004
    mixup_iou: float = 0.4       # thresholded variant: mix only when every cross-image IoU is below this
    min_box: float = 2.0         # boxes thinner than this (pixels) after augmentation are dropped
    min_area_kept: float = 0.2   # ... and so are boxes cut to less than this share of their area

    def __post_init__(self):
        if self.mixup not in MIXUP_MODES:
            raise ValueError(f"unknown mixup mode {self.mixup!r}; choose one of {MIXUP_MODES}")
        for name in ("mosaic", "fliplr", "mixup_prob"):
            v = getattr(self, name)
            if not 0 <= v <= 1:
                raise ValueError(f"augmentation {name} must be a probability in [0, 1], got {v}")
        if not 0 <= self.scale < 1:
            raise ValueError(f"augmentation scale must be in [0, 1), got {self.scale}")

    @staticmethod
    def off() -> "AugmentConfig":
        """Only the letterbox: evaluation-like inputs (used to close training without mosaic)."""
        return AugmentConfig(mosaic=0.0, scale=0.0, translate=0.0, fliplr=0.0, hsv=(0.0, 0.0, 0.0))


def pairwise_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,4) x (M,4) xyxy -> (N,M)."""
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.clip(rb - lt, 0, None).prod(2)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    return inter / np.maximum(area_a[:, None] + area_b[None] - inter, 1e-12)


class Augmenter:
    """Builds training inputs of size (w, h) from a DetectionData."""

    def __init__(self, data: DetectionData, cfg: AugmentConfig, seed: int):
        self.data = data
        self.cfg = cfg
        self.seed = seed
        self.w, self.h = data.input_size

    def rng(self, epoch: int, index: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, epoch, index])

    def __call__(self, index: int, epoch: int, cfg: AugmentConfig | None = None) -> Sample:
        cfg = cfg or self.cfg
        rng = self.rng(epoch, index)
        s = self._one(index, rng, cfg)
        if cfg.mixup != "none" and rng.random() < cfg.mixup_prob:
            partner = self._one(int(rng.integers(len(self.data))), rng, cfg)
            s = mix(s, partner, cfg, rng)
        return s

    def _one(self, index: int, rng: np.random.Generator, cfg: AugmentConfig) -> Sample:
        if rng.random() < cfg.mosaic:
            canvas, boxes, classes = self._mosaic(index, rng)
        else:
            canvas, boxes, classes = self._letterboxed(index)
        img, boxes, classes = self._affine(canvas, boxes, classes, rng, cfg)
        if rng.random() < cfg.fliplr:
            img = img[:, ::-1].copy()
            boxes = boxes.copy()
            boxes[:, [0, 2]] = self.w - boxes[:, [2, 0]]
        if any(cfg.hsv):
            img = hsv_jitter(img, cfg.hsv, rng)
        return Sample(img, boxes, classes)

    def _letterboxed(self, index: int):
        s = self.data.samples[index]
        h, w = s.image.shape[:2]
        px, py = (self.w - w) // 2, (self.h - h) // 2
        canvas = np.full((self.h, self.w, 3), PAD_VALUE, np.uint8)
        canvas[py:py + h, px:px + w] = s.image
        return canvas, s.boxes + np.array([px, py, px, py]), s.classes

    def _mosaic(self, index: int, rng: np.random.Generator):
        """Four images meet at a random point of a 2w x 2h canvas, each in its own quadrant."""
        W, H = self.w, self.h
        canvas = np.full((2 * H, 2 * W, 3), PAD_VALUE, np.uint8)
        xc = int(rng.uniform(0.5 * W, 1.5 * W))
        yc = int(rng.uniform(0.5 * H, 1.5 * H))
        idx = [index] + [int(i) for i in rng.integers(len(self.data), size=3)]
        all_boxes, all_cls = [], []
        for q, i in enumerate(idx):
            s = self.data.samples[i]
            h, w = s.image.shape[:2]
            # canvas region (x1,y1,x2,y2) and the image's top-left corner on the canvas
            if q == 0:
                x1, y1, x2, y2 = max(xc - w, 0), max(yc - h, 0), xc, yc
                ox, oy = xc - w, yc - h
            elif q == 1:
                x1, y1, x2, y2 = xc, max(yc - h, 0), min(xc + w, 2 * W), yc
                ox, oy = xc, yc - h
            elif q == 2:
                x1, y1, x2, y2 = max(xc - w, 0), yc, xc, min(yc + h, 2 * H)
                ox, oy = xc - w, yc
            else:
                x1, y1, x2, y2 = xc, yc, min(xc + w, 2 * W), min(yc + h, 2 * H)
                ox, oy = xc, yc
            canvas[y1:y2, x1:x2] = s.image[y1 - oy:y2 - oy, x1 - ox:x2 - ox]
            b = s.boxes + np.array([ox, oy, ox, oy])
            b, keep = clip_boxes(b, (x1, y1, x2, y2), 0.0, 0.0)
            all_boxes.append(b)
            all_cls.append(s.classes[keep])
        return canvas, np.concatenate(all_boxes), np.concatenate(all_cls)

    def _affine(self, canvas: np.ndarray, boxes: np.ndarray, classes: np.ndarray,
                rng: np.random.Generator, cfg: AugmentConfig):
        """Zoom about the canvas centre and shift, into a w x h output."""
        ch, cw = canvas.shape[:2]
        zoom = rng.uniform(1 - cfg.scale, 1 + cfg.scale)
        tx = rng.uniform(-cfg.translate, cfg.translate) * self.w
        ty = rng.uniform(-cfg.translate, cfg.translate) * self.h
        ox = self.w / 2 + tx - zoom * cw / 2
        oy = self.h / 2 + ty - zoom * ch / 2
        if zoom == 1.0 and ox == 0 and oy == 0 and (cw, ch) == (self.w, self.h):
            img = canvas.copy()
        else:
            m = np.array([[zoom, 0, ox], [0, zoom, oy]], dtype=np.float64)
            img = cv2.warpAffine(canvas, m, (self.w, self.h), flags=cv2.INTER_LINEAR,
                                 borderValue=(PAD_VALUE,) * 3)
        b = boxes * zoom + np.array([ox, oy, ox, oy])
        b, keep = clip_boxes(b, (0, 0, self.w, self.h), cfg.min_box, cfg.min_area_kept)
        return img, b, classes[keep]


def clip_boxes(boxes: np.ndarray, region: tuple[float, float, float, float], min_size: float,
               min_area_kept: float) -> tuple[np.ndarray, np.ndarray]:
    """Clip xyxy boxes to a region; keep those at least min_size wide and high that kept at least
    min_area_kept of their area. Returns (kept clipped boxes, boolean mask)."""
    x1, y1, x2, y2 = region
    b = boxes.astype(np.float64).reshape(-1, 4)
    c = np.stack((b[:, 0].clip(x1, x2), b[:, 1].clip(y1, y2), b[:, 2].clip(x1, x2), b[:, 3].clip(y1, y2)), 1)
    w, h = c[:, 2] - c[:, 0], c[:, 3] - c[:, 1]
    area0 = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    keep = (w > min_size) & (h > min_size) & (w * h > min_area_kept * np.maximum(area0, 1e-12))
    keep &= (w > 0) & (h > 0)
    return c[keep], keep


def hsv_jitter(img: np.ndarray, gains: tuple[float, float, float], rng: np.random.Generator) -> np.ndarray:
    """Random hue shift and saturation/value scaling through lookup tables (RGB uint8 in and out)."""
    r = rng.uniform(-1, 1, 3) * np.asarray(gains) + 1
    hue, sat, val = cv2.split(cv2.cvtColor(img, cv2.COLOR_RGB2HSV))
    x = np.arange(256, dtype=np.float64)
    lut_h = ((x * r[0]) % 180).astype(np.uint8)
    lut_s = np.clip(x * r[1], 0, 255).astype(np.uint8)
    lut_v = np.clip(x * r[2], 0, 255).astype(np.uint8)
    hsv = cv2.merge((cv2.LUT(hue, lut_h), cv2.LUT(sat, lut_s), cv2.LUT(val, lut_v)))
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


def mix(a: Sample, b: Sample, cfg: AugmentConfig, rng: np.random.Generator) -> Sample:
    """Mixup (004): pixels blended with lambda ~ Beta(alpha, alpha), the boxes of both kept.
    The thresholded variant returns `a` unchanged when any box pair overlaps at IoU >= mixup_iou."""
    if cfg.mixup == "thresholded" and len(a.boxes) and len(b.boxes):
        if pairwise_iou(a.boxes, b.boxes).max() >= cfg.mixup_iou:
            return a
    lam = rng.beta(cfg.mixup_alpha, cfg.mixup_alpha)
    img = (a.image.astype(np.float32) * lam + b.image.astype(np.float32) * (1 - lam)).round().astype(np.uint8)
    return Sample(img, np.concatenate((a.boxes, b.boxes)), np.concatenate((a.classes, b.classes)))
