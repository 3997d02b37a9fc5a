"""How the label rules move the fidelity report's label statistics: one generated root relabelled
under each rule set (`simgen.relabel`, nothing rendered or scanned again), each read by
`testbed fidelity` against a real root.

A rule set is NAME:key=value,key=value over `simgen.spec.LabelRules` fields (e.g.
`points5:min_lidar_points=5`); the source's own rules come first as "as generated". Printed:
per rule set, each label statistic (median over frames or objects, as the report reads it) with
its relative difference to the real root's and the verdict, decided or not by the report's
bootstrap; DontCare regions a frame (mean) and Cars and Vans a frame by distance beside them.

Usage: .venv/bin/python benchmarks/label_rules.py --data ROOT --real REAL --out DIR
           --rule NAME:key=value[,key=value] [--rule ...] [--workers 2]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from kitti.labels import read_label
from simgen.relabel import relabel, source_rules
from simgen.spec import LabelRules
from testbed.backends import LocalBackend
from testbed.fidelity.collect import compute_stats
from testbed.fidelity.compare import compare

DISTANCE_BINS = (0.0, 10.0, 20.0, 40.0, 80.0)  # m, ground x-z distance from camera 0
KEYS = ("labels.objects_per_frame", "labels.cars_per_frame", "labels.distance_m",
        "labels.box_height_px", "labels.fully_visible_share", "labels.truncated_share")


def parse_rule(text: str, base: LabelRules) -> tuple[str, LabelRules]:
    """NAME:key=value,... as a LabelRules over `base` (values read as YAML scalars)."""
    name, _, body = text.partition(":")
    if not name or not body:
        raise SystemExit(f"--rule {text!r}: expected NAME:key=value[,key=value]")
    fields = dict(base.model_dump())
    for item in body.split(","):
        key, eq, value = item.partition("=")
        if not eq or key not in fields:
            raise SystemExit(f"--rule {text!r}: {key!r} is not a LabelRules field")
        fields[key] = yaml.safe_load(value)
    return name, LabelRules.model_validate(fields)


def vehicles_by_distance(root: Path) -> np.ndarray:
    """Cars and Vans a frame (mean over the root's label files) in each DISTANCE_BINS bin."""
    files = sorted((root / "training" / "label_2").glob("*.txt"))
    d = [float(np.hypot(o.location[0], o.location[2])) for f in files for o in read_label(f)
         if o.type in ("Car", "Van")]
    return np.histogram(d, bins=DISTANCE_BINS)[0] / max(len(files), 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True, help="a root written by `testbed generate`")
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True, help="relabelled roots go to OUT/NAME")
    ap.add_argument("--rule", action="append", default=[])
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    base = source_rules(args.data)
    sets = [parse_rule(r, base) for r in args.rule]
    with LocalBackend(args.workers) as backend:
        real = compute_stats(args.real, backend=backend)
        roots = [("as generated", args.data)]
        for name, rules in sets:
            relabel(args.data, args.out / name, rules, backend)
            roots.append((name, args.out / name))
        comps = [(name, compare(compute_stats(root, backend=backend), real)) for name, root in roots]
    print(f"`{args.data}` relabelled, against `{args.real}` ({len(real.frames)} frames)\n")
    print("| statistic | real | " + " | ".join(name for name, _ in comps) + " |")
    print("|---|---:|" + "---:|" * len(comps))
    rows = {name: {r.key: r for r in comp.rows} for name, comp in comps}
    for key in KEYS:
        first = rows[comps[0][0]][key]
        cells = []
        for name, _ in comps:
            r = rows[name][key]
            rel = "n/a" if r.rel_diff is None else f"{100 * r.rel_diff:+.0f} %"
            cells.append(f"{r.sim:.3g} ({rel}, {r.verdict}{'' if r.decided else ', undecided'})")
        print(f"| {first.label} | {first.real:.3g} | " + " | ".join(cells) + " |")
    dontcare = [float(np.mean(c.sim.get("labels.dontcare"))) for _, c in comps]
    print(f"| DontCare regions a frame (mean) | {float(np.mean(real.get('labels.dontcare'))):.3g} | "
          + " | ".join(f"{d:.3g}" for d in dontcare) + " |")
    bins = [vehicles_by_distance(Path(args.real))] + [vehicles_by_distance(Path(r)) for _, r in roots]
    for i, (lo, hi) in enumerate(zip(DISTANCE_BINS[:-1], DISTANCE_BINS[1:])):
        print(f"| Cars and Vans a frame at {lo:g}-{hi:g} m (mean) | "
              + " | ".join(f"{b[i]:.2f}" for b in bins) + " |")


if __name__ == "__main__":
    main()
