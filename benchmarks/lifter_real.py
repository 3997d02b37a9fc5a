"""Lifter diagnosis on a KITTI dataset (made for the real dev frames): per method and priors,
Car AP|R40 (3D @0.7 and @0.5, moderate) and, per labelled Car/Van, the errors of its lifted box
(oracle 2D boxes, so each lifted box belongs to the label with the same 2D box).

    .venv/bin/python benchmarks/lifter_real.py --data ../shared/kitti_real_dev \
        --out runs/lifter/real [--methods fit,mono,frustum] [--priors net,truth] [--objects] \
        [--drives results/fidelity/kitti_real_dev_drives.txt]

Per object: depth, truncation/occlusion, the centre error (along the camera ray, across it, and
in height), the yaw error, the size error (h, w, l), the 3D IoU, and how high the label's bottom
stands above the scan's road under it (`road_err`: above the plane `lifter.road.scan_road` fits
there, the road the methods stand boxes on without planes/; 0 for a label on that road). An
image-only placement on that road puts the box farther along the ray by about depth x road_err /
the camera's height above the road: the last table says how much of each method's along-ray
error that accounts for. Writes
OUT/<method>_<priors>/ (result files) and OUT/objects.json, prints markdown. With fewer than 41
evaluated cars the devkit's AP|R40 cannot reach 100 (`kitti.eval.ap.devkit_cap`): the table gives
it as a share of that cap too, the AP|R40 on the measured recall (`kitti.eval.ap`), and counts the
moderate cars placed within IoU 0.7 and 0.5.
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
import json
from pathlib import Path

import numpy as np

from kitti.boxes import wrap_angle
from kitti.dataset import KittiDataset
from kitti.drives import drawn, read_drives
from kitti.eval import evaluate_folders, load_annotations
from kitti.eval.ap import devkit_cap
from kitti.eval.bootstrap import DRAWS, bootstrap_ap
from kitti.eval.protocol import outside_difficulty
from kitti.iou import iou_3d
from kitti.labels import read_label
from lifter.ground import height_above
from lifter.pipeline import lift_dataset
from lifter.points import frame_points
from lifter.road import LocalRoad, scan_road


def object_errors(gt, pr) -> dict:
    """The errors of one lifted box `pr` against its label `gt` (both Object3D)."""
    d = pr.location - gt.location
    ray = gt.location[[0, 2]] / np.linalg.norm(gt.location[[0, 2]])
    along = float(d[[0, 2]] @ ray)
    across = float(d[0] * ray[1] - d[2] * ray[0])
    dyaw = float(wrap_angle(pr.rotation_y - gt.rotation_y))
    return {"depth": float(np.linalg.norm(gt.location[[0, 2]])), "d_along": along,
            "d_across": across, "d_y": float(d[1]), "d_yaw_deg": float(np.rad2deg(dyaw)),
            "d_h": pr.h - gt.h, "d_w": pr.w - gt.w, "d_l": pr.l - gt.l,
            "iou3d": float(iou_3d(gt.box7, pr.box7)[0, 0])}


def is_moderate(row: dict) -> bool:
    """KITTI's moderate difficulty (kitti.eval.protocol): 25 px high, occlusion <= 1, truncation
    <= 0.3."""
    return not outside_difficulty(row["height_px"], row["occ"], row["trunc"], 1)


def scan_roads(data: Path, ids: list[str]) -> dict[str, LocalRoad]:
    """The scan's road of each frame that has a scan."""
    ds = KittiDataset(data)
    return {fid: scan_road(frame_points(v, ds.calib(fid), None))
            for fid in ids if (v := ds.velodyne(fid)) is not None}


def per_object(data: Path, pred_dir: Path, ids: list[str], roads: dict[str, LocalRoad]) -> list[dict]:
    ds = KittiDataset(data)
    rows = []
    for fid in ids:
        preds = read_label(pred_dir / f"{fid}.txt")
        for gt in ds.labels(fid):
            if gt.type not in ("Car", "Van"):
                continue
            match = [p for p in preds if np.allclose(p.bbox, gt.bbox, atol=1e-3)]
            row = {"frame": fid, "type": gt.type, "trunc": gt.truncated, "occ": gt.occluded,
                   "height_px": gt.height_px}
            row.update(object_errors(gt, match[0]) if match else {"iou3d": 0.0})
            if fid in roads:
                plane = roads[fid].plane_at(gt.location[0], gt.location[2])
                row["road_err"] = float(height_above(np.asarray(gt.location)[None], plane)[0])
                row["camera_above_road"] = float(height_above(np.zeros((1, 3)), plane)[0])
            rows.append(row)
    return rows


