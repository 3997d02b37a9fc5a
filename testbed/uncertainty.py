"""How sure a sweep's report is: every AP with its 95 % interval over bootstrap draws of the
frames, and every comparison the sweep exists for as a paired per-object change against a
reference point, over the same draws.

Draws: the frames of the scene's split, with replacement (`kitti.eval.bootstrap.draw_frames`);
whole drives where the scene's generated data holds a drives file (DRIVES_FILE, read by
`kitti.drives`: frames of one drive show the same cars). The seed is `kitti.eval.bootstrap`'s and
every point of a scene takes the same draws, so the AP intervals and the paired changes read the
same draws and the same inputs give the same bytes.

DRAWS: a draw re-scores every AP of a point, overall and per distance bin, each class with truth
and each metric (`kitti.eval.intervals`): about 0.12 s on one core for 100 val frames, three
classes and nine bins, nearly all of it the evaluation's fixed cost per precision curve (0.09 s on
5 frames and six bins). So 200 draws add about 14 CPU minutes to the 34-point reference sweep (7
on its 2 workers) and 1000 would add 70 (35). At 200 an interval's ends are the 5th and 196th of
the ordered draws and move from one seed to another by about a fifth of the statistic's standard
error (0.09 at 1000): that flips `decided` only for a change whose interval ends that close to
zero. `testbed sweep --draws` sets more.

Reference point (`comparisons`): along each axis, a point is compared with the point that has
that axis at its first listed value and every other axis as it is. A dropped-ring scan, which
exists only below 64 beams, is compared along `beams` with the 64-beam scan its rings are
kept from when the first listed count is not dropped to (the reference sweep lists 128 first). An
image-only method has no LiDAR axes; along `method` it is compared with the first method on the
reference scan (every LiDAR axis at its first value).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from kitti.drives import drawn, read_drives
from kitti.eval.bootstrap import SEED, central_interval, draw_frames
from kitti.eval.breakdown import bin_index
from kitti.eval.folders import load_folders
from kitti.eval.intervals import drawn_evaluations
from kitti.eval.paired import Change, TruthOverlaps, frame_counts, paired_change, truth_overlaps
from kitti.eval.protocol import DIFFICULTIES, min_overlap
from kitti.jobs import Backend
from lifter.methods import METHODS

from .sweep import Plan, Point, ScanConfig

DRAWS = 200
DRIVES_FILE = "drives.txt"  # `FRAME_ID DRIVE` lines in a scene's generated data (kitti.drives)
SCAN_AXES = {"lidar": "lidar", "beams": "beams", "beam_mode": "mode", "max_range": "max_range",
             "weather": "weather"}  # spec axis: ScanConfig field
AXES = (*SCAN_AXES, "method", "boxes")

APKey = tuple[str, str, str, str, str]  # iou, class, metric, difficulty, range_m
Interval = tuple[float, float] | None


def range_label(lo: float, hi: float | None) -> str:
    """'20-40', or '80+' for the open-ended last bin (its edge is null in the JSON)."""
    return f"{lo:g}+" if hi is None or not math.isfinite(hi) else f"{lo:g}-{hi:g}"


def ap_values(ev: dict) -> dict[APKey, tuple]:
    """Every AP of an evaluation's JSON (`kitti.eval`, or one draw of `kitti.eval.intervals`)
    keyed as metrics.csv lists it, (iou, class, metric, difficulty, range_m): (AP|R40, AP|R11,
    AP|R40 on the measured recall, truth boxes); overall at the strict and loose thresholds, then
    per distance bin (strict), None where a bin holds no truth."""
    out: dict[APKey, tuple] = {}
    none = [None] * 3
    measured = ev.get("ap_r40_measured_recall", {})
    for iou, table in (("strict", ev["ap"]), ("loose", ev.get("ap_loose", {}))):
        for cls, per_metric in table.items():
            n_gt = ev.get("n_gt", {}).get(cls, [""] * 3)
            for metric, ap in per_metric.items():
                m = measured.get(cls, {}).get(iou, {}).get(metric, none)
                for i, d in enumerate(DIFFICULTIES):
                    out[iou, cls, metric, d, "all"] = (ap["R40"][i], ap["R11"][i], m[i], n_gt[i])
    for b in (ev.get("range_bins") or {}).get("bins", []):
        label = range_label(*b["range"])
        for cls, per_metric in b["ap"].items():
            for metric, ap in per_metric.items():
                m = b.get("ap_r40_measured", {}).get(cls, {}).get(metric, none)
                for i, d in enumerate(DIFFICULTIES):
                    out["strict", cls, metric, d, label] = (ap["R40"][i], ap["R11"][i], m[i],
                                                            b["n_gt"][cls][i])
    return out


@dataclass(frozen=True)
class DrawJob:
    """One point's bootstrap: its truth, lifted boxes and split, scored as the sweep scored them."""

    labels: Path
    pred: Path
    split: Path
    classes: tuple[str, ...]
    metrics: tuple[str, ...]
    range_bins: tuple[float, ...]
    draws: int
    drives: Mapping[str, str] | None


