"""How far an AP measured on few frames can be trusted: the frames drawn again with replacement
(a frame's objects and detections travel with it), the devkit's AP recomputed on each draw, and
the central 95 % of the draws. Result sets scored on the same draws give paired intervals of
their differences: whether one detector beats another on these frames, or the frames cannot
tell. The percentile bootstrap (Efron & Tibshirani, "An Introduction to the Bootstrap", 1993);
a fixed seed, so the same inputs give the same numbers.

On 11 real frames holding 14 moderate Cars, one car found or missed moves AP|R40 by several
points: read a real figure with its interval."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..drives import draw_units, drawn, drive_units
from ..labels import Object3D
from .evaluate import METRICS, _progress, check_request, class_ap, overlaps_needed
from .frames import pack
from .overlaps import dontcare_overlap, pair_overlaps
from .report import EvalResult

DRAWS = 1000
SEED = 20261126
LEVEL = 0.95


def central_interval(values: np.ndarray) -> tuple[float, float]:
    """The central LEVEL share of bootstrap draws: order statistics, no interpolation (so +-inf
    draws stay usable)."""
    tail = 100 * (1 - LEVEL) / 2
    return (float(np.percentile(values, tail, method="lower")),
            float(np.percentile(values, 100 - tail, method="higher")))


@dataclass(frozen=True)
class APDraws:
    """AP|R40 ([draw, result set, difficulty]) of each result set over the same draws of frames,
    the devkit's and on the measured recall (`ap.Curve.r40_measured`: for sets of 40 or fewer
    truth boxes, where the devkit's figure is capped at (n - 1) / 40 and the cap moves with the
    number of boxes a draw holds)."""

    names: list[str]
    cls: str
    metric: str
    ap: np.ndarray
    measured: np.ndarray

    def _of(self, measured: bool) -> np.ndarray:
        return self.measured if measured else self.ap

    def interval(self, name: str, difficulty: int = 1, measured: bool = False) -> tuple[float, float]:
        """The central 95 % of `name`'s AP over the draws."""
        return central_interval(self._of(measured)[:, self.names.index(name), difficulty])

    def difference(self, a: str, b: str, difficulty: int = 1,
                   measured: bool = False) -> tuple[float, float]:
        """The central 95 % of AP(a) - AP(b), paired draw by draw."""
        i, j = self.names.index(a), self.names.index(b)
        v = self._of(measured)
        return central_interval(v[:, i, difficulty] - v[:, j, difficulty])


def draw_frames(ids: Sequence[str], draws: int = DRAWS, seed: int = SEED,
                drives: Mapping[str, str] | None = None) -> np.ndarray | list[np.ndarray]:
    """(draws, len(ids)) indices into `ids`, drawn with replacement; where `drives` ({frame id:
    drive}, `kitti.read_drives`) puts frames on one drive, a list of draws that each take whole
    drives (`kitti.drives.draw_units`: frames seconds apart show the same cars)."""
    rng = np.random.default_rng(seed)
    units = drive_units(ids, drives)
    if len(units) == len(ids):
        return rng.integers(len(ids), size=(draws, len(ids)))
    return [draw_units(rng, units) for _ in range(draws)]


def resampled(objects: Mapping[str, Sequence[Object3D]], ids: Sequence[str],
              picks: np.ndarray) -> dict[str, Sequence[Object3D]]:
    """One draw: the picked frames' objects under fresh ids (a frame drawn twice counts twice); a
    frame absent from `objects` (no detections) stays absent."""
    return {f"{k:06d}": objects[ids[i]] for k, i in enumerate(picks) if ids[i] in objects}


