"""A detector's weights on a real KITTI root (made for the real dev frames): Car 2D AP|R40 (the
official protocol, IoU 0.7) and false positives per frame, each weight file side by side.

A false positive here is a Car detection with score >= 0.3 that overlaps no labelled object of
any type (DontCare included) at 2D IoU 0.5: what the detector fires on that is not a car.

    .venv/bin/python benchmarks/detector_real.py --data ../shared/kitti_real_dev \
        --weights detector/weights/flexinet_small.pt [--weights OTHER.pt ...] --out runs/det_real
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from detector.augment import pairwise_iou
from detector.infer import detect_dataset
from kitti.dataset import KittiDataset
from kitti.eval import evaluate_folders

FP_SCORE, FP_IOU = 0.3, 0.5


def false_positives(ds: KittiDataset, ids: list[str], pred: dict) -> np.ndarray:
    """Per frame, the Car detections at score >= FP_SCORE overlapping no label at FP_IOU."""
    out = []
    for fid in ids:
        dets = np.array([o.bbox for o in pred[fid] if o.type == "Car" and o.score >= FP_SCORE]).reshape(-1, 4)
        gts = np.array([o.bbox for o in ds.labels(fid)]).reshape(-1, 4)
        if len(gts) == 0:
            out.append(len(dets))
            continue
        out.append(int((pairwise_iou(dets, gts).max(axis=1, initial=0.0) < FP_IOU).sum()) if len(dets) else 0)
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default=None, help="ImageSets name (default: every frame)")
    ap.add_argument("--weights", action="append", required=True)
    ap.add_argument("--out", required=True, type=Path)
    args = ap.parse_args()
    ds = KittiDataset(args.data)
    ids = ds.ids(args.split)
    print(f"{args.data}: {len(ids)} frames")
    print("| weights | Car 2D AP\\|R40 @0.7 (e / m / h) | "
          f"false positives per frame (score >= {FP_SCORE}) |")
    print("|---|---|---|")
    for i, w in enumerate(args.weights):
        pred_dir = args.out / f"pred_{i}"
        pred = detect_dataset(args.data, pred_dir, w, split=args.split, progress=False)
        strict = evaluate_folders(Path(args.data) / "training" / "label_2", pred_dir, classes=["Car"],
                                  progress=False)
        ap7 = strict.ap["Car"]["2d"]["R40"]
        fp = false_positives(ds, ids, pred)
        print(f"| {w} | {' / '.join(f'{a:.1f}' for a in ap7)} | {fp.mean():.1f} (median {np.median(fp):.0f}) |")


if __name__ == "__main__":
    main()
