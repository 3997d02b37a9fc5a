"""report.md and fidelity.json of a Comparison: the same numbers, for reading and for tools.
No timestamps and sorted, fixed layouts, so the same inputs give the same bytes."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np

from kitti.io import atomic_write_text

from .bootstrap import LEVEL, SEED
from .compare import Comparison, Row
from .images import (CANNY, HIGH_PASS_PX, KITTI_TRAINING_PIXEL_MEAN, KITTI_TRAINING_PIXEL_SD,
                     MIN_ROAD_PIXELS, NEAR_CAR_PX, ROAD_ROWS, ROAD_SURFACE_M, pooled_channels)
from .labels import CLASSES, KITTI_TRAINING_FRAMES, KITTI_TRAINING_LABELS
from .lidar import FAR_M, GROUND_M, NEAR_M
from .stats import DatasetStats

GROUPS = (("lidar", "LiDAR", "velodyne/"), ("images", "Images", "image_2/"),
          ("labels", "Labels", "label_2/"))

NOTES = f"""\
## How the numbers are measured

- Per-frame values are summarised by their median over frames; per-object values (distance, 2D
  height, projection gap, points on a Car, the look of a near Car) by their median over objects.
  Histograms pool all frames.
- Range is sqrt(x^2 + y^2 + z^2) of the .bin points. Rings come from `kitti.rings.recover_rings(points, 64)`
  for both datasets; a ring's elevation is the median of atan2(z, sqrt(x^2 + y^2)) of its points.
- Ground returns: within {GROUND_M} m of the road plane fitted by RANSAC to the low returns
  (`lifter.ground.fit_ground_plane`, rectified camera frame). Near the sensor, the same share
  among the returns within {NEAR_M:.0f} m (bird's-eye), left (LiDAR y > 0) and right of it: what
  stands beside the car (parked or passing cars, walls, hedges) takes those returns from the road.
- Points on a Car: .bin points inside the label's 3D box (velo -> rect with the frame's calib),
  and the share of them whose reflectance is 0. A Car label's bottom above the road: its
  bottom-face centre's height above the road plane the lifter fits to the scan's road returns
  near it (`lifter.road.scan_road`). Far returns' reading: the median of the nonzero
  reflectance of the returns beyond {FAR_M[0]:.0f} m.
- Images are read with cv2; grey is cv2's BGR2GRAY; dI/dx is the forward difference along x;
  gradient magnitude is sqrt(dx^2 + dy^2) of forward differences; edges are Canny with thresholds
  {CANNY[0]} and {CANNY[1]}. The road's fine structure: in the bottom {ROAD_ROWS:.0%} of the rows,
  R - G and the grey less a Gaussian blur of {HIGH_PASS_PX:g} px, each read as 1.4826 x its median
  absolute deviation (a robust SD: lane paint and edges barely move it). Sensor noise moves both;
  a surface's colour grain at one brightness only the first. The road surface: the same two at
  the pixels (each once) that the scan's returns within {ROAD_SURFACE_M} m of the road plane
  project to with P2, by ground distance from camera 0 (rect x-z), in frames with at least
  {MIN_ROAD_PIXELS} such pixels in the band. PNG size: the decoded pixels encoded again, the
  Paeth filter on every row, run-length coding, zlib level 3 (one encoder for both datasets,
  whichever wrote their files).
- Objects are every label but DontCare. Projection gap: the label's 3D box corners projected with
  P2 and clipped to the image, max |side difference| against its 2D box.
- A near, whole Car: a Car label at least {NEAR_CAR_PX} px tall, truncation 0, occlusion 0; its
  look is read from the grey image inside its 2D box (sides rounded to pixel indices).
- Relative difference = (sim - real) / |real|; a statistic passes when its magnitude is at most the
  tolerance.
