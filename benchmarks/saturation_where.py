"""Where two datasets' images differ in colour saturation (a diagnosis of the fidelity report's
`images.saturation_mean`): the median over frames of the mean HSV saturation (OpenCV's 0-255
scale) in five horizontal bands of the image, top to bottom, and among the pixels of five value
(brightness) ranges; the mean colour of the bottom band (mostly road), to tell a cast from
chroma noise; that band's colour noise and detail (the fidelity report's
`images.road_colour_noise` and `images.road_detail`, `testbed.fidelity.images.road_structure`);
and the share of the pixels with green at 255 that are 255 in all three
channels (white clipping: does the colour balance come before the clip?).

    .venv/bin/python benchmarks/saturation_where.py --sim data/fidelity/urban200_balance \
        --real ../shared/kitti_real_dev [--frames 60]

HSV saturation is (max - min) / max of a pixel's channels: a small colour cast on a dark grey
(asphalt in shade) reads as much saturation as a strong colour on a bright surface, so the value
ranges tell a tinted dark road from pale bright paint.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from testbed.fidelity.images import road_structure

BANDS = 5
VALUES = ((0, 40), (40, 80), (80, 140), (140, 200), (200, 256))


def frame_saturation(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(BANDS,) mean saturation per horizontal band, (len(VALUES),) per value range (NaN where
    the frame has no pixel in that range), the bottom band's mean R, G, B, and (the bottom band's
    R - G noise, its grey detail, the white share of green-clipped pixels or NaN)."""
    bgr = cv2.imread(str(path))
    if bgr is None:
        raise SystemExit(f"{path}: not a readable image")
    hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
    s, v = hsv[..., 1].astype(np.float64), hsv[..., 2]
    edges = np.linspace(0, len(s), BANDS + 1).astype(int)
    bands = np.array([s[a:b].mean() for a, b in zip(edges[:-1], edges[1:])])
    by_value = np.array([s[(v >= lo) & (v < hi)].mean() if np.any((v >= lo) & (v < hi)) else np.nan
                         for lo, hi in VALUES])
    bottom = bgr[edges[-2]:].reshape(-1, 3).mean(axis=0)[::-1]
    clipped = bgr[..., 1] == 255
    white = np.all(bgr[clipped] == 255, axis=1).mean() if clipped.sum() >= 100 else np.nan
    # the fidelity report's own rows (its bottom fifth is this bottom band)
    noise = np.array([*road_structure(bgr, cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)), white])
    return bands, by_value, bottom, noise


def dataset_saturation(root: Path, frames: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                  np.ndarray, int]:
    files = sorted((root / "training" / "image_2").glob("*.png"))[:frames]
    if not files:
        raise SystemExit(f"{root}: no training/image_2/*.png")
    per = [frame_saturation(f) for f in files]
    return (*(np.nanmedian([p[k] for p in per], axis=0) for k in range(4)), len(files))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sim", type=Path, required=True)
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--frames", type=int, default=None, help="first N frames of each (default: all)")
    args = ap.parse_args()
    sides = {name: dataset_saturation(root, args.frames) for name, root in
             (("sim", args.sim), ("real", args.real))}
    print("| median over frames | " + " | ".join(f"{k} ({v[4]} frames)" for k, v in sides.items()) + " |")
    print("|---|" + "---:|" * len(sides))
    for i in range(BANDS):
        print(f"| HSV saturation, rows band {i + 1} of {BANDS} (top to bottom) | "
              + " | ".join(f"{v[0][i]:.1f}" for v in sides.values()) + " |")
    for j, (lo, hi) in enumerate(VALUES):
        print(f"| HSV saturation, pixels of value {lo}-{hi - 1} | "
              + " | ".join(f"{v[1][j]:.1f}" for v in sides.values()) + " |")
    print("| bottom band's mean R / G / B | "
          + " | ".join(" / ".join(f"{c:.1f}" for c in v[2]) for v in sides.values()) + " |")
    for k, name in enumerate(("bottom band's colour noise: robust SD of high-passed R - G",
                              "bottom band's detail: robust SD of the high-passed grey",
                              "share of the pixels with green at 255 that are white")):
        print(f"| {name} | " + " | ".join(f"{v[3][k]:.2f}" for v in sides.values()) + " |")


if __name__ == "__main__":
    main()
