"""`evaluate`: the official KITTI object evaluation plus the testbed's breakdowns, CPU only."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..labels import Object3D
from . import breakdown
from .ap import curve
from .frames import Packed, pack
from .overlaps import dontcare_overlap, pair_overlaps
from .protocol import DIFFICULTIES, METRICS, clean, min_overlap, restrict
from .report import EvalResult
from .volumetric import DEFAULT_MAX_DISTANCE

PROGRESS_DELAY = 0.5  # seconds before a step's bar shows: a quick step draws none, not an empty one


def _progress(items: list, on: bool, desc: str, unit: str | None = None):
    """`items` with a bar counting `unit`, shown on a terminal only and once the step has taken
    PROGRESS_DELAY, and cleared when done (no empty bars, no blank lines left in the output)."""
    if not on:
        return items
    from tqdm import tqdm  # only when a progress bar is asked for
    return tqdm(items, desc=desc, unit=unit or {"bootstrap": "draw"}.get(desc, "it"), leave=False,
                delay=PROGRESS_DELAY, disable=None)


def _absent(p: Packed, cls: str, metrics: Sequence[str]) -> dict:
    """Metrics the detections cannot support, as the devkit decides it.

    AOS needs every detection to carry alpha (one alpha of -10 anywhere turns it off); bird's-eye
    and 3D need at least one detection of the class with such a box (2D-only result files). A class
    without any detection is evaluated (and scores 0) rather than skipped.
    """
    out = {}
    of_cls = p.dt.type == cls.lower()
    if "aos" in metrics and np.any(p.dt.alpha == -10):
        out["aos"] = "detections carry no alpha (-10)"
    if of_cls.any():
        if not np.any(p.dt.bbox[of_cls, 0] >= 0):
            for m in ("2d", "aos"):
                if m in metrics:
                    out[m] = "no detection carries a 2D box (x1 >= 0)"
        if "bev" in metrics and not p.dt.has_bev[of_cls].any():
            out["bev"] = "no detection carries a bird's-eye box"
        if "3d" in metrics and not p.dt.has_3d[of_cls].any():
            out["3d"] = "no detection carries a 3D box"
    return out


@dataclass
class _Block:
    """AP {metric: {"R11": [e, m, h], "R40": [...]}}, recall with all detections {metric: [e, m, h]},
    evaluated truth per difficulty, the precision curves {metric: {difficulty: [41]}} and AP|R40 on
    the measured recall {metric: [e, m, h]} (`ap.Curve.r40_measured`)."""

    ap: dict
    recall: dict
    n_gt: list
    curves: dict
    measured: dict


def _ignored(p: Packed, cls: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """(ignored truth, ignored detections) of each difficulty (`protocol.clean`): the class's
    flags, computed once for every block that reads them (strict, loose, each distance bin)."""
    return [clean(cls, d, p.gt.type, p.gt.bbox, p.gt.occluded, p.gt.truncated, p.dt.type, p.dt.bbox)
            for d in range(len(DIFFICULTIES))]


def _ap_block(p: Packed, cls: str, ignored: list[tuple[np.ndarray, np.ndarray]], metrics: Sequence[str],
              ovs: dict, dc_ov: np.ndarray, loose: bool, subset: tuple[np.ndarray, np.ndarray] | None,
              overlap: float | None = None) -> _Block:
    """Every difficulty and metric of one class (`ignored`: its `_ignored` flags); AOS rides on
    the 2D matching. `overlap`, when given, replaces the protocol's IoU threshold (diagnosis only,
    see `ap_2d`)."""
    b = _Block({m: {"R11": [], "R40": []} for m in metrics}, {m: [] for m in metrics}, [], {},
               {m: [] for m in metrics})
    for d, (ig_gt, ig_dt) in enumerate(ignored):
        if subset is not None:
            ig_gt, ig_dt = restrict(ig_gt, ig_dt, *subset)
        b.n_gt.append(int((ig_gt == 0).sum()))
        for m in metrics:
            if m == "aos":
                continue
            with_aos = m == "2d" and "aos" in metrics
            c = curve(p, ovs[m], ig_gt, ig_dt, min_overlap(cls, m, loose) if overlap is None else overlap,
                      dc_ov if m == "2d" else None, with_aos)
            pairs = [(m, c.precision, c.precision_at)] + ([("aos", c.aos, c.aos_at)] if with_aos else [])
            for name, vals, at in pairs:
                b.ap[name]["R11"].append(c.r11(vals))
                b.ap[name]["R40"].append(c.r40(vals))
                b.measured[name].append(c.r40_measured(at))
                b.recall[name].append(c.recall)
                b.curves.setdefault(name, {})[DIFFICULTIES[d]] = vals.tolist()
    return b


def _metrics_for(cls_absent: dict, metrics: Sequence[str]) -> list[str]:
    ms = [m for m in metrics if m not in cls_absent]
    if "aos" in ms and "2d" not in ms:
        ms.insert(0, "2d")
    return ms


def check_request(classes: Sequence[str], metrics: Sequence[str]) -> None:
    """A clear error for an unknown metric or class, before any work."""
    bad = [m for m in metrics if m not in METRICS]
    if bad:
        raise ValueError(f"unknown metric(s) {bad}; known: {', '.join(METRICS)}")
    for c in classes:
        min_overlap(c, "2d")


def overlaps_needed(metrics: Sequence[str]) -> list[str]:
    """The pair overlaps the AP of `metrics` reads (AOS rides on the 2D matching)."""
    need = {m for m in metrics if m != "aos"} | ({"2d"} if "aos" in metrics else set())
    return [m for m in ("2d", "bev", "3d") if m in need]


def class_ap(p: Packed, cls: str, metrics: Sequence[str], ovs: dict, dc_ov: np.ndarray
             ) -> tuple[_Block, _Block, dict]:
    """One class: the strict block over the metrics its detections support (with 2D for AOS),
    the loose block of bird's-eye and 3D, and what the detections cannot be scored on."""
    absent = _absent(p, cls, metrics)
    ms = _metrics_for(absent, metrics)
    ignored = _ignored(p, cls)
    strict = _ap_block(p, cls, ignored, ms, ovs, dc_ov, False, None)
    loose = _ap_block(p, cls, ignored, [m for m in ms if m in ("bev", "3d")], ovs, dc_ov, True, None)
    return strict, loose, absent