def bootstrap_ap(gt: Mapping[str, Sequence[Object3D]],
                 results: Mapping[str, Mapping[str, Sequence[Object3D]]],
                 classes: Sequence[str] = ("Car",), metrics: Sequence[str] = ("2d",),
                 draws: int = DRAWS, seed: int = SEED, progress: bool = False,
                 drives: Mapping[str, str] | None = None) -> dict[tuple[str, str, bool], APDraws]:
    """AP|R40 (easy, moderate, hard) of each of `results` ({name: {frame id: detections}}) against
    `gt` over `draws` draws of gt's frames (whole drives where `drives` says which frames share
    one), the same draws for every result set; keyed by (class, metric, loose): strict IoU, and
    for bird's-eye and 3D also the loose one (0.5 for Car). A metric the results cannot be scored
    on (3D without 3D boxes) is left out.

    Each draw is scored exactly as `evaluate` scores the drawn frames (`resampled`): each result
    set is packed and its overlaps computed once, and a draw takes its frames' rows and overlaps
    (`Packed.take`), with none of `evaluate`'s breakdowns, which no interval reads."""
    ids = sorted(gt)
    if not ids:
        raise ValueError("no truth frames to draw from")
    classes, metrics, names = list(classes), list(metrics), list(results)
    check_request(classes, metrics)
    keys = [(c, m, loose) for c in classes for m in metrics
            for loose in ((False, True) if m in ("bev", "3d") else (False,))]
    ap = {k: np.full((draws, len(names), 3), np.nan) for k in keys}
    measured = {k: np.full((draws, len(names), 3), np.nan) for k in keys}
    packed = []
    for name in names:
        p = pack(gt, results[name])
        packed.append((p, {m: pair_overlaps(p, m) for m in overlaps_needed(metrics)},
                       dontcare_overlap(p.dt, p.dc)))
    for d, picks in enumerate(_progress(draw_frames(ids, draws, seed, drives), progress, "bootstrap")):
        for j, (p, ovs, dc_ov) in enumerate(packed):
            q, slots, rows = p.take(picks)
            q_ovs, q_dc = {m: v[slots] for m, v in ovs.items()}, dc_ov[rows]
            for c in classes:
                strict, loose, _ = class_ap(q, c, metrics, q_ovs, q_dc)
                for m in metrics:
                    for is_loose, block in ((False, strict), (True, loose)):
                        if m in block.ap:
                            ap[c, m, is_loose][d, j] = block.ap[m]["R40"]
                            measured[c, m, is_loose][d, j] = block.measured[m]
    return {k: APDraws(names, k[0], k[1], a, measured[k]) for k, a in ap.items() if not np.isnan(a).any()}


def interval_table(gt: Mapping[str, Sequence[Object3D]], dt: Mapping[str, Sequence[Object3D]],
                   res: EvalResult, draws: int = DRAWS,
                   drives: Mapping[str, str] | None = None) -> tuple[str, dict]:
    """`testbed evaluate --bootstrap`: every AP|R40 of `res` (the evaluation of `dt` against
    `gt`, strict IoU) with its 95 % interval over draws of the frames (of whole drives, given
    `drives`), as a printout and JSON; for a class with fewer than 41 truth boxes in a difficulty
    (`EvalResult.capped`), the AP|R40 on the measured recall too, over the same draws."""
    metrics = sorted({m for c in res.classes for m in res.ap[c]}, key=list(METRICS).index)
    head = "class       metric  easy                   moderate               hard"
    ids = sorted(gt)
    lines = [f"AP|R40 with its {LEVEL:.0%} interval over {draws} bootstrap draws of {drawn(ids, drives)} "
             "(a frame's labels and detections together):", "", head]
    out: dict = {"draws": draws, "level": LEVEL, "seed": SEED, "units": len(drive_units(ids, drives))}
    boot = bootstrap_ap(gt, {"pred": dt}, res.classes, metrics, draws=draws, progress=True, drives=drives)
    few = [c for c in res.classes if res.capped(c)]
    for key, classes, measured in (("R40", res.classes, False), ("R40_measured_recall", few, True)):
        if not classes:
            continue
        if measured:
            lines += ["", "On the measured recall (classes the devkit's AP|R40 caps):", "", head]
        out[key] = {}
        for (cls, m, loose), b in boot.items():
            if loose or cls not in classes:
                continue
            cells = [b.interval("pred", k, measured) for k in range(3)]
            point = res.measured[cls]["strict"][m] if measured else res.ap[cls][m]["R40"]
            lines.append(f"{cls:<11s} {m:<7s} " + " ".join(
                f"{p:5.2f} [{lo:5.2f}, {hi:5.2f}]" for p, (lo, hi) in zip(point, cells)))
            out[key].setdefault(cls, {})[m] = [list(c) for c in cells]
    return "\n".join(lines) + "\n", out
