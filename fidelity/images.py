"""Image statistics of one image_2 PNG: tone, colour, texture and how much a PNG encoder has to
store of its pixels. Generated images tend to be too clean (flat shading, no sensor noise), which
shows as many flat pixels, weak gradients and small PNGs. With labels, the same inside the 2D
boxes of near, whole Cars: what a detector sees of a car, which whole-image figures can match while
the cars still look nothing like real ones."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from kitti.calib import Calibration
from kitti.errors import KittiFormatError
from kitti.labels import Object3D
from kitti.median import median

from .stats import Acc

CANNY = (100, 200)  # fixed hysteresis thresholds, grey levels
# How compressible the pixels are: the size of the PNG one fixed encoder makes of them (the Paeth
# filter on every row, run-length coding, zlib level 3: about the entropy of each pixel's
# difference from what its three neighbours predict, which noise and fine detail raise), whichever
# encoder wrote the file. The file's size would also measure its writer: the same pixels written
# with libpng's per-row filter search take 11-14 % more bytes (KITTI's files, re-encoded that way,
# come within -3 to +7 % of their own sizes).
PNG_MEASURE = [cv2.IMWRITE_PNG_COMPRESSION, 3, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_PAETH,
               cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE]
FLAT = 1            # |dI/dx| below this (grey levels) is a flat pixel
# A Car whose look is measured: its 2D box at least this tall (KITTI's "easy" height, about 28 m
# and nearer for a 1.5 m car), untruncated and fully visible, so the box holds the car alone.
NEAR_CAR_PX = 40
# The road's fine structure: the bottom fifth of the frame (mostly road in a KITTI-like view), less
# a Gaussian of HIGH_PASS_PX, read as a robust SD (1.4826 x the median absolute deviation, which
# edges and lane paint barely move): in R - G (colour noise) and in the grey (detail).
ROAD_ROWS = 0.2
HIGH_PASS_PX = 3.0
# The road surface itself, where the scan says the camera sees road: the pixels that the LiDAR's
# road returns (within ROAD_SURFACE_M of the frame's fitted road plane: on the carriageway, not
# on a 0.15 m kerb) project to, in bands of ground distance from camera 0, the same two robust SDs
# read there (one sample per pixel). The bottom fifth mixes the asphalt's grain with kerbs, paint,
# cars and shade; this separates it, and the near band from the far (a pixel spans about 1 cm
# across and 3 cm along the road at 7 m, four times that at 15 m).
ROAD_SURFACE_M = 0.1
ROAD_SURFACE_BANDS = ((5.0, 10.0), (10.0, 20.0))
MIN_ROAD_PIXELS = 30  # fewer road pixels in a band: no value for the frame there
# The whole KITTI object training set's pixel statistics, every pixel of its 7,481 image_2 PNGs,
# R / G / B, as detection code that normalises KITTI inputs publishes them: the camera's tone
# (simgen.camera.KEY) and colour balance (simgen.camera.BALANCE) were set from these.
KITTI_TRAINING_PIXEL_MEAN = (93.83, 98.76, 95.88)
KITTI_TRAINING_PIXEL_SD = (78.78, 80.13, 81.20)
LEVELS = np.arange(256, dtype=np.uint8)  # of an 8-bit channel
# The float32 gradient magnitude of each (|dI/dx|, |dI/dy|) pair of 8-bit pixels, at 256·dx + dy:
# computed once, so the gradient histogram counts pairs instead of taking a square root a pixel.
GRADIENT_MAG = np.sqrt(np.square(np.arange(256)[:, None], dtype=np.float32)
                       + np.square(np.arange(256), dtype=np.float32)).ravel()


def read_image(path: Path) -> np.ndarray:
    """The BGR image; a file cv2 cannot decode is a format error."""
    img = cv2.imdecode(np.fromfile(path, np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        raise KittiFormatError("cannot decode the image", path)
    return img


def png_size(img: np.ndarray) -> int:
    """Bytes of the PNG that PNG_MEASURE's encoder makes of the image's pixels."""
    ok, buf = cv2.imencode(".png", img, PNG_MEASURE)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return len(buf)


def levels(image: np.ndarray, n: int = 256, channel: int = 0) -> np.ndarray:
    """How many pixels of an 8- or 16-bit image's `channel` hold each of its `n` levels: cv2
    counts them three times faster than bincount (and reads one channel of a colour image in
    place), in float32, exact below 2**24 pixels."""
    if image.shape[0] * image.shape[1] >= 1 << 24:
        return np.bincount((image if image.ndim == 2 else image[..., channel]).ravel(), minlength=n)
    return cv2.calcHist([image], [channel], None, [n], [0, n]).ravel().astype(np.int64)


def robust_sd(x: np.ndarray) -> float:
    """1.4826 x the median absolute deviation: the SD of a normal sample, robust to outliers."""
    x = np.asarray(x, np.float64).ravel()
    return float(1.4826 * median(np.abs(x - median(x))))


def _high_pass(x: np.ndarray) -> np.ndarray:
    return x - cv2.GaussianBlur(x, (0, 0), HIGH_PASS_PX)


def _red_minus_green(bgr: np.ndarray) -> np.ndarray:
    """R - G of 8-bit BGR pixels in float32 (exact), without converting the blue channel too."""
    return bgr[..., 2].astype(np.float32) - bgr[..., 1]


def road_structure(img: np.ndarray, grey: np.ndarray) -> tuple[float, float]:
    """(colour noise, detail) of the bottom ROAD_ROWS of a BGR image and its grey: robust SDs of
    R - G and of the grey after a high-pass."""
    top = int(round(img.shape[0] * (1.0 - ROAD_ROWS)))
    return (robust_sd(_high_pass(_red_minus_green(img[top:]))),
            robust_sd(_high_pass(grey[top:].astype(np.float32))))


def road_surface_stats(acc: Acc, img: np.ndarray, grey: np.ndarray, rect: np.ndarray,
                       height: np.ndarray, calib: Calibration) -> None:
    """Per ROAD_SURFACE_BANDS band, the colour noise and detail (`road_structure`'s) at the pixels
    the scan's road returns project to: `rect` the returns in the rectified frame, `height` their
    heights above the frame's road plane."""
    road = (np.abs(height) < ROAD_SURFACE_M) & (rect[:, 2] > 1.0)  # in front of the camera
    uv, _ = calib.rect_to_image(rect[road])
    ground = np.hypot(rect[road, 0], rect[road, 2])
    u, v = np.round(uv[:, 0]).astype(np.int64), np.round(uv[:, 1]).astype(np.int64)
    h, w = grey.shape
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    if not inside.any():
        return
    # the high-pass of the rows the road pixels lie in: a Gaussian reaches 4 sigma (cv2's kernel
    # for float images), so rows from that far above the first are as the whole image's
    top = max(int(v[inside].min()) - int(np.ceil(4 * HIGH_PASS_PX)) - 1, 0)
    colour = _high_pass(_red_minus_green(img[top:])).ravel()
    detail = _high_pass(grey[top:].astype(np.float32)).ravel()
    for lo, hi in ROAD_SURFACE_BANDS:
        m = inside & (ground >= lo) & (ground < hi)
        pix = np.unique((v[m] - top) * w + u[m])
        if len(pix) < MIN_ROAD_PIXELS:
            continue
        acc.put(f"images.road_surface_colour_noise_{lo:g}_{hi:g}m", robust_sd(colour[pix]))
        acc.put(f"images.road_surface_detail_{lo:g}_{hi:g}m", robust_sd(detail[pix]))


def channel_sums(img: np.ndarray) -> np.ndarray:
    """(7,) R, G, B sums, their sums of squares and the pixel count of a BGR image, from level
    counts (exact in float64): what pooled means and SDs over every pixel of a dataset add up."""
    counts = [levels(img, channel=c) for c in (2, 1, 0)]
    level = LEVELS.astype(np.float64)
    return np.array([*(level @ n for n in counts), *(level ** 2 @ n for n in counts),
                     img.shape[0] * img.shape[1]], np.float64)


def pooled_channels(sums: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, G, B means, their SDs) over every pixel of the frames whose channel_sums are `sums`."""
    total = np.asarray(sums, np.float64).reshape(-1, 7).sum(axis=0)
    mean = total[:3] / total[6]
    return mean, np.sqrt(total[3:6] / total[6] - mean ** 2)


def image_stats(acc: Acc, img: np.ndarray) -> np.ndarray:
    """The whole image's statistics; returns its grey image (cv2's BGR2GRAY). Means and
    histograms of a channel come from its level counts: a sum of 8-bit levels is exact in
    float64, so the mean is the one numpy gives."""
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    grey_n, sat_n = levels(grey), levels(cv2.cvtColor(img, cv2.COLOR_BGR2HSV), channel=1)
    g = grey.astype(np.int16)
    dx = np.abs(np.diff(g, axis=1))
    dy = np.abs(np.diff(g, axis=0))
    pairs = dx[:-1].astype(np.uint16) << 8 | dy[:, :-1].astype(np.uint16)  # GRADIENT_MAG's index
    acc.put("images.png_bytes", png_size(img))
    acc.put("images.grey_mean", LEVELS @ grey_n / grey.size)
    acc.put("images.grey_sd", grey.std())
    acc.put("images.saturation_mean", LEVELS @ sat_n / grey.size)
    acc.put("images.mean_abs_dx", dx.mean())
    acc.put("images.flat_share", np.count_nonzero(dx < FLAT) / dx.size)
    acc.put("images.edge_density", np.count_nonzero(cv2.Canny(grey, *CANNY)) / grey.size)
    acc.row("images.channel_sums", channel_sums(img))
    colour_noise, detail = road_structure(img, grey)
    acc.put("images.road_colour_noise", colour_noise)
    acc.put("images.road_detail", detail)
    acc.hist("images.grey", LEVELS, grey_n)
    acc.hist("images.saturation", LEVELS, sat_n)
    acc.hist("images.gradient", GRADIENT_MAG, levels(pairs, len(GRADIENT_MAG)))
    return grey


def car_look_stats(acc: Acc, grey: np.ndarray, labels: list[Object3D]) -> None:
    """Per near, whole Car (NEAR_CAR_PX) of a grey image: grey mean, grey standard deviation (RMS
    contrast) and mean |dI/dx| inside its 2D box (pixel indices rounded, clipped to the image),
    and how much darker the box's lowest eighth (tyres, the shade under the body) is than the
    whole box."""
    h, w = grey.shape
    for o in labels:
        if o.type != "Car" or o.truncated > 0 or o.occluded != 0 or o.height_px < NEAR_CAR_PX:
            continue
        x1, y1 = (int(np.clip(round(v), 0, n - 1)) for v, n in zip(o.bbox[:2], (w, h)))
        x2, y2 = (int(np.clip(round(v), 0, n - 1)) for v, n in zip(o.bbox[2:], (w, h)))
        patch = grey[y1:y2 + 1, x1:x2 + 1].astype(np.float64)
        if patch.shape[0] < 8 or patch.shape[1] < 2:
            continue
        acc.put("labels.car_grey_mean", patch.mean())
        acc.put("labels.car_grey_sd", patch.std())
        acc.put("labels.car_abs_dx", np.abs(np.diff(patch, axis=1)).mean())
        acc.put("labels.car_bottom_darkening", patch.mean() - patch[-(len(patch) // 8):].mean())
