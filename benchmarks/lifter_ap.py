"""Lifter accuracy: Car AP|R40 (3D at IoU 0.7 and 0.5, BEV at 0.7; easy/moderate/hard) of each
lifting method on datasets that differ only in the LiDAR (e.g. 64/32/16 beams of the same worlds),
from oracle 2D boxes (the labels) or from detection files.

    .venv/bin/python benchmarks/lifter_ap.py --split val --boxes gt \
        --dataset 64=data/urban_val_hdl64 --dataset 32=data/urban_val_b32 \
        --dataset 16=data/urban_val_b16 --out runs/lifter/ap_gt

Prints a markdown table and writes OUT/table.md and OUT/ap.json.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from kitti.dataset import KittiDataset
from kitti.eval import evaluate, load_annotations
from kitti.io import atomic_write_text
from lifter.methods import METHODS
from lifter.pipeline import lift_dataset


def fmt(v) -> str:
    return " / ".join(f"{x:5.1f}" for x in v)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", action="append", required=True, help="LABEL=PATH, repeatable")
    ap.add_argument("--split", default="val")
    ap.add_argument("--boxes", default="gt", help="'gt' or a detection folder")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--priors", default="net", choices=["net", "truth"])
    ap.add_argument("--weights", default=None)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    out = Path(args.out)
    rows, results = [], {}
    image_only_done: dict[str, list] = {}
    for spec in args.dataset:
        label, path = spec.split("=", 1)
        gt_all = load_annotations(Path(path) / "training" / "label_2")
        ids = KittiDataset(path).ids(args.split)
        gt = {i: gt_all[i] for i in ids}
        for method in args.methods.split(","):
            if method in image_only_done:  # no LiDAR used: the same on every scan
                rows.append((label, method, *image_only_done[method]))
                continue
            pred_dir = out / f"{label}_{method}"
            detections = None if args.boxes == "gt" else Path(args.boxes)
            lift_dataset(path, detections, method, pred_dir, args.split, priors=args.priors,
                         weights=args.weights)
            dt = load_annotations(pred_dir, ids=ids)
            r = evaluate(gt, dt, classes=("Car",), metrics=("bev", "3d"))
            a, al = r.ap["Car"], r.ap_loose["Car"]
            vals = (a["3d"]["R40"], al["3d"]["R40"], a["bev"]["R40"])
            results[f"{label}/{method}"] = {"3d@0.7": vals[0], "3d@0.5": vals[1], "bev@0.7": vals[2],
                                            "n_gt": r.to_json()["n_gt"]["Car"]}
            has_planes = any((Path(path) / "training" / "planes").glob("*.txt"))
            if not METHODS[method].loads_scan(has_planes):
                image_only_done[method] = list(vals)
            rows.append((label, method, *vals))
    lines = ["| LiDAR | method | Car 3D AP R40 @0.7 (E / M / H) | 3D @0.5 (E / M / H) | BEV @0.7 (E / M / H) |",
             "|---|---|---|---|---|"]
    lines += [f"| {lab} | {m} | {fmt(a)} | {fmt(b)} | {fmt(c)} |" for lab, m, a, b, c in rows]
    table = "\n".join(lines) + "\n"
    print(table)
    atomic_write_text(out / "table.md", table)
    atomic_write_text(out / "ap.json", json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
