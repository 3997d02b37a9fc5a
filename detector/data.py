"""Detector training data from any KITTI-format root (ours or real KITTI).

Classes follow thesis 000: Van is merged into Car; Pedestrian; Cyclist. Every other type
(Truck, Tram, Misc, Person_sitting, DontCare) is left out of training.
Images are decoded once and kept resized to the training scale, so an epoch costs only
augmentation and the network.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from detector.boxes import Letterbox
from kitti.dataset import KittiDataset
from kitti.labels import Object3D

CLASSES = ("Car", "Pedestrian", "Cyclist")
CLASS_MAP = {"Car": 0, "Van": 0, "Pedestrian": 1, "Cyclist": 2}


@dataclass
class Sample:
    """One training image at the working scale: image HxWx3 uint8 RGB, boxes (n,4) xyxy pixels, classes (n,)."""
    image: np.ndarray
    boxes: np.ndarray
    classes: np.ndarray


def labels_to_arrays(objects: list[Object3D]) -> tuple[np.ndarray, np.ndarray]:
    """KITTI objects -> (boxes (n,4) float64 xyxy, class ids (n,) int64) for the trained classes."""
    keep = [o for o in objects if o.type in CLASS_MAP]
    boxes = np.array([np.asarray(o.bbox, dtype=np.float64) for o in keep]).reshape(-1, 4)
    classes = np.array([CLASS_MAP[o.type] for o in keep], dtype=np.int64)
    return boxes, classes


class DetectionData:
    """Frames of one split of one or more roots (in order), cached at the scale that letterboxes
    them into `input_size` (w, h)."""

    def __init__(self, roots: str | Sequence[str], split: str | None, input_size: tuple[int, int],
                 progress: bool = True):
        self.roots = (roots,) if isinstance(roots, str) else tuple(roots)
        self.input_size = input_size
        self.samples: list[Sample] = []
        for root in self.roots:
            kitti = KittiDataset(root)
            ids = kitti.ids(split)
            if not ids:
                raise ValueError(f"{root}: split {split!r} has no frames")
            for fid in tqdm(ids, desc=f"loading {root}", disable=not progress, leave=False):
                img = kitti.image(fid)
                h, w = img.shape[:2]
                lb = Letterbox.fit(w, h, *input_size)
                boxes, classes = labels_to_arrays(kitti.labels(fid))
                resized = lb.apply(img)[lb.pad_y:lb.pad_y + lb.new_h, lb.pad_x:lb.pad_x + lb.new_w].copy()
                sx, sy = lb.scale
                self.samples.append(Sample(resized, boxes * np.array([sx, sy, sx, sy]), classes))

    def __len__(self) -> int:
        return len(self.samples)

    def box_sizes(self) -> np.ndarray:
        """(N,2) widths and heights of all training boxes at the working scale (for anchors)."""
        wh = [s.boxes[:, 2:] - s.boxes[:, :2] for s in self.samples if len(s.boxes)]
        return np.concatenate(wh) if wh else np.zeros((0, 2))
