"""Image statistics of one image_2 PNG: tone, colour, texture and how much the encoder had to
store. Generated images tend to be too clean (flat shading, no sensor noise), which shows as many
flat pixels, weak gradients and small PNG files."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from kitti.errors import KittiFormatError

from .stats import Acc

CANNY = (100, 200)  # fixed hysteresis thresholds, grey levels
FLAT = 1            # |dI/dx| below this (grey levels) is a flat pixel


def read_image(path: Path) -> tuple[np.ndarray, int]:
    """(BGR image, encoded file size in bytes); a file cv2 cannot decode is a format error."""
    data = np.fromfile(path, np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_COLOR)
    if img is None:
        raise KittiFormatError("cannot decode the image", path)
    return img, len(data)


def image_stats(acc: Acc, img: np.ndarray, nbytes: int) -> None:
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    sat = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)[..., 1]
    g = grey.astype(np.int16)
    dx = np.abs(np.diff(g, axis=1))
    dy = np.abs(np.diff(g, axis=0))
    mag = np.sqrt(np.square(dx[:-1], dtype=np.float32) + np.square(dy[:, :-1], dtype=np.float32))
    acc.put("images.png_bytes", nbytes)
    acc.put("images.grey_mean", grey.mean())
    acc.put("images.saturation_mean", sat.mean())
    acc.put("images.mean_abs_dx", dx.mean())
    acc.put("images.flat_share", np.count_nonzero(dx < FLAT) / dx.size)
    acc.put("images.edge_density", np.count_nonzero(cv2.Canny(grey, *CANNY)) / grey.size)
    acc.hist("images.grey", grey)
    acc.hist("images.saturation", sat)
    acc.hist("images.gradient", mag)
