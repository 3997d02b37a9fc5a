"""Label statistics of one label_2 file: what is labelled, how far, how hidden, how big, and
whether each 2D box agrees with its own 3D box (real KITTI dev frames: 0.84 px median gap)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from kitti.boxes import project_boxes
from kitti.calib import Calibration
from kitti.dataset import KittiDataset
from kitti.labels import Object3D, boxes7

from .stats import Acc

# The KITTI object classes (DontCare regions are not objects); other types are counted in no class.
CLASSES = ("Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc")
# The whole KITTI object training set: labels per class in its 7,481 label_2 files (the same counts
# in every independent tally of the official release). The real dev frames are 11 of them; these
# say what a frame holds on average over the whole set.
KITTI_TRAINING_FRAMES = 7481
KITTI_TRAINING_LABELS = {"Car": 28742, "Van": 2914, "Truck": 1094, "Pedestrian": 4487,
                         "Person_sitting": 222, "Cyclist": 1627, "Tram": 511, "Misc": 973,
                         "DontCare": 11295}


def label_stats(acc: Acc, labels: list[Object3D], calib: Calibration,
                size: tuple[int, int]) -> None:
    """Per-frame counts and per-object values; DontCare regions are left out."""
    objs = [o for o in labels if o.type != "DontCare"]
    acc.put("labels.objects", len(objs))
    acc.put("labels.cars", sum(o.type == "Car" for o in objs))
    acc.put("labels.dontcare", len(labels) - len(objs))
    acc.row("labels.class_counts", [sum(o.type == c for o in objs) for c in CLASSES])
    loc = np.array([o.location for o in objs]).reshape(-1, 3)
    per_object = {
        "labels.distance_m": np.hypot(loc[:, 0], loc[:, 2]),
        "labels.occlusion": [o.occluded for o in objs],
        "labels.truncation": [o.truncated for o in objs],
        "labels.box_height_px": [o.height_px for o in objs],
        "labels.proj_gap_px": projection_gaps(objs, calib, size),
    }
    for key, v in per_object.items():
        acc.put(key, v)
        acc.hist(key, np.asarray(v, np.float64))


def projection_gaps(objs: list[Object3D], calib: Calibration, size: tuple[int, int]) -> np.ndarray:
    """Per object with a 3D box: max |side difference| (px) between its 2D box and the image box
    of its 3D box's corners projected with P2 and clipped to the image (width, height)."""
    boxed = [o for o in objs if min(o.h, o.w, o.l) > 0 and o.location[1] > -1000]
    if not boxed:
        return np.zeros(0)
    proj = project_boxes(boxes7(boxed), calib, size)
    gap = np.abs(proj - np.array([o.bbox for o in boxed])).max(axis=1)
    return gap[np.isfinite(gap)]


def box_projections(ds: KittiDataset, classes: tuple[str, ...]
                    ) -> Iterator[tuple[Object3D, np.ndarray, np.ndarray]]:
    """Each untruncated label of `classes` in the dataset with the two projections of its 3D box:
    the label box's own and the box stood upright in the LiDAR's frame, which is how KITTI's 2D
    boxes were made (`kitti.boxes.lidar_upright_corners`)."""
    for fid in ds.ids():
        objs = [o for o in ds.labels(fid) if o.type in classes and o.truncated == 0]
        if not objs:
            continue
        b7, calib, size = boxes7(objs), ds.calib(fid), ds.image_size(fid)
        own, lidar = project_boxes(b7, calib, size), project_boxes(b7, calib, size, upright="lidar")
        yield from zip(objs, own, lidar)
