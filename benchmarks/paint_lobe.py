"""What the car paint's unknown 905 nm lobe does to what a user learns from generated scans: a
sensitivity bound, not a model (a diagnosis of the near Cars' zero readings, stop 60).

    .venv/bin/python benchmarks/paint_lobe.py --src data/s59/urban200 --out DIR [--exponents 1,3,6]

The generator's body paint is Lambertian: its echo is its 905 nm reflectivity times cos(incidence)
(`simgen.meshes.paint`, incidence exponent 1). KITTI's grey and silver cars read 0 off their
normal and normally near it (`benchmarks/car_readings.py`), as a glossy or metallic coat would;
how steeply, no source at hand says. Here the worlds of a generated root are scanned again
(`simgen.rescan`, the root's own sensor and LiDAR seeds) with the body paint's exponent k instead:
the same echo facing the beam, cos ** k of it off the normal (k = 1 gives the root's own scans
back, byte for byte; the paint of trims, rims and frames is left as it is). For each k it writes
DIR/k<k> and prints the fidelity report's car rows (`testbed.fidelity`) and the beam trend of
`fit` with oracle boxes (`benchmarks/beam_trend_paired.py`, moderate Cars), so one can read how
far a study's conclusion moves with the lobe. The rescans run in this process (the paint is
replaced in it), about a second a frame.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import simgen.meshes
from simgen.rescan import RescanRequest, rescan
from simgen.spec import LidarSection
from testbed.fidelity import compute_stats
from testbed.fidelity.catalog import STATS

ROWS = ("lidar.car_zero_share_0_20m", "lidar.car_points_0_20m", "lidar.car_points_20_40m",
        "lidar.car_points_40_80m", "lidar.visible_car_points_40_80m", "lidar.reflectance_mean",
        "lidar.reflectance_zero_share")


def lobed_paint(k: float):
    """simgen.meshes.paint with its echo falling as cos ** k."""
    lambertian = simgen.meshes.paint

    def paint(color):
        return dataclasses.replace(lambertian(color), incidence_exponent=float(k))
    return paint


def rescan_with(src: Path, out: Path, k: float) -> None:
    """`out`: the worlds of `src` scanned by its own sensor (simgen.json) with the body paint's
    exponent k, in this process."""
    section = LidarSection(**json.loads((src / "simgen.json").read_text())["lidar"])
    original = simgen.meshes.paint
    simgen.meshes.paint = lobed_paint(k)
    try:
        rescan(src, out, RescanRequest(section))
    finally:
        simgen.meshes.paint = original


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", required=True, type=Path)
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--exponents", default="1,3,6")
    args = ap.parse_args()
    ks = [float(x) for x in args.exponents.split(",")]
    roots = {}
    for k in ks:
        roots[k] = args.out / f"k{k:g}"
        rescan_with(args.src, roots[k], k)
    by_key = {s.key: s for s in STATS}
    stats = {k: compute_stats(root) for k, root in roots.items()}
    print("| statistic (fidelity report) | " + " | ".join(f"k = {k:g}" for k in ks) + " |")
    print("|---|" + "---:|" * len(ks))
    for key in ROWS:
        stat = by_key[key]
        print(f"| {stat.label} | " + " | ".join(f"{stat.value(stats[k]):.4g}" for k in ks) + " |")
    here = Path(__file__).resolve().parent
    for k, root in roots.items():
        print(f"\n### k = {k:g}: beam trend, `fit`, oracle boxes\n")
        out = subprocess.run([sys.executable, str(here / "beam_trend_paired.py"), "--data", str(root),
                              "--out", str(args.out / f"trend_k{k:g}")],
                             check=True, capture_output=True, text=True).stdout
        print(out.strip())


if __name__ == "__main__":
    main()