def _range_bins(p: Packed, classes: list[str], metrics: list[str], absent: dict, ovs: dict,
                dc_ov: np.ndarray, edges: np.ndarray, progress: bool) -> dict:
    """Strict AP per distance bin, the devkit's and on the measured recall (`ap.Curve.r40_measured`);
    objects outside the bin are ignored, not deleted."""
    gt_bin, dt_bin = breakdown.bin_index(p.gt.distance, edges), breakdown.bin_index(p.dt.distance, edges)
    out = {"edges": edges.tolist(), "distance": "ground (camera x-z) distance of the location",
           "bins": []}
    ignored = {cls: _ignored(p, cls) for cls in classes}
    for k in _progress(list(range(len(edges) - 1)), progress, "range bins", "bin"):
        entry = {"range": [float(edges[k]), float(edges[k + 1])], "ap": {}, "n_gt": {},
                 "ap_r40_measured": {}}
        for cls in classes:
            ms = _metrics_for(absent.get(cls, {}), metrics)
            b = _ap_block(p, cls, ignored[cls], ms, ovs, dc_ov, False, (gt_bin == k, dt_bin == k))
            entry["n_gt"][cls] = b.n_gt
            # no truth in the bin: AP is undefined, reported as None rather than 0
            entry["ap"][cls] = {m: {key: [v if n else None for v, n in zip(vals, b.n_gt)]
                                    for key, vals in b.ap[m].items()} for m in ms if m in metrics}
            # a bin holds few truth boxes: the devkit's AP|R40 there is mostly its count's cap
            entry["ap_r40_measured"][cls] = {m: [v if n else None for v, n in zip(b.measured[m], b.n_gt)]
                                             for m in ms if m in metrics}
        out["bins"].append(entry)
    return out


