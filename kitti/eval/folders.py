"""Evaluate a result folder against a label folder: the file-level entry `testbed evaluate` and
the pipelines share."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from ..splits import read_split
from .annotations import load_annotations
from .evaluate import evaluate
from .report import EvalResult
from .volumetric import DEFAULT_MAX_DISTANCE

CLASSES = ("Car", "Pedestrian", "Cyclist")


def load_folders(gt_dir: Path, pred_dir: Path, split: Path | None = None,
                 progress: bool = True) -> tuple[dict, dict]:
    """{id: truth} of every label file (or of the split's frames) and {id: detections} of the
    result files of the same ids (a missing file: no detections)."""
    ids = read_split(split) if split else None
    gt = load_annotations(gt_dir, ids, progress=progress)
    if not gt:
        raise ValueError(f"{gt_dir}: no label files")
    return gt, load_annotations(pred_dir, list(gt), missing_ok=True, progress=progress)


def evaluate_folders(gt_dir: Path, pred_dir: Path, split: Path | None = None,
                     classes: Sequence[str] = CLASSES, range_bins: Sequence[float] | None = None,
                     match_iou: float = 0.5, min_score: float | None = None,
                     max_distance: float = DEFAULT_MAX_DISTANCE,
                     progress: bool = True) -> EvalResult:
    """Truth of every label file (or the frames of an ImageSets `split` file) against the result
    files of the same ids; a missing result file is a frame with no detections."""
    gt, dt = load_folders(gt_dir, pred_dir, split, progress)
    return evaluate(gt, dt, classes=list(classes), range_bins=range_bins, progress=progress,
                    match_iou=match_iou, min_score=min_score, max_distance=max_distance)