def markdown_table(rows: list[dict]) -> str:
    head = ("| frame | type | tr | occ | depth | along | across | dy | yaw deg | dh | dw | dl | IoU | road_err |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        if "depth" not in r:
            lines.append(f"| {r['frame']} | {r['type']} | {r['trunc']:.2f} | {r['occ']} | (not lifted) |")
            continue
        lines.append(f"| {r['frame']} | {r['type']} | {r['trunc']:.2f} | {r['occ']} | {r['depth']:.1f} "
                     f"| {r['d_along']:+.2f} | {r['d_across']:+.2f} | {r['d_y']:+.2f} "
                     f"| {r['d_yaw_deg']:+.1f} | {r['d_h']:+.2f} | {r['d_w']:+.2f} | {r['d_l']:+.2f} "
                     f"| {r['iou3d']:.2f} | {r.get('road_err', float('nan')):+.3f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default=None, help="ImageSets split (default: every frame)")
    ap.add_argument("--methods", default="fit,mono,frustum")
    ap.add_argument("--priors", default="net,truth")
    ap.add_argument("--out", required=True)
    ap.add_argument("--objects", action="store_true", help="print the per-object tables")
    ap.add_argument("--reuse", action="store_true", help="evaluate result folders already in OUT")
    ap.add_argument("--drives", type=Path, help="which frames share a drive (`kitti.read_drives`): "
                                                "the intervals' draws take whole drives")
    args = ap.parse_args()
    data, out = Path(args.data), Path(args.out)
    ids = KittiDataset(data).ids(args.split)
    roads = scan_roads(data, ids)
    summary, objects = [], {}
    for method in args.methods.split(","):
        for priors in args.priors.split(","):
            pred = out / f"{method}_{priors}"
            if not (args.reuse and pred.is_dir()):
                lift_dataset(data, None, method, pred, args.split, priors=priors, progress=False)
            r = evaluate_folders(data / "training" / "label_2", pred, classes=("Car",),
                                 progress=False)
            rows = per_object(data, pred, ids, roads)
            objects[f"{method}/{priors}"] = rows
            cars = [x for x in rows if x["type"] == "Car" and "depth" in x]
            mod = [x for x in rows if x["type"] == "Car" and is_moderate(x)]
            med = {k: float(np.median([abs(x[k]) for x in cars]))
                   for k in ("d_along", "d_across", "d_y", "d_yaw_deg", "d_l")}
            cap = devkit_cap(r.n_gt["Car"][1])
            measured = (r.measured["Car"]["strict"]["3d"][1], r.measured["Car"]["loose"]["3d"][1])
            summary.append((method, priors, r.ap["Car"]["3d"]["R40"][1],
                            r.ap_loose["Car"]["3d"]["R40"][1], cap, measured, med,
                            sum(x["iou3d"] >= 0.7 for x in mod), sum(x["iou3d"] >= 0.5 for x in mod),
                            len(mod)))
            if args.objects:
                print(f"\n### {method}, {priors} priors\n\n{markdown_table(rows)}")
    print("\n| method | priors | Car 3D AP R40 mod @0.7 (% of cap) | @0.5 (% of cap) | on the measured "
          "recall @0.7 / @0.5 | moderate cars IoU>=0.7 / >=0.5 | all cars: median abs along / across "
          "/ dy (m) | yaw (deg) | dl (m) |\n|---|---|---|---|---|---|---|---|---|")
    for m, p, a7, a5, cap, (m7, m5), med, n7, n5, n in summary:
        print(f"| {m} | {p} | {a7:.1f} ({100 * a7 / cap:.0f}) | {a5:.1f} ({100 * a5 / cap:.0f}) "
              f"| {m7:.1f} / {m5:.1f} "
              f"| {n7} / {n5} of {n} | {med['d_along']:.2f} / {med['d_across']:.2f} / {med['d_y']:.2f} "
              f"| {med['d_yaw_deg']:.1f} | {med['d_l']:.2f} |")
    drives = None if args.drives is None else read_drives(args.drives)
    print("\n" + "\n".join(interval_rows(data, out, ids, [(m, p) for m, p, *_ in summary], drives)))
    if roads:
        print("\n" + "\n".join(bottom_rows(objects)))
    out.mkdir(parents=True, exist_ok=True)
    (out / "objects.json").write_text(json.dumps(objects, indent=1))


def bottom_rows(objects: dict[str, list[dict]]) -> list[str]:
    """Per run, over its lifted Cars: the labels' bottoms above the scan's road (median), the
    median |along-ray error|, and the same less what the bottom's height accounts for."""
    lines = ["| method | priors | Cars | label bottom above the scan's road, median (m) | median abs along "
             "(m) | median abs (along - depth x road_err / camera height) (m) |",
             "|---|---|---|---|---|---|"]
    for run, rows in objects.items():
        cars = [x for x in rows if x["type"] == "Car" and "depth" in x and "road_err" in x]
        if not cars:
            continue
        along = np.array([x["d_along"] for x in cars])
        expected = np.array([x["depth"] * x["road_err"] / x["camera_above_road"] for x in cars])
        lines.append(f"| {' | '.join(run.split('/'))} | {len(cars)} "
                     f"| {np.median([x['road_err'] for x in cars]):+.3f} | {np.median(np.abs(along)):.2f} "
                     f"| {np.median(np.abs(along - expected)):.2f} |")
    return lines


def interval_rows(data: Path, out: Path, ids: list[str], runs: list[tuple[str, str]],
                  drives: dict[str, str] | None = None) -> list[str]:
    """Each run's moderate Car 3D AP with its 95 % interval over draws of the frames (a frame's
    labels and lifted boxes together, a drive's frames together given `drives`;
    kitti.eval.bootstrap), the same draws for every run."""
    gt = load_annotations(data / "training" / "label_2", ids, progress=False)
    results = {f"{m}/{p}": load_annotations(out / f"{m}_{p}", list(gt), missing_ok=True, progress=False)
               for m, p in runs}
    boot = bootstrap_ap(gt, results, metrics=("3d",), drives=drives)
    rows = [f"Car 3D AP|R40 moderate over {DRAWS} bootstrap draws of {drawn(sorted(gt), drives)}: 95 % "
            "intervals (the devkit's; on the measured recall)", "",
            "| method | priors | @0.7 | @0.5 | measured recall @0.7 | @0.5 |", "|---|---|---|---|---|---|"]
    for name in results:
        cells = ["{:.1f} to {:.1f}".format(*boot["Car", "3d", loose].interval(name, measured=measured))
                 for measured in (False, True) for loose in (False, True)]
        rows.append(f"| {' | '.join(name.split('/'))} | " + " | ".join(cells) + " |")
    return rows


if __name__ == "__main__":
    main()