@dataclass(frozen=True)
class PointDraws:
    """A point's AP intervals (AP|R40, AP|R11, AP|R40 on the measured recall; None where no draw
    holds truth) by `ap_values` key, and its truth objects scored per class (moderate)."""

    ids: list[str]
    intervals: dict[APKey, tuple[Interval, Interval, Interval]]
    truth: dict[str, TruthOverlaps]


def _interval(values: np.ndarray) -> Interval:
    """The central 95 % of the draws that define the value (a bin some draws leave empty)."""
    v = values[~np.isnan(values)]
    return central_interval(v) if len(v) else None


def draw_point(job: DrawJob) -> PointDraws:
    """The backend job: every AP of the point on each draw, reduced to its interval, and the
    per-object scores the paired changes read."""
    gt, dt = load_folders(job.labels, job.pred, job.split, progress=False)
    ids = sorted(gt)
    draws = draw_frames(ids, job.draws, SEED, job.drives)
    values: dict[APKey, np.ndarray] = {}
    for d, ev in enumerate(drawn_evaluations(gt, dt, draws, job.classes, job.metrics, job.range_bins)):
        for key, (*aps, n) in ap_values(ev).items():
            if n:  # a difficulty or bin the draw leaves without truth has no AP
                row = values.setdefault(key, np.full((job.draws, 3), np.nan))
                row[d] = [np.nan if v is None else v for v in aps]
    intervals = {k: (_interval(v[:, 0]), _interval(v[:, 1]), _interval(v[:, 2])) for k, v in values.items()}
    return PointDraws(ids, intervals, {c: truth_overlaps(gt, dt, c) for c in job.classes})


def _reference_scan(p: Plan) -> ScanConfig | None:
    """Every LiDAR axis at its first value, or the plan's first scan where that is not scanned."""
    ax = p.spec.axes
    if not p.scans:
        return None
    first = ScanConfig(ax.lidar[0], ax.beams[0], ax.beam_mode[0], ax.max_range[0], ax.weather[0])
    return first if first in p.scans else p.scans[0]


def reference(p: Plan, pt: Point, axis: str) -> Point | None:
    """The point `pt` is compared with along `axis` (module docstring); None where it has none
    (an image-only method along a LiDAR axis, or no such point in the plan)."""
    if axis in SCAN_AXES and pt.scan is None:
        return None
    first = getattr(p.spec.axes, axis)[0]
    if axis in SCAN_AXES:
        scan = dataclasses.replace(pt.scan, **{SCAN_AXES[axis]: first})
        if axis == "beams" and pt.scan.mode == "dropped" and scan not in p.scans:
            scan = pt.scan.parent()
        ref = dataclasses.replace(pt, scan=scan)
    elif axis == "method":
        scan = (pt.scan or _reference_scan(p)) if METHODS[first].needs_scan else None
        ref = Point(pt.scene, scan, first, pt.boxes)
    else:
        ref = dataclasses.replace(pt, boxes=first)
    return ref if ref in p.points else None


def comparisons(p: Plan) -> list[tuple[str, Point, Point]]:
    """(axis, point, reference) for every point and axis with a reference other than itself, by
    axis, then in the plan's order."""
    out = []
    for axis in AXES:
        for pt in p.points:
            ref = reference(p, pt, axis)
            if ref is not None and ref != pt:
                out.append((axis, pt, ref))
    return out


