"""A tiny KITTI-format dataset of coloured rectangles on noise: exact boxes by construction, for
tests and smoke runs of the detector without the scene generator."""
from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np

from kitti.io import atomic_path
from kitti.labels import Object3D, write_label
from kitti.splits import write_split

# type -> (RGB colour, width range, height range) in pixels
TOY_CLASSES = {
    "Car": ((220, 40, 40), (30, 60), (18, 32)),
    "Pedestrian": ((40, 200, 40), (8, 14), (24, 40)),
    "Cyclist": ((40, 60, 220), (16, 26), (24, 38)),
}


def toy_object(kind: str, bbox) -> Object3D:
    """A 2D-only label row (3D fields as the format's placeholders)."""
    return Object3D(kind, 0.0, 0, -10.0, np.asarray(bbox, dtype=float), -1.0, -1.0, -1.0,
                    np.array([-1000.0, -1000.0, -1000.0]), -10.0)


def make_toy_frame(rng: np.random.Generator, size: tuple[int, int], max_objects: int = 3):
    """(image HxWx3 uint8, objects): non-overlapping solid rectangles on dim noise."""
    w, h = size
    img = rng.integers(0, 60, size=(h, w, 3), dtype=np.uint8)
    objects: list[Object3D] = []
    taken = np.zeros((h, w), dtype=bool)
    kinds = list(TOY_CLASSES)
    first = int(rng.integers(len(kinds)))
    for n in range(int(rng.integers(1, max_objects + 1))):
        kind = kinds[(first + n) % len(kinds)]  # classes in turn: every class is well represented
        colour, (w0, w1), (h0, h1) = TOY_CLASSES[kind]
        for _attempt in range(20):
            bw, bh = int(rng.integers(w0, w1 + 1)), int(rng.integers(h0, h1 + 1))
            x1, y1 = int(rng.integers(0, w - bw)), int(rng.integers(0, h - bh))
            if not taken[max(y1 - 2, 0):y1 + bh + 2, max(x1 - 2, 0):x1 + bw + 2].any():
                taken[y1:y1 + bh, x1:x1 + bw] = True
                img[y1:y1 + bh, x1:x1 + bw] = colour
                objects.append(toy_object(kind, [x1, y1, x1 + bw, y1 + bh]))
                break
    return img, objects


def write_toy_dataset(root: str | Path, frames: int, seed: int, size: tuple[int, int] = (256, 96),
                      val_frames: int = 0, max_objects: int = 3) -> Path:
    """Write frames 000000.. under root/training with ImageSets train (first) and val (last val_frames)."""
    root = Path(root)
    rng = np.random.default_rng(seed)
    ids = [f"{i:06d}" for i in range(frames)]
    for fid in ids:
        img, objects = make_toy_frame(rng, size, max_objects)
        with atomic_path(root / "training" / "image_2" / f"{fid}.png") as tmp:
            iio.imwrite(tmp, img, extension=".png")
        write_label(root / "training" / "label_2" / f"{fid}.txt", objects)
    write_split(root / "ImageSets" / "train.txt", ids[:frames - val_frames] if val_frames else ids)
    write_split(root / "ImageSets" / "val.txt", ids[frames - val_frames:] if val_frames else ids)
    return root
