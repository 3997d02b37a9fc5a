"""Lift a dataset split: 2D boxes (labels or detection files) -> complete KITTI result lines, one
file per frame of the split (an empty file where nothing is found, or where a detection folder
has no file for the frame)."""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.boxes import alpha_from_rotation_y, project_boxes
from kitti.calib import Calibration
from kitti.dataset import KittiDataset
from kitti.errors import KittiFormatError
from kitti.labels import Object3D, read_label, write_label

from .methods import Frame, get_method
from .types import LABEL_SIDE_SIGMA_PX, Box2D, Prior

# Oracle boxes: every labelled road user. The evaluation scores Car/Pedestrian/Cyclist and ignores
# their neighbour classes (Van, Person_sitting); lifting the other vehicles too costs nothing there
# and lets `fit` claim their returns, so a van in front is not mistaken for the car behind it.
ORACLE_CLASSES = ("Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram")
OUTLINE_GAP = 0.015   # share of the 2D box's height between its bottom and the projected 3D box's
                      # above which the labels outline silhouettes (KITTI 0.8 %, silhouettes 2.5 %)
OUTLINE_SAMPLE = 30   # labelled vehicles enough to tell
# A sweep lifts the same frames from the same 2D boxes at every scan configuration and with every
# LiDAR method (18 times over in the reference sweep); the network's priors depend on the image,
# the boxes and the weights alone, so a process computes them once per frame and set of boxes.
PRIOR_CACHE = 4096    # frames' priors a process keeps, least recently used dropped first
_priors: OrderedDict = OrderedDict()


def oracle_boxes(labels: list[Object3D], classes=ORACLE_CLASSES) -> list[Box2D]:
    """The label_2 boxes of the road users, score 1."""
    return [Box2D(o.type, o.bbox.copy(), 1.0) for o in labels if o.type in classes]


# The shipped detector's left and right box sides against the labels' (Car detections scoring 0.3
# or more matched to a Car or Van at 2D IoU 0.5 or more, Pedestrians and Cyclists likewise; 1,574,
# 117 and 24 sides): the Student-t fitted to their errors by maximum likelihood, (scale px, degrees
# of freedom), on 200 generated held-out frames (`scenes/urban.yaml` seed 5601 `val`;
# benchmarks/detector_sides.py). Most sides lie within a few pixels and a tail 10-35 px off, which
# the t's heavy tails let go (results/lifter.md). Another class takes the Car's.
SHIPPED_SIDE_ERRORS = {"Car": (2.75, 1.55), "Pedestrian": (2.22, 2.02), "Cyclist": (2.71, math.inf)}


def detection_side_sigma(side_sd: float | None = None) -> float:
    """The scale `fit` gives a detected box's left and right sides' errors: a label's own
    (LABEL_SIDE_SIGMA_PX) and the detector's `side_sd` (px: an sd, or a Student-t's scale) in
    quadrature."""
    return float(np.hypot(LABEL_SIDE_SIGMA_PX, side_sd or 0.0))


def read_detections(det_dir: Path, fid: str, side_sd: float | None = None,
                    side_dof: float | None = None) -> list[Box2D]:
    """The frame's detections; a frame without a file has none (a detector that writes only the
    frames where it found something, or an empty frame: the evaluation reads it the same way).
    Their sides' scale is `detection_side_sigma(side_sd)`, their errors Student-t with `side_dof`
    degrees of freedom (None: Gaussian); without `side_sd`, the shipped detector's
    (SHIPPED_SIDE_ERRORS)."""
    path = det_dir / f"{fid}.txt"
    if not path.exists():
        return []
    boxes = []
    for o in read_label(path):
        if o.type == "DontCare":
            continue
        if o.score is None:
            raise KittiFormatError("detection line without a score", path, None, "score")
        sd, dof = (SHIPPED_SIDE_ERRORS.get(o.type, SHIPPED_SIDE_ERRORS["Car"]) if side_sd is None
                   else (side_sd, math.inf if side_dof is None else float(side_dof)))
        boxes.append(Box2D(o.type, o.bbox.copy(), float(o.score), detection_side_sigma(sd), dof))
    return boxes


def truth_priors(boxes: list[Box2D], labels: list[Object3D]) -> list[Prior]:
    """Size and alpha of the label each box came from (same bbox): the 'oracle size' ablation."""
    out = []
    for b in boxes:
        match = [o for o in labels if np.allclose(o.bbox, b.bbox)]
        if not match:
            raise ValueError("--priors truth needs --boxes gt (a box matched no label)")
        o = match[0]
        out.append(Prior(np.array([o.h, o.w, o.l]), float(o.alpha)))
    return out


def box_outline(data: str | Path, detections: Path | None, ids: list[str] | None = None) -> str:
    """How the 2D boxes to lift outline their objects (`lifter.methods.OUTLINES`). Labels: as
    their files show it. KITTI's 2D box is the projection of the labelled 3D box stood upright in
    the LiDAR's frame (`kitti.boxes.lidar_upright_corners`; on the real dev frames the vehicles'
    sides lie a median 0.2 px from it); the generator wrote the rendered silhouette until it took
    up KITTI's convention (its bottom 2.4-2.7 % of the box's height above the projected one: the
    lowest point is a tyre's contact, not the box's bottom corner). The median of that share over
    the dataset's first untruncated vehicles decides, at OUTLINE_GAP. Detections outline what the
    detector was trained on: KITTI's boxes for a detector trained on KITTI, and the generator's
    since it took up KITTI's convention, on which the shipped FlexiNet (stage 7,
    `detector/weights/README.md`) was trained."""
    if detections is not None:
        return "box"
    ds = KittiDataset(data)
    gaps: list[float] = []
    for fid in (ids if ids is not None else ds.ids()):
        calib, size = ds.calib(fid), ds.image_size(fid)
        for o in ds.labels(fid):
            if o.type in ("Car", "Van", "Truck") and o.truncated <= 0.05 and o.height_px >= 25:
                bottom = project_boxes(o.box7[None], calib, size, upright="lidar")[0][3]
                gaps.append((bottom - o.bbox[3]) / o.height_px)
        if len(gaps) >= OUTLINE_SAMPLE:
            break
    return "silhouette" if gaps and float(np.median(gaps)) > OUTLINE_GAP else "box"