@dataclass(frozen=True)
class PairedChange:
    """One measure of one class's truth objects (within a distance bin, or "all") at `point`
    against `reference`, which differs from it along `axis`: the means at both and the change."""

    axis: str
    point: Point
    reference: Point
    cls: str
    measure: str
    range_m: str
    value: float
    reference_value: float
    change: Change


def measures(cls: str, iou: np.ndarray) -> dict[str, np.ndarray]:
    """Per object: the 3D IoU and whether it passes the class's strict and loose 3D thresholds
    (Car 0.7 and 0.5), whose shares AP counts."""
    strict, loose = min_overlap(cls, "3d"), min_overlap(cls, "3d", loose=True)
    return {"mean_iou_3d": iou, f"share_above_{strict:g}": (iou > strict).astype(float),
            f"share_above_{loose:g}": (iou > loose).astype(float)}


def paired_changes(p: Plan, points: Mapping[Point, PointDraws],
                   counts: Mapping[str, np.ndarray]) -> list[PairedChange]:
    """Every comparison (`comparisons`) of every class with truth, over all distances and per
    distance bin of the spec (by the truth's ground distance, as AP's bins), each change with its
    interval over the scene's draws (`counts`)."""
    edges = np.asarray(p.spec.range_bins, dtype=float)
    out = []
    for axis, pt, ref in comparisons(p):
        for cls, a in points[pt].truth.items():
            b = points[ref].truth[cls]
            if not a.same_truth(b):
                raise ValueError(f"{pt.key} and {ref.key} hold different {cls} truth: the points "
                                 "of a sweep share their labels")
            k = bin_index(a.distance, edges)
            bins = [("all", np.ones(len(k), bool))] + [
                (range_label(edges[i], edges[i + 1]), k == i) for i in range(len(edges) - 1)]
            ma, mb = measures(cls, a.iou), measures(cls, b.iou)
            for label, sel in bins:
                if not sel.any():
                    continue
                for name in ma:
                    x, y = ma[name][sel], mb[name][sel]
                    out.append(PairedChange(axis, pt, ref, cls, name, label, float(x.mean()),
                                            float(y.mean()),
                                            paired_change(x, y, a.frame[sel], counts[pt.scene])))
    return out


@dataclass(frozen=True)
class Uncertainty:
    """What `measure` found: the draw count, what a draw resamples per scene, each point's
    intervals and scored truth, and the paired changes."""

    draws: int
    units: dict[str, str]
    points: dict[Point, PointDraws]
    changes: list[PairedChange]


def scene_drives(data: Path) -> dict[str, str] | None:
    """Which frames of a scene's generated data share a drive, where its DRIVES_FILE says."""
    f = data / DRIVES_FILE
    return read_drives(f) if f.is_file() else None


def measure(p: Plan, results: list[tuple[Point, dict]], backend: Backend,
            draws: int = DRAWS) -> Uncertainty:
    """Bootstrap every evaluated point of an executed plan on `backend` (one job a point) and
    pair the points along every axis."""
    generator, models = p.versions  # the folders `execute` wrote
    drives = {pt.scene: scene_drives(p.base_dir(pt.scene, generator)) for pt, _ in results}
    jobs = []
    for pt, ev in results:
        data = p.data_dir(pt, generator)
        # a class without truth has no AP interval (no draw holds any): its draws are not made
        with_truth = tuple(c for c in ev["settings"]["classes"] if any(ev["n_gt"][c]))
        jobs.append(DrawJob(data / "training" / "label_2", p.point_dir(pt, generator, models) / "pred",
                            data / "ImageSets" / f"{p.spec.split}.txt", with_truth,
                            tuple(ev["settings"]["metrics"]), tuple(p.spec.range_bins), draws,
                            drives[pt.scene]))
    points = dict(zip([pt for pt, _ in results], backend.map(draw_point, jobs, desc="bootstrap")))
    ids = {pt.scene: d.ids for pt, d in points.items()}
    counts = {s: frame_counts(draw_frames(i, draws, SEED, drives[s]), len(i)) for s, i in ids.items()}
    units = {s: drawn(i, drives[s]) for s, i in ids.items()}
    return Uncertainty(draws, units, points, paired_changes(p, points, counts))
