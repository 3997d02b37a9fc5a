"""The output bytes of a small scene through the whole chain, and the manifest every machine must
reproduce.

Two frames of `scenes/golden/street.yaml` are generated (images, scans, labels, calib, planes,
meta), re-scanned with 16 beams, read by the shipped detector and lifted by `fit` from the
oracle and the detector's boxes, each lift evaluated. The sha256 of every file written is
compared with `scenes/golden/manifest.sha256`: a machine whose kernels round otherwise (see
kitti.cpu for what the project pins) fails here first, naming the first file that differs, before
any AP moves.

    .venv/bin/python -m testbed.fingerprint            # compare with the manifest
    .venv/bin/python -m testbed.fingerprint --update   # after a change meant to move outputs
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import tempfile
from pathlib import Path

from . import stages
from .backends import LocalBackend

GOLDEN_DIR = Path(__file__).resolve().parent.parent / "scenes" / "golden"
SPEC = GOLDEN_DIR / "street.yaml"
MANIFEST = GOLDEN_DIR / "manifest.sha256"
FRAMES = 2
RESCAN_BEAMS = 16


def run_chain(root: Path, workers: int = 1, threads: int = 1) -> None:
    """Generate, re-scan, detect, lift and evaluate the small scene under `root`, with `workers`
    processes for the per-frame stages and `threads` CPU threads for the networks."""
    from simgen.rescan import RescanRequest
    from simgen.spec import LidarSection

    data = root / "data"
    with LocalBackend(workers) as backend:
        stages.generate(SPEC, data, FRAMES, None, backend)
        request = RescanRequest(LidarSection(preset="hdl64e", beams=RESCAN_BEAMS))
        stages.rescan([stages.Rescan(data, root / f"rescan-{RESCAN_BEAMS}", request)], backend)
    detections = stages.detect(data, root / "detections", "val", threads)
    import torch

    torch.set_num_threads(threads)
    for scans, boxes, name in ((data, None, "fit-gt"), (data, detections, "fit-detector"),
                               (root / f"rescan-{RESCAN_BEAMS}", None, f"fit-gt-{RESCAN_BEAMS}")):
        stages.lift_and_evaluate(stages.LiftJob(scans, boxes, "fit", "val", root / name, (0, 20, 40, float("inf"))))


def manifest(root: Path) -> dict[str, str]:
    """sha256 of every file under `root` by its path relative to it, in path order; the `.done`
    markers, which name the folders they were written in, are left out."""
    files = sorted(p for p in root.rglob("*") if p.is_file() and p.name != ".done")
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def format_manifest(hashes: dict[str, str]) -> str:
    return "".join(f"{h}  {path}\n" for path, h in hashes.items())


def read_manifest(path: Path = MANIFEST) -> dict[str, str]:
    out = {}
    for n, line in enumerate(path.read_text().splitlines(), 1):
        digest, sep, name = line.partition("  ")
        if not sep or len(digest) != 64:
            raise ValueError(f"{path}:{n}: expected '<sha256>  <path>', got {line!r}")
        out[name] = digest
    return out


def first_difference(got: dict[str, str], expected: dict[str, str]) -> str | None:
    """The first file, in path order, that is missing, extra or has other bytes; None if none."""
    for name in sorted(set(got) | set(expected)):
        if name not in got:
            return f"{name}: expected, not written"
        if name not in expected:
            return f"{name}: written, not in the manifest"
        if got[name] != expected[name]:
            return f"{name}: sha256 {got[name][:12]}… where the manifest has {expected[name][:12]}…"
    return None


def check_manifest(workers: int = 1, threads: int = 1, keep: Path | None = None) -> str | None:
    """Run the chain (under `keep`, else a temporary folder) and name its first file that differs
    from the committed manifest; None when every file matches."""
    with tempfile.TemporaryDirectory() as tmp:
        root = keep or Path(tmp)
        run_chain(root, workers, threads)
        return first_difference(manifest(root), read_manifest())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--update", action="store_true", help=f"rewrite {MANIFEST}")
    ap.add_argument("--workers", type=int, default=1, help="worker processes")
    ap.add_argument("--threads", type=int, default=1, help="CPU threads of the networks")
    ap.add_argument("--keep", type=Path, help="run under this folder and keep it (default: a temporary one)")
    args = ap.parse_args()
    if args.update:
        with tempfile.TemporaryDirectory() as tmp:
            root = args.keep or Path(tmp)
            run_chain(root, args.workers, args.threads)
            hashes = manifest(root)
        MANIFEST.write_text(format_manifest(hashes))
        print(f"wrote {MANIFEST} ({len(hashes)} files)")
    elif diff := check_manifest(args.workers, args.threads, args.keep):
        sys.exit(f"the outputs here differ from {MANIFEST}: first {diff}")
    else:
        print(f"every file matches {MANIFEST}")


if __name__ == "__main__":
    main()
