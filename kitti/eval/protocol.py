"""The rules of the official KITTI object evaluation (devkit `evaluate_object.cpp`), as data.

Which truth counts, which is ignored, which detection may be a false positive: `clean` mirrors the
devkit's `cleanData` line by line, vectorised over all objects of all frames at once. Its odd corners
are kept on purpose, because users compare our numbers with published ones:
- a truth box is too small when its height is < the minimum (the devkit's C++; the popular Python
  port uses <=, so a 40.0 px Car is evaluated in easy here and ignored there), a detection when its
  height, truncated to an integer, is < the minimum;
- the height rule on detections comes first and applies to every class, so a small detection of
  another class is "ignored" (1), not "other class" (-1): it may still absorb a truth box;
- Van is the neighbour of Car and Person_sitting of Pedestrian: such truth is ignored, such
  detections are of another class;
- difficulties are not disjoint: each level keeps every object that passes its own (looser) limits,
  so moderate counts the easy objects too and hard counts both.
"""

from __future__ import annotations

import numpy as np

DIFFICULTIES = ("easy", "moderate", "hard")
MIN_HEIGHT = (40, 25, 25)  # px, an int array in the devkit
MAX_OCCLUSION = (0, 1, 2)
MAX_TRUNCATION = (0.15, 0.30, 0.50)
N_SAMPLE_PTS = 41
METRICS = ("2d", "bev", "3d", "aos")

# neighbouring classes: truth of the neighbour is ignored, never a miss
NEIGHBOUR = {"car": "van", "pedestrian": "person_sitting"}

# IoU thresholds per class and metric (2D, bird's-eye, 3D). Car/Pedestrian/Cyclist are the devkit's;
# Van/Truck/Tram and Person_sitting are our extension for the testbed's extra classes, set like
# the class they resemble.
STRICT = {"car": 0.7, "pedestrian": 0.5, "cyclist": 0.5,
          "van": 0.7, "truck": 0.7, "tram": 0.7, "person_sitting": 0.5}
LOOSE = {"car": 0.5, "pedestrian": 0.25, "cyclist": 0.25,
         "van": 0.5, "truck": 0.5, "tram": 0.5, "person_sitting": 0.25}


def min_overlap(cls: str, metric: str, loose: bool = False) -> float:
    """IoU a match must exceed. The loose set changes only bird's-eye and 3D (2D stays strict)."""
    key = cls.lower()
    if key not in STRICT:
        raise ValueError(f"class '{cls}' has no IoU threshold; known: {', '.join(sorted(STRICT))}")
    return (LOOSE if loose and metric in ("bev", "3d") else STRICT)[key]


def outside_difficulty(height_px, occluded, truncated, difficulty: int):
    """Whether truth boxes (arrays or scalars) are too small, occluded or truncated for a
    difficulty (0 easy, 1 moderate, 2 hard): what the evaluation ignores."""
    return ((np.asarray(occluded) > MAX_OCCLUSION[difficulty])
            | (np.asarray(truncated) > MAX_TRUNCATION[difficulty])
            | (np.asarray(height_px) < MIN_HEIGHT[difficulty]))


def clean(cls: str, difficulty: int, gt_type: np.ndarray, gt_bbox: np.ndarray, gt_occ: np.ndarray,
          gt_trunc: np.ndarray, dt_type: np.ndarray, dt_bbox: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray]:
    """(ignored_gt, ignored_det) as int8: 0 evaluated, 1 ignored, -1 other class (skipped).

    Types must be lower-case (the devkit compares with strcasecmp); DontCare rows are not passed.
    """
    c = cls.lower()
    nb = NEIGHBOUR.get(c)
    valid = np.where(gt_type == c, 1, np.where(gt_type == nb, 0, -1)) if nb else \
        np.where(gt_type == c, 1, -1)
    ignore = outside_difficulty(gt_bbox[:, 3] - gt_bbox[:, 1], gt_occ, gt_trunc, difficulty)
    ig_gt = np.where((valid == 1) & ~ignore, 0,
                     np.where((valid == 0) | ((valid == 1) & ignore), 1, -1)).astype(np.int8)
    dt_height = np.trunc(np.abs(dt_bbox[:, 1] - dt_bbox[:, 3]))  # int32_t in the devkit
    ig_dt = np.where(dt_height < MIN_HEIGHT[difficulty], 1,
                     np.where(dt_type == c, 0, -1)).astype(np.int8)
    return ig_gt, ig_dt


def restrict(ig_gt: np.ndarray, ig_dt: np.ndarray, gt_in: np.ndarray, dt_in: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """Ignore (not delete) evaluated truth and detections outside a subset, e.g. a distance bin.

    Outside objects behave like the devkit's too-small ones: a detection matched to outside truth
    is no false positive, and outside detections are never false positives.
    """
    ig_gt = np.where((ig_gt == 0) & ~gt_in, 1, ig_gt).astype(np.int8)
    ig_dt = np.where((ig_dt == 0) & ~dt_in, 1, ig_dt).astype(np.int8)
    return ig_gt, ig_dt
