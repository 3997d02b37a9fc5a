"""Which moderate Cars `fit` misses only because of the network's priors, and by what: reads the
per-object rows `benchmarks/bench_lifter_real.py` writes with `--priors net,truth` (the same
oracle 2D boxes lifted with the network's size and orientation and with the true ones) and
splits the cars placed within IoU 0.7 with true priors but not with the network's by their
largest error: yaw (over 5 degrees, modulo 180), size (length over 0.5 m, width or height over
0.2 m), along the camera ray (over 0.4 m), or none of these alone.

    .venv/bin/python benchmarks/bench_lifter_real.py --data data/lifter/tune4100_u16 --methods fit \
        --priors net,truth --out runs/lifter23/tune_u16
    .venv/bin/python benchmarks/lifter_prior_misses.py runs/lifter23/tune_u16/objects.json
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from bench_lifter_real import is_moderate  # run as a script: benchmarks/ is on the path

YAW_DEG, LENGTH_M, WIDTH_HEIGHT_M, ALONG_M = 5.0, 0.5, 0.2, 0.4


def _yaw(row: dict) -> float:
    """Yaw error modulo 180 degrees (a box's IoU does not see its heading's sign)."""
    y = abs(row["d_yaw_deg"]) % 180.0
    return min(y, 180.0 - y)


def cause(row: dict) -> str:
    """The first of the thresholds above that a lifted box's errors exceed."""
    if _yaw(row) > YAW_DEG:
        return "yaw"
    if abs(row["d_l"]) > LENGTH_M or abs(row["d_w"]) > WIDTH_HEIGHT_M or abs(row["d_h"]) > WIDTH_HEIGHT_M:
        return "size"
    if abs(row["d_along"]) > ALONG_M:
        return "along the ray"
    return "none alone"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("objects", help="objects.json of bench_lifter_real.py (fit/net and fit/truth)")
    args = ap.parse_args()
    rows = json.load(open(args.objects))
    net, truth = rows["fit/net"], rows["fit/truth"]

    def lifted_car(r: dict) -> bool:
        return r["type"] == "Car" and "depth" in r and is_moderate(r)

    pairs = [(a, b) for a, b in zip(net, truth) if lifted_car(a) and lifted_car(b)]
    lost = [a for a, b in pairs if a["iou3d"] < 0.7 <= b["iou3d"]]
    both = sum(a["iou3d"] < 0.7 and b["iou3d"] < 0.7 for a, b in pairs)
    print(f"{args.objects}: {len(pairs)} moderate Cars; missed at IoU 0.7 with both priors {both}, "
          f"with the network's only {len(lost)}, with the true ones only "
          f"{sum(b['iou3d'] < 0.7 <= a['iou3d'] for a, b in pairs)}")
    print("| largest error (network priors) | cars | distance, median (m) | yaw error, median (deg) "
          "| length error, median (m) | along-ray error, median (m) |\n|---|---|---|---|---|---|")
    for name in ("yaw", "size", "along the ray", "none alone"):
        g = [r for r in lost if cause(r) == name]
        if g:
            print(f"| {name} | {len(g)} | {np.median([r['depth'] for r in g]):.1f} "
                  f"| {np.median([_yaw(r) for r in g]):.1f} | {np.median([abs(r['d_l']) for r in g]):.2f} "
                  f"| {np.median([abs(r['d_along']) for r in g]):.2f} |")


if __name__ == "__main__":
    main()
