"""What exact 2D boxes give a lifting method: Car AP|R40 (3D, moderate, IoU 0.7 and 0.5) from the
label_2 boxes as they are (oracle) and with each side moved by Gaussian noise of `sigma` pixels,
as a human annotator's or a detector's box would be.

    .venv/bin/python benchmarks/box_noise.py --data data/lifter/urban_val --split trainval \\
        --methods mono,fit --sigmas 0,0.5,1,2 --out runs/box_noise

A generated label's 2D box is its 3D box's projection to a thousandth of a pixel; KITTI's lie
0.84 px from it (median of the largest side gap; the fidelity report's `labels.proj_gap_px` on
the real dev frames), as the largest of four Gaussian sides of sd 0.6 px would be (the median of
the largest of four |N(0, s)| is 1.41 s: (2 Phi(x / s) - 1) ** 4 = 1/2). The noisy boxes go
to the lifter as a detection folder (score 1, class and everything else as labelled), each
side drawn once per sigma with a fixed seed and clipped to the image.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from kitti.eval import evaluate, load_annotations
from kitti.labels import read_label, write_label
from lifter.pipeline import lift_dataset

SEED = 0


def noisy_boxes(root: Path, ids: list[str], sigma: float, out: Path) -> Path:
    """The labels' road users as a detection folder, each 2D box side + N(0, sigma) px."""
    rng = np.random.default_rng(SEED)
    data = KittiDataset(root)
    out.mkdir(parents=True, exist_ok=True)
    for fid in tqdm(ids, desc=f"boxes sd {sigma:g} px", leave=False):
        w, h = data.image_size(fid)
        rows = []
        for o in read_label(root / "training" / "label_2" / f"{fid}.txt"):
            if o.type == "DontCare":
                continue
            box = o.bbox + rng.normal(0.0, sigma, 4) if sigma > 0 else o.bbox.copy()
            rows.append(replace(o, bbox=np.clip(box, 0.0, [w - 1, h - 1, w - 1, h - 1]), score=1.0))
        write_label(out / f"{fid}.txt", rows)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--split", default="trainval")
    ap.add_argument("--methods", default="mono,fit")
    ap.add_argument("--sigmas", default="0,0.5,1,2")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    ids = KittiDataset(args.data).ids(args.split)
    gt_all = load_annotations(args.data / "training" / "label_2")
    gt = {i: gt_all[i] for i in ids}
    print(f"{args.data}, split {args.split} ({len(ids)} frames): Car 3D AP|R40 moderate @0.7 / @0.5")
    print("| side noise sd (px) | " + " | ".join(args.methods.split(",")) + " |")
    print("|---" * (1 + len(args.methods.split(","))) + "|")
    for sigma in (float(s) for s in args.sigmas.split(",")):
        boxes = noisy_boxes(args.data, ids, sigma, args.out / f"boxes_{sigma:g}")
        cells = []
        for method in args.methods.split(","):
            pred = args.out / f"{method}_{sigma:g}"
            lift_dataset(args.data, boxes, method, pred, args.split)
            r = evaluate(gt, load_annotations(pred, ids=ids), classes=("Car",), metrics=("3d",))
            cells.append(f"{r.ap['Car']['3d']['R40'][1]:.1f} / {r.ap_loose['Car']['3d']['R40'][1]:.1f}")
        print(f"| {sigma:g} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
