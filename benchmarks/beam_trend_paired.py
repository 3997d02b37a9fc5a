"""Does the beam trend of generated scans hold on real ones? Car by Car, paired across beam counts.

AP on the dev frames' 14 moderate Cars moves 2.5 points a Car, too coarse to show how a lifter
loses accuracy as rings are dropped. Here each labelled Car is lifted from its own scan with its
rings all kept and with rings dropped (every 2nd, every 4th: `kitti.reduce`, what `testbed
reduce-beams` writes), from the labels' 2D boxes (oracle boxes: each lifted box belongs to the
label with the same 2D box), and its 3D IoU is compared with itself: the mean change of IoU and of
the share of Cars within IoU 0.7 and 0.5, with the central 95 % over draws of the frames (a frame's
Cars together; with `--drives`, a drive's frames together). Run on a real root and on a generated
one, the two trends can be set side by side.

    .venv/bin/python benchmarks/beam_trend_paired.py --data ROOT --out DIR [--split S]
        [--beams 32,16] [--method fit] [--priors net] [--boxes DETECTIONS] [--cars moderate|all]
        [--bins 0,20,45,80] [--draws 1000] [--drives FILE] [--reuse]

`--boxes`: a folder of 2D detections of ROOT (`testbed detect`) lifted instead of the labels'
boxes, the whole chain: the lifted Car boxes, highest score first, each take the free Car label
their 2D box overlaps most (2D IoU at least 0.5), as an evaluation assigns them; a Car no box
matches counts as IoU 0 at every ring count, so it adds nothing to a change.

Writes the reduced roots and the lifted boxes under DIR (`--reuse`: the lifted boxes already
there) and prints two markdown tables: every Car, then the change of mean IoU by the Car's ground
distance from the camera (a trend depends on it, and real and generated Cars stand at different
distances). A Car with no lifted box counts as IoU 0.
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from pathlib import Path

import numpy as np

from kitti.dataset import KittiDataset
from kitti.drives import draw_units, drawn, drive_units, read_drives
from kitti.eval.protocol import outside_difficulty
from kitti.iou import iou_2d, iou_3d
from kitti.labels import read_label
from kitti.reduce import reduce_beams, source_beams_of
from lifter.pipeline import lift_dataset

THRESHOLDS = (0.7, 0.5)
MIN_OVERLAP = 0.5  # 2D IoU for a detection's lifted box to stand for a label (KITTI's Car 2D: 0.7)


def matches(labels: list, preds: list, oracle: bool) -> list:
    """Each label's lifted box or None: the one with its very 2D box (oracle boxes), else, the
    Car boxes taken highest score first, the free label each overlaps most (at least MIN_OVERLAP)."""
    if oracle:
        return [next((p for p in preds if np.allclose(p.bbox, gt.bbox, atol=1e-3)), None) for gt in labels]
    cars = sorted((p for p in preds if p.type == "Car"), key=lambda p: -p.score)
    out = [None] * len(labels)
    if not labels or not cars:
        return out
    overlap = iou_2d(np.array([gt.bbox for gt in labels]), np.array([p.bbox for p in cars]))
    for j, box in enumerate(cars):
        free = [i for i in range(len(labels)) if out[i] is None and overlap[i, j] >= MIN_OVERLAP]
        if free:
            out[max(free, key=lambda i: overlap[i, j])] = box
    return out


def car_labels(data: Path, ids: list[str]) -> list[list]:
    """Each frame's Car labels."""
    ds = KittiDataset(data)
    return [[gt for gt in ds.labels(fid) if gt.type == "Car"] for fid in ids]


def car_ious(labels: list[list], pred: Path, ids: list[str], oracle: bool) -> np.ndarray:
    """3D IoU of every Car label (frame by frame, in label order) against its lifted box, 0 where
    none matches."""
    return np.array([float(iou_3d(gt.box7, box.box7)[0, 0]) if box is not None else 0.0
                     for fid, frame in zip(ids, labels)
                     for gt, box in zip(frame, matches(frame, read_label(pred / f"{fid}.txt"), oracle))])


def frame_draws(ids: list[str], draws: int, drives: dict[str, str] | None = None) -> np.ndarray:
    """(draws, frames) counts: how often each frame is drawn in each bootstrap draw (seeded), a
    drive's frames together where `drives` says which share one (`kitti.drives`)."""
    rng, units = np.random.default_rng(0), drive_units(ids, drives)
    return np.stack([np.bincount(draw_units(rng, units), minlength=len(ids)) for _ in range(draws)])


