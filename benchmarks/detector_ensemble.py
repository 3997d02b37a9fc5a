"""An output-space ensemble of FlexiNet checkpoints: one file holding each network, which
`testbed detect` (`detector.infer.Detector`) reads together, every network's plain and mirrored
reads as views of one NMS, each box scored by the mean over them.

Where a weight-space average (`benchmarks/detector_soup.py`) lands between its members, an
ensemble keeps what each network alone scores and ranks by their agreement; it costs each
network's full read (`results/detector.md`, stop 54).

    .venv/bin/python benchmarks/detector_ensemble.py --out runs/ensemble.pt A.pt B.pt
"""

from __future__ import annotations

import argparse
from pathlib import Path

from detector.infer import save_ensemble


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("weights", nargs="+", type=Path, help="single-network checkpoints, two or more")
    ap.add_argument("--out", required=True, type=Path)
    args = ap.parse_args()
    save_ensemble(args.out, args.weights)
    size = args.out.stat().st_size / 2 ** 20
    print(f"{args.out}: an ensemble of {len(args.weights)} networks ({size:.1f} MiB)")


if __name__ == "__main__":
    main()
