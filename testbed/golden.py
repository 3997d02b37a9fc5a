"""Golden scenes: the whole pipeline on tiny committed scenes, its key numbers pinned in a file.

The test suite runs it and compares with `scenes/golden/expected.json` within TOLERANCE, so a
change anywhere (meshes, renderer, LiDAR, detector, lifter, evaluation) that moves a number is caught.
`.venv/bin/python -m testbed.golden` makes the same comparison and exits 1 listing what moved.
When a change is meant to move them, regenerate the expectation and commit it with the change:

    .venv/bin/python -m testbed.golden --update
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from lifter.methods import METHODS

from .backends import LocalBackend
from .sweep import Axes, SceneRef, SweepSpec, execute, plan

GOLDEN_DIR = Path(__file__).resolve().parent.parent / "scenes" / "golden"
EXPECTED = GOLDEN_DIR / "expected.json"
# AP in points (0-100) and errors in metres / degrees; the pipeline is deterministic on one machine,
# the tolerance absorbs floating-point differences between BLAS builds.
TOLERANCE = {"ap": 0.5, "error": 0.01}


def golden_sweep(root: Path) -> SweepSpec:
    return SweepSpec(
        name="golden",
        scenes=[SceneRef(spec=GOLDEN_DIR / "street.yaml")],
        axes=Axes(lidar=["hdl64e"], beams=[64, 16], beam_mode=["native"],
                  method=[n for n, m in METHODS.items() if m.rig == "any"],
                  boxes=["gt", "detector"]),
        split="val", range_bins=[0, 20, 40, float("inf")], data_dir=root)


def key_numbers(results) -> dict:
    """Per point: Car AP|R40 (3D, BEV strict; 3D loose) and centre-matched error medians."""
    out = {}
    for pt, ev in results:
        car, loose = ev["ap"]["Car"], ev["ap_loose"]["Car"]
        err = ev["errors"]["centre"]["Car"]["all"]
        bins = {f"{b['range'][0]:g}": b["ap"]["Car"].get("3d", {}).get("R40", [None] * 3)[1]
                for b in ev["range_bins"]["bins"]}
        out[pt.key.split("/", 1)[1]] = {
            "3d_r40": car["3d"]["R40"], "bev_r40": car["bev"]["R40"], "3d_loose_r40": loose["3d"]["R40"],
            "3d_r40_moderate_by_range": bins, "matched": err["n"],
            "centre_median": err["centre"]["median"], "depth_median": err["depth"]["median"],
            "yaw_deg_median": err["yaw_deg"]["median"]}
    return out


def differences(got: dict, expected: dict) -> list[str]:
    """Every key number of `got` that moved from `expected` beyond TOLERANCE (AP keys, those with
    "r40", in points; errors in metres and degrees; the matched count exactly), as readable lines;
    empty when the two agree."""
    out: list[str] = []

    def walk(g, w, tol: float, where: str) -> None:
        if isinstance(w, dict) and isinstance(g, dict) and set(g) == set(w):
            for k in w:
                walk(g[k], w[k], tol, f"{where}.{k}")
        elif isinstance(w, list) and isinstance(g, list) and len(g) == len(w):
            for i, (a, b) in enumerate(zip(g, w)):
                walk(a, b, tol, f"{where}[{i}]")
        elif w is None or g is None or isinstance(w, (dict, list)):
            if g != w:
                out.append(f"{where}: {g} != {w}")
        elif abs(g - w) > tol:
            out.append(f"{where}: {g} != {w} (tolerance {tol})")

    for point in sorted(set(got) | set(expected)):
        if point not in got or point not in expected:
            out.append(f"{point}: {'not computed' if point not in got else 'not in the expectation'}")
            continue
        for key in sorted(set(got[point]) | set(expected[point])):
            tol = 0.0 if key == "matched" else TOLERANCE["ap"] if "r40" in key else TOLERANCE["error"]
            walk(got[point].get(key), expected[point].get(key), tol, f"{point}.{key}")
    return out


def compute(root: Path | None = None, workers: int = 1) -> dict:
    """The key numbers of the golden sweep, run under `root` (default: a temporary folder)."""
    with tempfile.TemporaryDirectory() as tmp:
        spec = golden_sweep(Path(root or tmp))
        with LocalBackend(workers) as backend:
            return key_numbers(execute(plan(spec), backend))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--update", action="store_true", help=f"rewrite {EXPECTED}")
    ap.add_argument("--workers", type=int, default=2, help="worker processes")
    args = ap.parse_args()
    numbers = compute(workers=args.workers)
    text = json.dumps(numbers, indent=1, sort_keys=True) + "\n"
    if args.update:
        EXPECTED.write_text(text)
        print(f"wrote {EXPECTED}")
        return
    moved = differences(numbers, json.loads(EXPECTED.read_text()))
    if moved:
        sys.exit(f"{len(moved)} golden numbers moved from {EXPECTED}:\n" + "\n".join(moved)
                 + "\nIf the change is meant to move them: .venv/bin/python -m testbed.golden --update")
    print(f"the golden numbers match {EXPECTED} (AP within {TOLERANCE['ap']} points, errors within "
          f"{TOLERANCE['error']})")


if __name__ == "__main__":
    main()
