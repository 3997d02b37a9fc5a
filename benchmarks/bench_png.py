"""The generator's PNG files: encoding time and size of each image kind, as written and with libpng's
adaptive per-row filter choice at zlib level 3 (what the generator once wrote for every kind), and
that both decode to the same pixels.

Without `--data` it first generates `--frames` frames of `--spec` (no LiDAR) into a temporary folder.

    .venv/bin/python benchmarks/bench_png.py [--data ROOT] [--frames 8] [--repeats 3]
        [--spec scenes/urban.yaml]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import kitti  # noqa: F401  (first: it pins the kernels and OpenBLAS's threads before numpy loads)
import cv2
import numpy as np

from simgen.generate import PNG_CAMERA, PNG_DEPTH, PNG_INSTANCE, encode_png, generate
from simgen.spec import load_spec

KINDS = {"image_2": PNG_CAMERA, "depth_2": PNG_DEPTH, "instance_2": PNG_INSTANCE}


def adaptive(img: np.ndarray) -> bytes:
    """libpng's own filter choice per row, zlib's default strategy at level 3."""
    ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 3])
    assert ok
    return buf.tobytes()


def timed(encode, images: list[np.ndarray], repeats: int) -> tuple[float, float, list[bytes]]:
    """Median milliseconds an image over `repeats` passes, mean kB an image, the encoded files."""
    passes = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        files = [encode(im) for im in images]
        passes.append(1000 * (time.perf_counter() - t0) / len(images))
    return float(np.median(passes)), sum(map(len, files)) / len(files) / 1000, files


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, help="a root testbed generate wrote (default: generate one)")
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--spec", default="scenes/urban.yaml")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.data
        if root is None:
            root = Path(tmp) / "frames"
            generate(load_spec(args.spec).model_copy(update={"lidar": None}), root, frames=args.frames)
        print(f"{root}: per image, median of {args.repeats} passes")
        print(f"  {'kind':<11} {'adaptive, level 3':>22} {'as written':>22}   pixels")
        total_before = total_now = 0.0
        for kind, setting in KINDS.items():
            paths = sorted((root / "training" / kind).glob("*.png"))[: args.frames]
            images = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in paths]
            ms0, kb0, before = timed(adaptive, images, args.repeats)
            ms1, kb1, now = timed(lambda im, s=setting: encode_png(im, s), images, args.repeats)
            same = all(np.array_equal(cv2.imdecode(np.frombuffer(a, np.uint8), cv2.IMREAD_UNCHANGED),
                                      cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_UNCHANGED))
                       for a, b in zip(before, now))
            total_before, total_now = total_before + ms0, total_now + ms1
            print(f"  {kind:<11} {ms0:8.1f} ms {kb0:8.1f} kB {ms1:8.1f} ms {kb1:8.1f} kB   "
                  f"{'identical' if same else 'DIFFER'}")
        print(f"  a frame's three files: {total_before:.1f} -> {total_now:.1f} ms ({len(images)} frames)")


if __name__ == "__main__":
    main()
