"""A detector's weights on a real KITTI root (made for the real dev frames): Car 2D AP|R40 (the
official protocol, IoU 0.7) and false positives per frame, each weight file side by side.

Beside it, the same on the measured recall (`kitti.eval.ap`: on these frames' 14 moderate Cars
the devkit's AP|R40 cannot exceed 32.5; read at each threshold's own recall it estimates the
devkit's figure on a large set, `benchmarks/ap_few_frames.py`), and the devkit's Car 2D AP|R40
with the match's IoU at 0.5 (`kitti.eval.ap_2d`, a diagnosis, not the benchmark): which cars a
detector finds at all, against how tightly it boxes them.

A false positive here is a Car detection with score >= 0.3 that overlaps no labelled object of
any type (DontCare included) at 2D IoU 0.5: what the detector fires on that is not a car. Beside
the count at score 0.3, the false positives at the score where each weight file finds its 15th and
20th labelled car: a fine-tune can move every score, and at one threshold that reads as more false
positives while the ranking of cars against clutter is unchanged. Then where it loses cars: the
share of labelled Cars and Vans that a detection of score >= 0.3 overlaps at IoU 0.5 and 0.7, by
occlusion level, truncation and distance (run on a generated root too, for the same table beside).

    .venv/bin/python benchmarks/detector_real.py --data ../shared/kitti_real_dev \
        --weights detector/weights/flexinet_small.pt [--weights OTHER.pt ...] --out runs/det_real \
        [--mirror on|off|both] [--scales 1 --scales 1,1.25] [--objects]

`--mirror`: the image read also mirrored (as `testbed detect` does by default), in one pass only,
or both ways, each weight file's rows side by side. `--scales`: the reads' input scales
(`Detector.scales`), each set given its own rows.
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from pathlib import Path

import numpy as np

from detector.augment import pairwise_iou
from detector.infer import default_scales, detect_dataset, parse_scales
from kitti.dataset import KittiDataset
from kitti.drives import drawn, read_drives
from kitti.eval import ap_2d, evaluate
from kitti.eval.bootstrap import DRAWS, bootstrap_ap
from kitti.eval.folders import load_folders

FP_SCORE, FP_IOU = 0.3, 0.5


def unmatched_scores(ds: KittiDataset, ids: list[str], pred: dict) -> list[np.ndarray]:
    """Per frame, the scores of the Car detections (any score) overlapping no label at FP_IOU."""
    out = []
    for fid in ids:
        dets = [o for o in pred[fid] if o.type == "Car"]
        boxes = np.array([o.bbox for o in dets]).reshape(-1, 4)
        scores = np.array([o.score for o in dets])
        gts = np.array([o.bbox for o in ds.labels(fid)]).reshape(-1, 4)
        if len(gts) and len(dets):
            scores = scores[pairwise_iou(boxes, gts).max(axis=1) < FP_IOU]
        out.append(scores)
    return out


def false_positives(unmatched: list[np.ndarray]) -> np.ndarray:
    """Per frame, the Car detections at score >= FP_SCORE overlapping no label at FP_IOU, from
    `unmatched_scores`."""
    return np.array([int((s >= FP_SCORE).sum()) for s in unmatched])


FOUND = (15, 20)  # labelled Cars and Vans found, about a third and a half of the dev frames' 42


def at_equal_finds(objects: list[tuple], unmatched: list[np.ndarray]) -> list[tuple[int, float, float]]:
    """For each k in FOUND: the score at which the detector finds its k-th labelled Car or Van (its
    best score at IoU >= FP_IOU, the last field of `object_scores`' rows) and the false positives a
    frame (`unmatched_scores`) scoring at least that. Two weight files compared at one score
    threshold differ in calibration as well as in what they tell apart; compared at the same number
    of cars found, only in the second."""
    found = np.sort([row[-1] for row in objects])[::-1]
    pooled = np.concatenate(unmatched)
    rows = []
    for k in FOUND:
        if k > len(found) or found[k - 1] <= 0:
            rows.append((k, float("nan"), float("nan")))
            continue
        t = float(found[k - 1])
        rows.append((k, t, float((pooled >= t).sum()) / len(unmatched)))
    return rows


NEAR_PX = 100  # 2D box height of a near car (about 13 m and closer)


def near_cars(ds: KittiDataset, ids: list[str], pred: dict) -> tuple[int, float, float, float, float]:
    """Labelled Cars and Vans at least NEAR_PX tall (truncation < 0.1, occlusion <= 1), each with
    the Car detection of score >= 0.1 that overlaps it most: how many, the median IoU, the share
    at IoU >= 0.7, and the median offsets of that detection's top and bottom edges as shares of
    the label's height (positive: lower in the image)."""
    rows = []
    for fid in ids:
        gts = [o for o in ds.labels(fid) if o.type in ("Car", "Van") and o.height_px >= NEAR_PX
               and o.truncated < 0.1 and o.occluded <= 1]
        dets = np.array([o.bbox for o in pred[fid] if o.type == "Car" and o.score >= 0.1]).reshape(-1, 4)
        for g in gts:
            iou = pairwise_iou(g.bbox[None], dets)[0] if len(dets) else np.zeros(1)
            d = dets[np.argmax(iou)] if len(dets) else g.bbox + np.nan
            rows.append((iou.max(), (d[1] - g.bbox[1]) / g.height_px, (d[3] - g.bbox[3]) / g.height_px))
    r = np.array(rows).reshape(-1, 3)
    if not len(r):
        return 0, *([float("nan")] * 4)
    return len(r), float(np.median(r[:, 0])), float(np.mean(r[:, 0] >= 0.7)), \
        float(np.nanmedian(r[:, 1])), float(np.nanmedian(r[:, 2]))


def object_scores(ds: KittiDataset, ids: list[str], pred: dict) -> list[tuple]:
    """Per labelled Car and Van: frame, 2D height, truncation, occlusion, ground distance, the
    IoU of the Car detection (any score) that overlaps it most, that detection's score, the best
    IoU among detections scoring at least FP_SCORE, and the best score among detections at IoU >=
    FP_IOU: which cars the detector finds and trusts."""
    rows = []
    for fid in ids:
        dets = [o for o in pred[fid] if o.type == "Car"]
        boxes = np.array([o.bbox for o in dets]).reshape(-1, 4)
        scores = np.array([o.score for o in dets])
        for g in ds.labels(fid):
            if g.type not in ("Car", "Van"):
                continue
            iou = pairwise_iou(g.bbox[None], boxes)[0] if len(dets) else np.zeros(0)
            best = int(np.argmax(iou)) if len(iou) else -1
            rows.append((fid, g.height_px, g.truncated, g.occluded, float(np.hypot(*g.location[[0, 2]])),
                         float(iou[best]) if best >= 0 else 0.0, float(scores[best]) if best >= 0 else 0.0,
                         float(iou[scores >= FP_SCORE].max(initial=0.0)) if len(iou) else 0.0,
                         float(scores[iou >= FP_IOU].max(initial=0.0)) if len(iou) else 0.0))
    return sorted(rows, key=lambda r: r[1])


GROUPS = {  # by the label fields KITTI's difficulty levels read (occlusion, truncation) and by distance
    "every Car and Van": lambda h, tr, occ, d: True,
    "fully visible (occlusion 0)": lambda h, tr, occ, d: occ == 0,
    "partly occluded (1)": lambda h, tr, occ, d: occ == 1,
    "largely occluded (2)": lambda h, tr, occ, d: occ == 2,
    "truncated > 0.15": lambda h, tr, occ, d: tr > 0.15,
    "nearer than 15 m": lambda h, tr, occ, d: d < 15.0,
    "15-30 m": lambda h, tr, occ, d: 15.0 <= d < 30.0,
    "30 m and farther": lambda h, tr, occ, d: d >= 30.0,
}


def found_by_group(objects: list[tuple]) -> list[tuple[str, int, float, float]]:
    """For each of GROUPS: its labelled Cars and Vans (`object_scores` rows) and the shares that a
    Car detection scoring at least FP_SCORE overlaps at 2D IoU 0.5 and at 0.7: where the detector
    loses cars (a share of a handful of cars is a direction, not a figure)."""
    out = []
    for name, member in GROUPS.items():
        best = np.array([row[-2] for row in objects if member(*row[1:5])])
        out.append((name, len(best), float(np.mean(best >= 0.5)) if len(best) else float("nan"),
                    float(np.mean(best >= 0.7)) if len(best) else float("nan")))
    return out


def interval_rows(ds: KittiDataset, ids: list[str], preds: dict[str, dict],
                  drives: dict[str, str] | None = None) -> list[str]:
    """Each run's moderate Car AP with its 95 % interval over draws of the frames (a drive's frames
    together given `drives`), and the paired interval of its difference to the first run
    (kitti.eval.bootstrap)."""
    gt = {fid: ds.labels(fid) for fid in ids}
    boot = bootstrap_ap(gt, preds, drives=drives)["Car", "2d", False]
    first = boot.names[0]
    rows = [(f"Car 2D AP|R40 moderate over {DRAWS} bootstrap draws of {drawn(sorted(gt), drives)} (a frame's "
             f"labels and detections together): its 95 % interval, and the paired 95 % interval of "
             f"its difference to {first}, by the devkit and on the measured recall:"), "",
            "| weights | 95 % interval | minus the first run | on the measured recall | minus the first run |",
            "|---|---|---|---|---|"]
    for name in boot.names:
        cells = []
        for measured in (False, True):
            diff = "" if name == first else "{:+.1f} to {:+.1f}".format(
                *boot.difference(name, first, measured=measured))
            cells += ["{:.1f} to {:.1f}".format(*boot.interval(name, measured=measured)), diff]
        rows.append(f"| {name} | " + " | ".join(cells) + " |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default=None, help="ImageSets name (default: every frame)")
    ap.add_argument("--weights", action="append", required=True)
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--mirror", choices=["on", "off", "both"], default="on",
                    help="read each image also mirrored (on, the default of `testbed detect`), not, or both")
    ap.add_argument("--scales", action="append",
                    help="input scales of the reads, comma-separated (`testbed detect --scales`); given "
                         "more than once, each set side by side (default: each weight file's "
                         "default read, `detector.infer.default_scales`)")
    ap.add_argument("--objects", action="store_true",
                    help="also list every labelled Car and Van with the detection that overlaps it most")
    ap.add_argument("--drives", type=Path, help="which frames share a drive (`kitti.read_drives`): "
                                                "the intervals' draws take whole drives")
    args = ap.parse_args()
    ds = KittiDataset(args.data)
    ids = ds.ids(args.split)
    print(f"{args.data}: {len(ids)} frames")
    print("| weights | Car 2D AP\\|R40 @0.7 (e / m / h) | the same on the measured recall | the devkit's "
          f"@0.5 (diagnosis) | false positives per frame (score >= {FP_SCORE}) |")
    print("|---|---|---|---|---|")
    near, equal, groups, objects, preds = [], [], [], [], {}
    modes = {"on": [True], "off": [False], "both": [False, True]}[args.mirror]
    split = Path(args.data) / "ImageSets" / f"{args.split}.txt" if args.split else None
    scale_sets = [parse_scales(c) for c in args.scales] if args.scales else [None]
    runs = [(w, m, c or default_scales(w)) for w in args.weights for m in modes for c in scale_sets]
    for i, (w, mirror, scales) in enumerate(runs):
        pred_dir = args.out / f"pred_{i}"
        pred = detect_dataset(args.data, pred_dir, w, split=args.split, progress=False, mirror=mirror,
                              scales=scales)
        at = f", scales {','.join(f'{v:g}' for v in scales)}"
        w = f"{w} ({'mirrored' if mirror else 'one pass'}{at})"
        gt, dt = load_folders(Path(args.data) / "training" / "label_2", pred_dir, split, progress=False)
        res = evaluate(gt, dt, classes=["Car"])
        ap7, apm = res.ap["Car"]["2d"]["R40"], res.measured["Car"]["strict"]["2d"]
        ap5 = ap_2d(gt, dt, "Car", 0.5)
        unmatched = unmatched_scores(ds, ids, pred)
        fp = false_positives(unmatched)
        print(f"| {w} | " + " | ".join(" / ".join(f"{a:.1f}" for a in v) for v in (ap7, apm, ap5))
              + f" | {fp.mean():.1f} (median {np.median(fp):.0f}) |")
        near.append((w, near_cars(ds, ids, pred)))
        scored = object_scores(ds, ids, pred)
        groups.append((w, found_by_group(scored)))
        equal.append((w, at_equal_finds(scored, unmatched)))
        preds[w] = pred
        if args.objects:
            objects.append((w, scored))
    drives = None if args.drives is None else read_drives(args.drives)
    print("\n" + "\n".join(interval_rows(ds, ids, preds, drives)))
    print(f"\nNear Cars and Vans (2D box >= {NEAR_PX} px, untruncated, occlusion <= 1), the best-"
          "overlapping Car detection (score >= 0.1):\n")
    print("| weights | labels | median IoU | IoU >= 0.7 | top edge, median (x height) | bottom edge |")
    print("|---|---|---|---|---|---|")
    for w, (n, iou, ok, top, bottom) in near:
        print(f"| {w} | {n} | {iou:.2f} | {ok:.0%} | {top:+.3f} | {bottom:+.3f} |")
    print(f"\nWhere it loses cars: the labelled Cars and Vans that a Car detection of score >= {FP_SCORE} "
          "overlaps at 2D IoU 0.5 / 0.7, by occlusion, truncation and distance:\n")
    print("| weights | " + " | ".join(name for name, *_ in groups[0][1]) + " |")
    print("|---|" + "---|" * len(GROUPS))
    for w, rows in groups:
        print(f"| {w} | " + " | ".join(f"{a:.2f} / {b:.2f} (n {n})" for _, n, a, b in rows) + " |")
    print("\nFalse positives a frame at the score where each finds its k-th labelled Car or Van "
          f"(IoU {FP_IOU}): what it tells apart, whatever its calibration:\n")
    print("| weights | " + " | ".join(f"{k} found: score, false positives a frame" for k in FOUND) + " |")
    print("|---|" + "---|" * len(FOUND))
    for w, rows in equal:
        print(f"| {w} | " + " | ".join(f"{t:.2f}, {fp:.1f}" for _, t, fp in rows) + " |")
    for w, rows in objects:
        print(f"\n{w}: every labelled Car and Van, by 2D height; the Car detection that overlaps it "
              f"most (any score), and the best score at IoU >= {FP_IOU}:\n")
        print("| frame | height (px) | truncated | occluded | distance (m) | best IoU | its score | best score at IoU >= 0.5 |")
        print("|---|---|---|---|---|---|---|---|")
        for fid, h, tr, occ, d, iou, score, _, found in rows:
            print(f"| {fid} | {h:.0f} | {tr:.2f} | {occ} | {d:.1f} | {iou:.2f} | {score:.2f} | {found:.2f} |")


if __name__ == "__main__":
    main()