- 95 % interval: both datasets' frames resampled with replacement (a frame's objects travel with
  it), by drive where `--sim-drives` / `--real-drives` say which frames share one (a draw takes
  all of a drive's frames: frames seconds apart show the same street), every statistic
  recomputed, the draws above with a fixed seed; the central 95 % of the relative differences
  (`fidelity.bootstrap`). A verdict is decided when the whole interval lies on its side
  of the tolerance, undecided when more frames like these could turn it; n/a where the statistic
  has no value in more than 5 % of the draws (too few objects).
"""


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(f"{x:.6g}")


def _fmt(x: float) -> str:
    if not math.isfinite(x):
        return "n/a"
    return f"{x:,.0f}" if abs(x) >= 1000 else f"{x:.4g}"


def _rel(x: float | None) -> str:
    if x is None or math.isnan(x):
        return "n/a"
    return f"{x:+.1%}" if math.isfinite(x) else ("+inf" if x > 0 else "-inf")


def _table(rows: list[Row]) -> list[str]:
    out = ["| statistic | sim | real | relative difference | 95 % interval | verdict |",
           "|---|---:|---:|---:|---:|---|"]
    for r in rows:
        label = (f"{r.label} ({r.unit})" if r.unit else r.label).replace("|", "\\|")
        interval = "n/a" if r.interval is None else f"{_rel(r.interval.lo)} to {_rel(r.interval.hi)}"
        verdict = {"fail": "**fail**"}.get(r.verdict, r.verdict)
        decided = {True: "", False: ", undecided", None: ""}[r.decided]
        out.append(f"| {label} `{r.key}` | {_fmt(r.sim)} | {_fmt(r.real)} | {_rel(r.rel_diff)} | "
                   f"{interval} | {verdict} (±{r.tolerance:.0%}){decided} |")
    return out


def _side(d: DatasetStats) -> dict:
    return {"root": d.root, "split": d.split, "frames_read": len(d.frames),
            "frames_skipped": [{"id": fid, "error": err} for fid, err in d.skipped],
            "groups": d.groups}


def _per_ring(d: DatasetStats, key: str) -> list[float | None] | None:
    if key not in d.rows:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return [_num(v) for v in np.nanmedian(d.rows[key], axis=0)]


def to_json(comp: Comparison) -> dict:
    sides = {"sim": comp.sim, "real": comp.real}
    return {
        **{name: _side(d) for name, d in sides.items()},
        "tolerances": comp.tolerances.model_dump(),
        "statistics": {r.key: {"label": r.label, "unit": r.unit, "sim": _num(r.sim),
                               "real": _num(r.real), "rel_diff": _num(r.rel_diff),
                               "interval": None if r.interval is None
                               else [_num(r.interval.lo), _num(r.interval.hi)],
                               "tolerance": r.tolerance, "verdict": r.verdict, "decided": r.decided}
                       for r in comp.rows},
        "bootstrap": {"draws": comp.draws, "level": LEVEL, "seed": SEED,
                      "units": dict(zip(sides, comp.units))},
        "histograms": {key: {"edges": [_num(e) for e in comp.sim.hists[key].edges],
                             **{n: [_num(c) for c in d.hists[key].normalised()]
                                for n, d in sides.items()}} for key in comp.sim.hists},
        "rings": {k: {n: _per_ring(d, f"lidar.ring_{k}") for n, d in sides.items()}
                  for k in ("returns", "elevation_deg")},
        "pixels_by_channel": {
            **{n: None if (v := _pixels(d)) is None else
               {"mean": [_num(x) for x in v[0]], "sd": [_num(x) for x in v[1]]} for n, d in sides.items()},
            "kitti_training_set": {"mean": list(KITTI_TRAINING_PIXEL_MEAN),
                                   "sd": list(KITTI_TRAINING_PIXEL_SD)}},
        "objects_per_frame_by_class": {
            **{n: None if (v := _per_frame_by_class(d)) is None else dict(zip(CLASSES, map(_num, v)))
               for n, d in sides.items()},
            "kitti_training_set": {c: KITTI_TRAINING_LABELS[c] / KITTI_TRAINING_FRAMES
                                   for c in CLASSES}},
    }


def _decided_fails(comp: Comparison) -> str:
    """The decided fails by the size of their difference: where the generator is surely off."""
    rows = sorted((r for r in comp.rows if r.verdict == "fail" and r.decided),
                  key=lambda r: -abs(r.rel_diff) if r.rel_diff is not None else -math.inf)
    return ", ".join(f"`{r.key}` ({_rel(r.rel_diff)})" for r in rows)


def _units(frames: int, units: int) -> str:
    """What one side's bootstrap draws resample."""
    return "frames" if units == frames else f"{units} drives"


def _header(comp: Comparison) -> list[str]:
    sim, real = comp.sim, comp.real
    counts = {v: sum(r.verdict == v for r in comp.rows) for v in ("pass", "fail", "n/a")}
    decided = {v: sum(r.verdict == v and r.decided is True for r in comp.rows) for v in ("pass", "fail")}
    undecided = sum(r.decided is False for r in comp.rows)
    skipped = [f"- {n} {fid}: {err}" for n, d in (("sim", sim), ("real", real))
               for fid, err in d.skipped]
    return [
        "# Fidelity: sim vs real", "",
        "| | sim | real |", "|---|---|---|",
        f"| root | `{sim.root}` | `{real.root}` |",
        f"| split | {sim.split or 'every frame with an image'} | "
        f"{real.split or 'every frame with an image'} |",
        f"| frames read | {len(sim.frames)} | {len(real.frames)} |",
        *([f"| drawn as | {_units(len(sim.frames), comp.units[0])} | "
           f"{_units(len(real.frames), comp.units[1])} |"] if comp.draws else []), "",
        f"Verdicts: {counts['pass']} pass, {counts['fail']} fail, {counts['n/a']} n/a "
        f"(relative tolerance, default ±{comp.tolerances.default:.0%}).", "",
        *([f"Decided by these frames (the whole {LEVEL:.0%} bootstrap interval, {comp.draws} draws, on "
           f"the verdict's side of the tolerance): {decided['pass']} pass, {decided['fail']} fail; "
           f"{undecided} undecided.", ""] if comp.draws else []),
        *([f"Decided fails, largest first: {_decided_fails(comp)}.", ""] if decided["fail"] else []),
        f"frames skipped: {len(sim.skipped) + len(real.skipped)}", *skipped, ""]


def _group(comp: Comparison, group: str, title: str, folder: str) -> list[str]:
    out = [f"## {title}", ""]
    for name, d in (("sim", comp.sim), ("real", comp.real)):
        if not d.groups[group]:
            out += [f"{title}: absent in {name} (no {folder}).", ""]
    if group == "lidar":
        share = {n: np.mean(d.get("lidar.ring_by_azimuth")) if len(d.get("lidar.ring_by_azimuth"))
                 else float("nan") for n, d in (("sim", comp.sim), ("real", comp.real))}
        out += [f"Rings recovered from azimuth wraps in {_fmt(100 * share['sim'])} % of sim frames "
                f"and {_fmt(100 * share['real'])} % of real frames (the rest by elevation k-means).", ""]
    rows = [r for r in comp.rows if r.key.startswith(group + ".")]
    out += _table(rows)
    if group == "images":
        out += [""] + _pixel_table(comp)
    if group == "labels":
        out += [""] + _class_table(comp)
    return out + ["", f"![{group}]({group}.png)", ""]


def _pixels(d: DatasetStats) -> tuple[np.ndarray, np.ndarray] | None:
    rows = d.rows.get("images.channel_sums")
    return pooled_channels(rows) if rows is not None and len(rows) else None


def _pixel_table(comp: Comparison) -> list[str]:
    """Channel means and SDs over every pixel of every frame, beside the whole KITTI training
    set's (the figures the camera's tone and colour balance were set from)."""
    sides = [_pixels(comp.sim), _pixels(comp.real), (KITTI_TRAINING_PIXEL_MEAN, KITTI_TRAINING_PIXEL_SD)]
    out = ["Every pixel of every frame, R / G / B, beside the whole KITTI object training set's "
           f"({KITTI_TRAINING_FRAMES:,} images):", "",
           "| over every pixel | sim | real | KITTI training set |", "|---|---:|---:|---:|"]
    for k, name in enumerate(("channel means", "channel SDs")):
        cells = ["n/a" if v is None else " / ".join(f"{x:.1f}" for x in v[k]) for v in sides]
        out.append(f"| {name} | {' | '.join(cells)} |")
    return out


def _per_frame_by_class(d: DatasetStats) -> np.ndarray | None:
    rows = d.rows.get("labels.class_counts")
    return rows.mean(axis=0) if rows is not None and len(rows) else None


def _class_table(comp: Comparison) -> list[str]:
    """Objects a frame by class (mean over frames) beside the whole KITTI training set's."""
    sim, real = _per_frame_by_class(comp.sim), _per_frame_by_class(comp.real)
    out = ["Objects a frame by class (mean over frames), beside the whole KITTI object training set "
           f"({KITTI_TRAINING_FRAMES:,} frames: its label counts over its frames):", "",
           "| class | sim | real | KITTI training set |", "|---|---:|---:|---:|"]
    for i, cls in enumerate(CLASSES):
        cells = [_fmt(float(v[i])) if v is not None else "n/a" for v in (sim, real)]
        out.append(f"| {cls} | {cells[0]} | {cells[1]} | "
                   f"{_fmt(KITTI_TRAINING_LABELS[cls] / KITTI_TRAINING_FRAMES)} |")
    dontcare = [_fmt(float(np.mean(d.get("labels.dontcare")))) if len(d.get("labels.dontcare"))
                else "n/a" for d in (comp.sim, comp.real)]
    out.append(f"| DontCare regions | {dontcare[0]} | {dontcare[1]} | "
               f"{_fmt(KITTI_TRAINING_LABELS['DontCare'] / KITTI_TRAINING_FRAMES)} |")
    return out


def write_report(comp: Comparison, out_dir: str | Path) -> None:
    """report.md, fidelity.json, lidar.png, images.png, labels.png, frames.png in out_dir."""
    from .plots import write_plots

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figures = write_plots(comp, out_dir)
    atomic_write_text(out_dir / "fidelity.json",
                      json.dumps(to_json(comp), indent=1, allow_nan=False) + "\n")
    lines = _header(comp)
    for group, title, folder in GROUPS:
        lines += _group(comp, group, title, folder)
        if group == "images" and "frames.png" in figures:
            lines += ["The first frames of each side, generated and real alternating:", "",
                      "![frames](frames.png)", ""]
    atomic_write_text(out_dir / "report.md", "\n".join(lines + [NOTES]))
