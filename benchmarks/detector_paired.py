"""Detection runs on the same generated (or real) frames, paired: each run's 2D AP|R40 moderate
with its 95 % interval over bootstrap draws of the frames, and the paired interval of its
difference to the first run (`kitti.eval.bootstrap`). What a rule such as "Car >= 90.0 on 200
held-out frames" can and cannot tell apart: on a few hundred frames a car or two moves the AP by
a few tenths, so a shortfall inside the paired interval is not a measured loss.

    .venv/bin/python benchmarks/detector_paired.py --gt ROOT/training/label_2 \\
        --split ROOT/ImageSets/trainval.txt --pred A=DETECTIONS_A --pred B=DETECTIONS_B [--draws 1000]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from kitti.eval.annotations import load_annotations
from kitti.eval.bootstrap import DRAWS, bootstrap_ap
from kitti.eval.evaluate import evaluate
from kitti.splits import read_split


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gt", type=Path, required=True, help="label_2 folder with the truth")
    parser.add_argument("--split", type=Path, required=True, help="ImageSets file of the frames")
    parser.add_argument("--pred", action="append", required=True, metavar="NAME=DIR",
                    help="a run's result folder; the first is the one the others are paired with")
    parser.add_argument("--classes", default="Car,Pedestrian,Cyclist")
    parser.add_argument("--draws", type=int, default=DRAWS)
    parser.add_argument("--decimals", type=int, default=1,
                        help="digits after the point (a rule on an interval's end may need two)")
    args = parser.parse_args()
    if not args.split.is_file():
        raise SystemExit(f"--split {args.split}: no such file")
    ids = read_split(args.split)
    runs = {}
    for item in args.pred:
        name, sep, folder = item.partition("=")
        if not sep or not Path(folder).is_dir() or name in runs:
            raise SystemExit(f"--pred {item!r}: expected NAME=DIR, a new NAME and DIR a result folder")
        runs[name] = load_annotations(folder, ids, missing_ok=True)
    gt = load_annotations(args.gt, ids)
    classes = args.classes.split(",")
    boot = bootstrap_ap(gt, runs, classes=classes, draws=args.draws, progress=True)
    first, n = next(iter(runs)), args.decimals
    print(f"2D AP|R40 moderate over {args.draws} bootstrap draws of the {len(ids)} frames of "
          f"{args.split}: each run's 95 % interval, and the paired 95 % interval of its difference "
          f"to {first}\n")
    point = {name: evaluate(gt, dt, classes=classes, metrics=["2d"]).ap for name, dt in runs.items()}
    print(f"| class | run | AP [95 % interval] | minus {first}: point [paired 95 % interval] |")
    print("|---|---|---|---|")
    for cls in classes:
        b = boot[cls, "2d", False]
        for name in runs:
            ap, (lo, hi) = point[name][cls]["2d"]["R40"][1], b.interval(name)
            diff = ""
            if name != first:
                d = ap - point[first][cls]["2d"]["R40"][1]
                diff = "{:+.{n}f} [{:+.{n}f}, {:+.{n}f}]".format(d, *b.difference(name, first), n=n)
            print(f"| {cls} | {name} | {ap:.{n}f} [{lo:.{n}f}, {hi:.{n}f}] | {diff} |")


if __name__ == "__main__":
    main()
