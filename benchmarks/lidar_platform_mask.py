"""Where KITTI's recording car hides its own HDL-64E's lasers: per laser, the azimuth sectors with
no return in (nearly) every frame of a real KITTI root. The constants of `simgen.lidar.platform`.

The lowest lasers of a roof-mounted unit meet the car's own roof, bonnet and boot ahead of and
behind the sensor (and parts of the roof rack beside it) before the ground: KITTI's scans hold no
return there, in every frame, whatever the street. On the real dev frames the lowest laser keeps
about 1,100 returns a sweep against about 1,950 for the lasers above the body's edge. The car and
the mount are the same in every KITTI frame, so the sectors are a property of the platform, not of
the scenes: a sector counts where at least --share of the frames have no return of that laser in
it. Lasers are recovered as the fidelity report does (`kitti.rings.recover_rings`).

Usage: .venv/bin/python benchmarks/lidar_platform_mask.py --root REAL
    [--bin-deg 1] [--share 0.9]
Prints the laser-by-laser table (ring, azimuth sectors in degrees of atan2(y, x), 0-360) in the
form `simgen/lidar/platform.py` holds it, and per laser the returns a frame (median).
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from pathlib import Path

import numpy as np

from kitti.rings import recover_rings
from kitti.velodyne import read_velodyne


def empty_sectors(covered: np.ndarray, frames: int, share: float, bin_deg: float) -> list[tuple[float, float]]:
    """Merged [from, to) azimuth sectors (deg) whose bins are empty in >= share of the frames;
    a sector running through 360 is split there."""
    empty = covered <= (1.0 - share) * frames
    out: list[list[float]] = []
    for b in np.flatnonzero(empty):
        a0 = float(b * bin_deg)
        if out and abs(out[-1][1] - a0) < 1e-9:
            out[-1][1] = a0 + bin_deg
        else:
            out.append([a0, a0 + bin_deg])
    return [(round(a, 3), round(b, 3)) for a, b in out]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", required=True, help="a real KITTI root (training/velodyne)")
    ap.add_argument("--bin-deg", type=float, default=1.0)
    ap.add_argument("--share", type=float, default=0.9)
    args = ap.parse_args()
    files = sorted(Path(args.root, "training", "velodyne").glob("*.bin"))
    if not files:
        raise SystemExit(f"no scans in {args.root}/training/velodyne")
    bins = int(round(360.0 / args.bin_deg))
    covered = np.zeros((64, bins))
    counts = np.zeros((len(files), 64))
    for k, f in enumerate(files):
        p = read_velodyne(f)
        ring = recover_rings(p[:, :3]).ring
        az = np.degrees(np.arctan2(p[:, 1], p[:, 0])) % 360.0
        b = np.minimum((az / args.bin_deg).astype(int), bins - 1)
        for r in range(64):
            m = ring == r
            counts[k, r] = m.sum()
            covered[r] += np.bincount(b[m], minlength=bins) > 0
    print(f"{len(files)} frames of {args.root}; a sector: no return in >= {args.share:.0%} of them,"
          f" {args.bin_deg:g}-degree bins")
    print("HIDDEN = {")
    for r in range(64):
        sectors = empty_sectors(covered[r], len(files), args.share, args.bin_deg)
        if sectors:
            print(f"    {r}: {tuple(sectors)},  # {np.median(counts[:, r]):.0f} returns a frame")
    print("}")


if __name__ == "__main__":
    main()
