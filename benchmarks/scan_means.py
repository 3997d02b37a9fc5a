"""Per-point mean and SD of range, x, y, z and reflectance over KITTI roots' scans, the figures that
RangeNet++'s SemanticKITTI normalisation constants give for KITTI's training sequences (range
12.12 / 12.32 m, remission 0.21 / 0.16; results/fidelity/README.md, stop 45).

    .venv/bin/python benchmarks/scan_means.py ../shared/kitti_real_dev data/fidelity/urban200_edges
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.velodyne import read_velodyne

COLUMNS = ("range", "x", "y", "z", "reflectance")


def scan_moments(root: Path) -> tuple[int, np.ndarray, np.ndarray]:
    """Frames, and the per-point mean and SD of each of COLUMNS over every scan of `root`."""
    files = sorted((root / "training" / "velodyne").glob("*.bin"))
    if not files:
        raise SystemExit(f"{root}: no scans in training/velodyne/")
    total, squares, n = np.zeros(len(COLUMNS)), np.zeros(len(COLUMNS)), 0
    for f in tqdm(files, desc=root.name, leave=False):
        p = read_velodyne(f).astype(np.float64)
        v = np.column_stack([np.linalg.norm(p[:, :3], axis=1), p[:, :4]])
        total += v.sum(axis=0)
        squares += (v ** 2).sum(axis=0)
        n += len(v)
    mean = total / n
    return len(files), mean, np.sqrt(np.maximum(squares / n - mean ** 2, 0.0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("roots", type=Path, nargs="+", help="KITTI-format dataset roots")
    args = ap.parse_args()
    print("| root | frames | " + " | ".join(f"{c} mean / SD" for c in COLUMNS) + " |")
    print("|---|---|" + "---|" * len(COLUMNS))
    for root in args.roots:
        frames, mean, sd = scan_moments(root)
        print(f"| {root} | {frames} | " + " | ".join(f"{m:.2f} / {s:.2f}" for m, s in zip(mean, sd)) + " |")


if __name__ == "__main__":
    main()
