"""2D-box crops for the size and orientation network: the square around the box scaled to S x S
(000 and Deep3DBox warp the box itself; keeping the aspect ratio keeps the length cue), optionally
jittered like a detector's box and mirrored (alpha -> pi - alpha)."""

from __future__ import annotations

import cv2
import numpy as np

MEAN = np.array([0.485, 0.456, 0.406], dtype=np.float32) * 255
STD = np.array([0.229, 0.224, 0.225], dtype=np.float32) * 255


def crop(image: np.ndarray, bbox: np.ndarray, size: int) -> np.ndarray:
    """(size, size, 3) uint8: the square around bbox [x1, y1, x2, y2] (side = the longer side,
    sub-pixel) scaled to size. Not warped: the box's aspect ratio, which tells a long car from a
    short one at the same orientation, stays in the crop."""
    x1, y1, x2, y2 = (float(v) for v in bbox)
    side = max(x2 - x1, y2 - y1, 1.0)
    x1, y1 = 0.5 * (x1 + x2 - side), 0.5 * (y1 + y2 - side)
    k = size / side
    m = np.array([[k, 0, -x1 * k], [0, k, -y1 * k]], dtype=np.float64)
    return cv2.warpAffine(image, m, (size, size), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REPLICATE)


def jitter_box(bbox: np.ndarray, rng: np.random.Generator, shift: float = 0.05,
               scale: float = 0.08) -> np.ndarray:
    """A box moved by up to `shift` of its size and rescaled by up to `scale`, per side pair."""
    x1, y1, x2, y2 = bbox
    w, h = x2 - x1, y2 - y1
    cx, cy = (x1 + x2) / 2 + rng.uniform(-shift, shift) * w, (y1 + y2) / 2 + rng.uniform(-shift, shift) * h
    w *= 1 + rng.uniform(-scale, scale)
    h *= 1 + rng.uniform(-scale, scale)
    return np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])


def to_tensor_layout(crops: np.ndarray) -> np.ndarray:
    """(N, S, S, 3) uint8 -> (N, 3, S, S) float32 normalised."""
    x = (crops.astype(np.float32) - MEAN) / STD
    return np.ascontiguousarray(x.transpose(0, 3, 1, 2))
