"""Which of its three ways `fit` placed each moderate Car, and how well: from returns that reach
low on the body (bumpers, doors), from returns only above the bumpers (a sparse scan's ring over
the bonnet, boot or glasshouse: the face is set in by `lifter.placement.OUTLINE_*`), or
image-only (`_fallback`: too few returns). Oracle 2D boxes; per path and distance band the count,
the share missed at 3D IoU 0.7, and the median along-ray and height errors of the box centre
(lifted minus labelled; along > 0 is too far).

    .venv/bin/python benchmarks/fit_paths.py --data data/lifter/tune4100_u16 [--priors truth]

The paths are read by wrapping two functions; the lifted boxes are `testbed lift`'s.
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import numpy as np

import lifter.fit as fit
from kitti.dataset import KittiDataset
from kitti.eval.protocol import outside_difficulty
from kitti.iou import iou_3d
from lifter.placement import OUTLINE_FRONT
from lifter.pipeline import box_outline, lift_frame, oracle_boxes, truth_priors
from lifter.predictor import DEFAULT_WEIGHTS, Predictor

BANDS = ((0.0, 30.0), (30.0, 40.0), (40.0, 60.0), (60.0, np.inf))


HIGH = float(OUTLINE_FRONT[0, 0])  # share of the height: the lowest station of a set-in outline
PATHS = ("returns low on the body", "returns above the bumpers only", "image only")


def _record_paths() -> dict:
    """Wrap fit's image-only step and its yaw search (which sees the object's returns); returns
    the dict they fill per 2D box."""
    path: dict[tuple, str] = {}
    fallback, best_yaw = fit._fallback, fit._best_yaw

    def wrapped_fallback(box, prior, view, plane):
        path[tuple(box.bbox)] = PATHS[2]
        return fallback(box, prior, view, plane)

    def wrapped_best_yaw(obj, prior, ry_prior, small, box, view, plane):
        high = obj.height.min() > HIGH * prior.dims[0]
        path[tuple(box.bbox)] = PATHS[1] if high else PATHS[0]
        return best_yaw(obj, prior, ry_prior, small, box, view, plane)

    fit._fallback, fit._best_yaw = wrapped_fallback, wrapped_best_yaw
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--priors", choices=("net", "truth"), default="net")
    args = ap.parse_args()
    ds = KittiDataset(args.data)
    ids = ds.ids()
    outline = box_outline(args.data, None, ids)
    predictor = Predictor(DEFAULT_WEIGHTS) if args.priors == "net" else None
    path = _record_paths()
    rows: dict[str, list] = defaultdict(list)
    for fid in ids:
        labels = ds.labels(fid)
        boxes = oracle_boxes(labels)
        priors = (truth_priors(boxes, labels) if predictor is None
                  else predictor(ds.image(fid), boxes))
        path.clear()
        lifted = lift_frame("fit", boxes, priors, ds.calib(fid), ds.image_size(fid),
                            ds.velodyne(fid), None, outline=outline)
        for box, pr in zip(boxes, lifted):
            gt = next(o for o in labels if np.allclose(o.bbox, box.bbox))
            if gt.type != "Car" or outside_difficulty(gt.height_px, gt.occluded, gt.truncated, 1):
                continue
            ray = gt.location[[0, 2]] / np.linalg.norm(gt.location[[0, 2]])
            b_gt = np.array([[*gt.location, gt.h, gt.w, gt.l, gt.rotation_y]])
            b_pr = np.array([[*pr.location, pr.h, pr.w, pr.l, pr.rotation_y]])
            rows[path[tuple(box.bbox)]].append((
                float(np.linalg.norm(gt.location[[0, 2]])),
                float((pr.location - gt.location)[[0, 2]] @ ray),
                float(pr.location[1] - gt.location[1]), float(iou_3d(b_gt, b_pr)[0, 0])))
    print(f"{args.data}, {args.priors} priors, moderate Cars, oracle 2D boxes")
    print("| path | distance (m) | cars | missed at 0.7 | along-ray error, median (m) | height error, median (m) |")
    print("|---|---|---|---|---|---|")
    for name in PATHS:
        r = np.array(rows.get(name, [])).reshape(-1, 4)
        for lo, hi in BANDS:
            m = (r[:, 0] >= lo) & (r[:, 0] < hi)
            if m.any():
                print(f"| {name} | {lo:.0f}-{hi:.0f} | {m.sum()} | {np.sum(r[m, 3] < 0.7)} | "
                      f"{np.median(r[m, 1]):+.2f} | {np.median(r[m, 2]):+.3f} |")


if __name__ == "__main__":
    main()