def lift_frame(method: str, boxes: list[Box2D], priors: list[Prior], calib: Calibration,
               image_size: tuple[int, int], velodyne: np.ndarray | None,
               plane_file: np.ndarray | None, outline: str = "silhouette") -> list[Object3D]:
    """One frame's 2D boxes as complete KITTI result lines (score = box score x lift quality)."""
    m = get_method(method)
    if not boxes:
        return []
    if m.needs_scan and velodyne is None:
        raise ValueError(f"method '{method}' needs velodyne/ scans")
    lifted = m.run(Frame(boxes, priors, calib, image_size, velodyne, plane_file, outline))
    out = []
    for b, lf in zip(boxes, lifted):
        x, _, z = lf.location
        h, w, l = lf.dims
        out.append(Object3D(b.type, -1.0, -1, float(alpha_from_rotation_y(lf.rotation_y, x, z)),
                            b.bbox, float(h), float(w), float(l), lf.location, lf.rotation_y,
                            score=float(b.score * lf.quality)))
    return out


def lift_dataset(data: str | Path, detections: Path | None, method: str, out: str | Path,
                 split: str | None, priors: str = "net", weights: str | Path | None = None,
                 progress: bool = True, mirror: bool = True, side_sd: float | None = None,
                 side_dof: float | None = None) -> int:
    """Write out/<id>.txt for every frame of the split; returns the number of 3D boxes written.

    `detections`: a folder of detection result files, or None for the labels' boxes (oracle).
    `mirror`: the size/orientation network also reads each crop mirrored (`lifter.predictor`).
    `side_sd`, `side_dof`: the scale (px) and Student-t degrees of freedom of the detections'
    left and right sides' errors (`benchmarks/detector_sides.py` fits both), which `fit` then
    weighs them by (`side_dof` None: Gaussian; `side_sd` 0: as a label's); `side_sd` None: the
    shipped detector's, SHIPPED_SIDE_ERRORS."""
    m = get_method(method)
    ds = KittiDataset(data)
    ids = ds.ids(split)
    det_dir = None if detections is None else Path(detections)
    if det_dir is not None and not det_dir.is_dir():
        raise KittiFormatError("detection folder not found", det_dir)
    if priors == "net":
        from .predictor import DEFAULT_WEIGHTS, Predictor
        predictor = Predictor(weights or DEFAULT_WEIGHTS, mirror=mirror)
    elif priors != "truth":
        raise ValueError(f"unknown priors '{priors}' (net or truth)")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    outline = box_outline(data, det_dir, ids)
    total = 0
    with tqdm(ids, desc=f"lift {method}", unit="frame", disable=not progress) as bar:
        for fid in bar:
            # everything of the frame is read before its result is written (atomically): a frame
            # that cannot be read stops the run with the file and field named, and the frames
            # written before it stay as they are
            labels = ds.labels(fid) if (det_dir is None or priors == "truth") else None
            b2d = oracle_boxes(labels) if det_dir is None else read_detections(det_dir, fid, side_sd, side_dof)
            if priors == "truth":
                pr = truth_priors(b2d, labels)
            else:
                pr = _net_priors(predictor, ds, fid, b2d) if b2d else []
            planes = ds.planes(fid)
            velo = ds.velodyne(fid) if m.loads_scan(planes is not None) else None
            objs = lift_frame(method, b2d, pr, ds.calib(fid), _image_size(ds, fid), velo, planes,
                              outline)
            write_label(out / f"{fid}.txt", objs)
            total += len(objs)
    return total


def _net_priors(predictor, ds: KittiDataset, fid: str, boxes: list[Box2D]) -> list[Prior]:
    """The predictor's priors for the frame's boxes, computed once per process for the same
    image bytes, boxes and weights (`PRIOR_CACHE`); each call gets its own copies."""
    try:
        image_hash = hashlib.sha256(ds.image_path(fid).read_bytes()).digest()
    except OSError as e:
        raise KittiFormatError(f"unreadable image ({e})", ds.image_path(fid), None, "image") from None
    key = (predictor.key, image_hash, tuple((b.type, *b.bbox.tolist()) for b in boxes))
    priors = _priors.get(key)
    if priors is None:
        priors = _priors[key] = predictor(_image(ds, fid), boxes)
        if len(_priors) > PRIOR_CACHE:
            _priors.popitem(last=False)
    else:
        _priors.move_to_end(key)
    return [Prior(p.dims.copy(), p.alpha) for p in priors]


def _image(ds: KittiDataset, fid: str) -> np.ndarray:
    try:
        return ds.image(fid)
    except (OSError, ValueError) as e:  # imageio's errors do not all name the file
        raise KittiFormatError(f"unreadable image ({e})", ds.image_path(fid), None,
                               "image") from None


def _image_size(ds: KittiDataset, fid: str) -> tuple[int, int]:
    try:
        return ds.image_size(fid)
    except (OSError, ValueError) as e:
        raise KittiFormatError(f"unreadable image ({e})", ds.image_path(fid), None,
                               "image") from None