def drawn_mean(values: np.ndarray, frame: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """(draws,) mean of per-Car `values` over each draw's Cars (a frame drawn twice counts twice)."""
    w = counts[:, frame].astype(float)
    return (w @ values) / np.maximum(w.sum(axis=1), 1.0)


def change(d: np.ndarray, frame: np.ndarray, counts: np.ndarray) -> str:
    """The mean of per-Car changes `d` with its central 95 % over the draws."""
    if not len(d):
        return ""
    lo, hi = np.percentile(drawn_mean(d, frame, counts), [2.5, 97.5])
    return f"{np.mean(d):+.3f} [{lo:+.3f}, {hi:+.3f}]"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, type=Path)
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--split", default=None, help="ImageSets split (default: every frame)")
    ap.add_argument("--beams", default="32,16", help="beam counts to drop the rings to")
    ap.add_argument("--method", default="fit")
    ap.add_argument("--priors", default="net")
    ap.add_argument("--boxes", type=Path, help="2D detections to lift (default: the labels' boxes)")
    ap.add_argument("--cars", choices=("moderate", "all"), default="moderate")
    ap.add_argument("--bins", default="0,20,45,80", help="ground distance bin edges (m)")
    ap.add_argument("--draws", type=int, default=1000)
    ap.add_argument("--drives", type=Path, help="which frames share a drive (`kitti.read_drives`): "
                                                "the draws take whole drives")
    ap.add_argument("--reuse", action="store_true", help="the lifted boxes already in OUT")
    args = ap.parse_args()
    ids = KittiDataset(args.data).ids(args.split)
    drives = None if args.drives is None else read_drives(args.drives)
    native = source_beams_of(args.data)
    roots = {native: args.data}
    for b in (int(x) for x in args.beams.split(",")):
        roots[b] = args.out / f"beams{b}"
        reduce_beams(args.data, roots[b], b)
    labels = car_labels(args.data, ids)
    every = [gt for frame in labels for gt in frame]
    keep = np.array([args.cars == "all" or not outside_difficulty(gt.height_px, gt.occluded, gt.truncated, 1)
                     for gt in every], bool)
    frame = np.repeat(np.arange(len(ids)), [len(f) for f in labels])[keep]
    dist = np.array([np.hypot(gt.location[0], gt.location[2]) for gt in every])[keep]
    ious = {}
    for b, root in roots.items():
        boxes = "labels" if args.boxes is None else args.boxes.name
        pred = args.out / f"{args.method}_{args.priors}_{boxes}_{b}"
        if not args.reuse:
            lift_dataset(root, args.boxes, args.method, pred, args.split, priors=args.priors)
        ious[b] = car_ious(labels, pred, ids, args.boxes is None)[keep]
    counts = frame_draws(ids, args.draws, drives)
    base = ious[native]
    source = "oracle 2D boxes" if args.boxes is None else f"the 2D boxes of {args.boxes}"
    print(f"{args.data}: {len(ids)} frames, {len(base)} {args.cars} Cars, `{args.method}` with "
          f"{args.priors} priors and {source}; 95 % intervals over {args.draws} draws of "
          f"{drawn(ids, drives)}")
    print("\n| beams | mean 3D IoU | Cars within 0.7 / 0.5 | change of mean IoU against "
          f"{native} | change of the share within 0.7 | within 0.5 |\n|---|---:|---:|---:|---:|---:|")
    for b, iou in ious.items():
        within = [f"{np.mean(iou >= t):.2f}" for t in THRESHOLDS]
        cells = ["", "", ""] if b == native else [
            change(d, frame, counts)
            for d in (iou - base, *((iou >= t).astype(float) - (base >= t) for t in THRESHOLDS))]
        print(f"| {b}{'' if b == native else ' (dropped)'} | {np.mean(iou):.3f} | "
              f"{' / '.join(within)} | " + " | ".join(cells) + " |")
    edges = [float(x) for x in args.bins.split(",")]
    dropped = [b for b in ious if b != native]
    print(f"\n| ground distance | Cars | mean 3D IoU at {native} | "
          + " | ".join(f"change of mean IoU at {b} (dropped)" for b in dropped)
          + " |\n|---|---:|---:|" + "---:|" * len(dropped))
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (dist >= lo) & (dist < hi)
        mean = f"{np.mean(base[m]):.3f}" if m.any() else ""
        print(f"| {lo:g}-{hi:g} m | {int(m.sum())} | {mean} | "
              + " | ".join(change((ious[b] - base)[m], frame[m], counts) for b in dropped) + " |")


if __name__ == "__main__":
    main()
