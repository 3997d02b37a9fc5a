"""What a generated dataset's exact inputs give a lifting method, as a real system lacks them: Car
AP|R40 (3D, moderate, IoU 0.7 and 0.5) from the label_2 boxes as they are (oracle) and with each
side moved by Gaussian noise of `sigma` pixels, as a human annotator's or a detector's box would
be; and with the dataset's exact road plane (planes/) or without it (the road fitted to the scan,
as on KITTI's frames).

    .venv/bin/python benchmarks/oracle_inputs.py --data ROOT --split trainval \\
        --methods mono,fit --sigmas 0,0.6,1,2 --roads planes,scan --out runs/oracle_inputs

A generated label's 2D box is its 3D box's projection to a thousandth of a pixel; KITTI's lie
0.84 px from it (median of the largest side gap; the fidelity report's `labels.proj_gap_px` on
the real dev frames), as the largest of four Gaussian sides of sd 0.6 px would be (the median of
the largest of four |N(0, s)| is 1.41 s: (2 Phi(x / s) - 1) ** 4 = 1/2). The noisy boxes go
to the lifter as a detection folder (score 1, class and everything else as labelled), each
side drawn once per sigma with a fixed seed and clipped to the image, and the lifter told that
sigma (`lift_dataset`'s side_sd). Without planes/, the lifter reads the dataset through a folder
of links to everything else.
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from kitti.eval import evaluate, load_annotations
from kitti.labels import read_label, write_label
from lifter.methods import get_method
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


def without_planes(root: Path, out: Path) -> Path:
    """`root` seen without its planes/: a folder of links to its ImageSets and other folders."""
    (out / "training").mkdir(parents=True, exist_ok=True)
    for src in [root / "ImageSets", *(root / "training").iterdir()]:
        dst = out / src.relative_to(root)
        if src.name != "planes" and not dst.exists():
            dst.symlink_to(src.resolve(), target_is_directory=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--split", default="trainval")
    ap.add_argument("--methods", default="mono,fit")
    ap.add_argument("--sigmas", default="0,0.5,1,2")
    ap.add_argument("--roads", default="planes", help="planes (the dataset's planes/), scan (without them)")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    ids = KittiDataset(args.data).ids(args.split)
    methods, roads = args.methods.split(","), args.roads.split(",")
    folders = {"planes": args.data}
    if "scan" in roads:
        folders["scan"] = without_planes(args.data, args.out / "no_planes")
    boxes = {s: noisy_boxes(args.data, ids, s, args.out / f"boxes_{s:g}")
             for s in (float(x) for x in args.sigmas.split(","))}
    gt_all = load_annotations(args.data / "training" / "label_2")
    gt = {i: gt_all[i] for i in ids}
    done: dict = {}  # a method that reads its road from the scan anyway gives one result per sigma
    print(f"{args.data}, split {args.split} ({len(ids)} frames): Car 3D AP|R40 moderate @0.7 / @0.5")
    print("| road | side noise sd (px) | " + " | ".join(methods) + " |")
    print("|---|---" + "|---" * len(methods) + "|")
    for road in roads:
        for sigma, folder in boxes.items():
            cells = []
            for method in methods:
                key = (method, sigma, road if get_method(method).road == "planes-or-scan" else "scan")
                if key not in done:
                    pred = args.out / f"{road}_{method}_{sigma:g}"
                    lift_dataset(folders[road], folder, method, pred, args.split, side_sd=sigma)
                    r = evaluate(gt, load_annotations(pred, ids=ids), classes=("Car",), metrics=("3d",))
                    done[key] = f"{r.ap['Car']['3d']['R40'][1]:.1f} / {r.ap_loose['Car']['3d']['R40'][1]:.1f}"
                cells.append(done[key])
            print(f"| {road} | {sigma:g} | " + " | ".join(cells) + " |", flush=True)

if __name__ == "__main__":
    main()
