"""Does the beam trend of generated scans hold on real ones? Car by Car, paired across beam counts.

AP on the dev frames' 14 moderate Cars moves 2.5 points a Car, too coarse to show how a lifter
loses accuracy as rings are dropped. Here each labelled Car is lifted from its own scan with its
rings all kept and with rings dropped (every 2nd, every 4th: `kitti.reduce`, what `testbed
reduce-beams` writes), from the labels' 2D boxes (oracle boxes: each lifted box belongs to the
label with the same 2D box), and its 3D IoU is compared with itself: the mean change of IoU and of
the share of Cars within IoU 0.7 and 0.5, with the central 95 % over draws of the frames (a frame's
Cars together). Run on a real root and on a generated one, the two trends can be set side by side.

    .venv/bin/python benchmarks/beam_trend_paired.py --data ROOT --out DIR [--split S]
        [--beams 32,16] [--method fit] [--priors net] [--cars moderate|all] [--bins 0,20,45,80]
        [--draws 1000] [--reuse]

Writes the reduced roots and the lifted boxes under DIR (`--reuse`: the lifted boxes already
there) and prints two markdown tables: every Car, then the change of mean IoU by the Car's ground
distance from the camera (a trend depends on it, and real and generated Cars stand at different
distances). A Car with no lifted box counts as IoU 0.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from kitti.dataset import KittiDataset
from kitti.eval.protocol import outside_difficulty
from kitti.iou import iou_3d
from kitti.labels import read_label
from kitti.reduce import reduce_beams, source_beams_of
from lifter.pipeline import lift_dataset
from testbed.stages import sensor_beams

THRESHOLDS = (0.7, 0.5)


def car_ious(data: Path, pred: Path, ids: list[str], cars: str
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frame index, ground distance, 3D IoU) of every selected Car label, in label order,
    against the lifted box with its 2D box."""
    ds = KittiDataset(data)
    frame, dist, iou = [], [], []
    for k, fid in enumerate(ids):
        preds = read_label(pred / f"{fid}.txt")
        for gt in ds.labels(fid):
            if gt.type != "Car" or (cars == "moderate" and outside_difficulty(
                    gt.height_px, gt.occluded, gt.truncated, 1)):
                continue
            match = [p for p in preds if np.allclose(p.bbox, gt.bbox, atol=1e-3)]
            frame.append(k)
            dist.append(float(np.hypot(gt.location[0], gt.location[2])))
            iou.append(float(iou_3d(gt.box7, match[0].box7)[0, 0]) if match else 0.0)
    return np.array(frame, int), np.array(dist), np.array(iou)


def frame_draws(frame: np.ndarray, n_frames: int, draws: int) -> np.ndarray:
    """(draws, n_frames) counts: how often each frame is drawn in each bootstrap draw (seeded)."""
    rng = np.random.default_rng(0)
    return np.stack([np.bincount(rng.integers(n_frames, size=n_frames), minlength=n_frames)
                     for _ in range(draws)])


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
    ap.add_argument("--cars", choices=("moderate", "all"), default="moderate")
    ap.add_argument("--bins", default="0,20,45,80", help="ground distance bin edges (m)")
    ap.add_argument("--draws", type=int, default=1000)
    ap.add_argument("--reuse", action="store_true", help="the lifted boxes already in OUT")
    args = ap.parse_args()
    ids = KittiDataset(args.data).ids(args.split)
    native = source_beams_of(args.data, sensor_beams(args.data))
    roots = {native: args.data}
    for b in (int(x) for x in args.beams.split(",")):
        roots[b] = args.out / f"beams{b}"
        reduce_beams(args.data, roots[b], b, sensor_beams=sensor_beams(args.data))
    ious = {}
    for b, root in roots.items():
        pred = args.out / f"{args.method}_{args.priors}_{b}"
        if not args.reuse:
            lift_dataset(root, None, args.method, pred, args.split, priors=args.priors)
        frame, dist, ious[b] = car_ious(args.data, pred, ids, args.cars)
    counts = frame_draws(frame, len(ids), args.draws)
    base = ious[native]
    print(f"{args.data}: {len(ids)} frames, {len(base)} {args.cars} Cars, `{args.method}` with "
          f"{args.priors} priors and oracle 2D boxes; 95 % intervals over {args.draws} draws of the frames")
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