def evaluate(gt: Mapping[str, Sequence[Object3D]], dt: Mapping[str, Sequence[Object3D]],
             classes: Iterable[str] = ("Car", "Pedestrian", "Cyclist"),
             metrics: Iterable[str] = METRICS, range_bins: Sequence[float] | None = None,
             progress: bool = False, match_iou: float = 0.5, min_score: float | None = None,
             max_distance: float = DEFAULT_MAX_DISTANCE) -> EvalResult:
    """Evaluate detections `dt` against truth `gt`, both `{frame id: objects}`.

    Every truth frame is evaluated; a frame missing from `dt` has no detections; detection frames
    without truth are ignored. `range_bins` (edges in metres, e.g. 0, 20, 40, 60, 80) adds AP per
    ground distance bin and bins the error statistics. `match_iou`, `min_score` and `max_distance`
    set the matched-pair statistics and the 004 volumetric metrics (see `breakdown`, `volumetric`).
    """
    classes, metrics = list(classes), list(metrics)
    check_request(classes, metrics)
    edges = None if range_bins is None else np.asarray(range_bins, dtype=float)
    if edges is not None and (len(edges) < 2 or np.any(np.diff(edges) <= 0)):
        raise ValueError(f"range bins must be at least two increasing edges, got {list(range_bins)}")
    p = pack(gt, dt)
    need = overlaps_needed(metrics)  # and 3D always: the matched-pair breakdowns read it
    ovs = {m: pair_overlaps(p, m) for m in ("2d", "bev", "3d") if m in need or m == "3d"}
    dc_ov = dontcare_overlap(p.dt, p.dc)

    ap, ap_loose, n_gt, recall, precision, absent, measured = {}, {}, {}, {}, {}, {}, {}
    for cls in _progress(classes, progress, "AP", "class"):
        b, loose, ab = class_ap(p, cls, metrics, ovs, dc_ov)
        ap_loose[cls] = loose.ap
        if ab:
            absent[cls] = ab
        keep = [m for m in b.ap if m in metrics]
        ap[cls] = {m: b.ap[m] for m in keep}
        measured[cls] = {"strict": {m: b.measured[m] for m in keep}, "loose": loose.measured}
        recall[cls] = {m: b.recall[m] for m in keep}
        precision[cls] = {m: b.curves[m] for m in keep}
        n_gt[cls] = b.n_gt

    bins_out = None if edges is None else _range_bins(p, classes, metrics, absent, ovs, dc_ov, edges,
                                                      progress)
    errors, vol = breakdown.pair_breakdowns(p, classes, ovs["3d"], edges, match_iou, min_score,
                                            max_distance)

    settings = {"frames": len(p.ids), "classes": classes, "metrics": metrics,
                "strict_iou": {c: {m: min_overlap(c, m) for m in ("2d", "bev", "3d")} for c in classes},
                "loose_iou": {c: {m: min_overlap(c, m, True) for m in ("2d", "bev", "3d")} for c in classes},
                "match_iou": match_iou, "min_score": min_score, "max_distance": max_distance,
                "centre_gate": f"max({breakdown.CENTRE_GATE_M} m, {breakdown.CENTRE_GATE_FRACTION:.0%} "
                               "of the truth's ground distance)"}
    return EvalResult(classes, ap, ap_loose, n_gt, recall, precision, absent, bins_out, errors, vol,
                      settings, measured)


def ap_2d(gt: Mapping[str, Sequence[Object3D]], dt: Mapping[str, Sequence[Object3D]], cls: str,
          overlap: float) -> list[float]:
    """2D AP|R40 (easy, moderate, hard) of one class with the match's IoU threshold set to
    `overlap` instead of the protocol's (0.7 for Car), every other rule as in `evaluate`. A
    diagnosis, not the benchmark: at 0.5 a Car counts as found wherever a detection overlaps it
    by half, so AP@0.5 against AP@0.7 tells the cars a detector misses from the boxes it places
    loosely (COCO's AP50 reads the same way)."""
    min_overlap(cls, "2d")  # unknown class -> clear error
    if not 0.0 < overlap < 1.0:
        raise ValueError(f"overlap must lie in (0, 1), got {overlap}")
    p = pack(gt, dt)
    b = _ap_block(p, cls, _ignored(p, cls), ["2d"], {"2d": pair_overlaps(p, "2d")},
                  dontcare_overlap(p.dt, p.dc), False, None, overlap)
    return b.ap["2d"]["R40"]
