"""FlexiNet CPU figures: milliseconds per 1242x375 image at the weights' inference size, and the
training time a run needed to reach a Car 2D AP|R40 moderate target (from its history.csv).

    .venv/bin/python benchmarks/bench_detector.py [--weights W] [--threads 2] [--runs 30]
                                                  [--history RUN/history.csv [FT/history.csv]] [--target 90]
                                                  [--scales 1,1.25,0.83]

The network, and the whole read at scale 1 mirrored and in one pass; then the mirrored read at
`--scales` (default: the shipped weights' read, `detector.infer.DEFAULT_SCALES`).
"""
from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
import csv
import statistics
import time
from dataclasses import replace

import numpy as np
import torch

from detector.boxes import Letterbox
from detector.infer import DEFAULT_SCALES, DEFAULT_WEIGHTS, Detector, parse_scales
from detector.model import count_parameters
from detector.nms import postprocess


def time_inference(det: Detector, runs: int, img: np.ndarray, scales: tuple[float, ...]) -> dict[str, float]:
    """Median times on one 1242x375 image (post-processing cost depends on the image: use a real
    frame; uniform noise makes thousands of low-score candidates and a slow NMS): the network once,
    and the whole detection read at scale 1 mirrored or once, and read mirrored at `scales`."""
    lb = Letterbox.fit(1242, 375, *det.input_size)
    x = torch.from_numpy(lb.apply(img)[None]).permute(0, 3, 1, 2).float().div_(255)
    single = replace(det, mirror=False)
    scaled = replace(det, scales=scales)
    for _ in range(3):
        det.detect([img])
    net, mirrored, once, at_scales = [], [], [], []
    with torch.no_grad():
        for _ in range(runs):
            t0 = time.perf_counter()
            raw = det.models[0].predict_raw(x)
            net.append(time.perf_counter() - t0)
            postprocess(raw)
            for d, acc in ((det, mirrored), (single, once), (scaled, at_scales)):
                t0 = time.perf_counter()
                d.detect([img])
                acc.append(time.perf_counter() - t0)
    return {"network_ms": 1000 * statistics.median(net),
            "end_to_end_ms": 1000 * statistics.median(mirrored),
            "one_pass_ms": 1000 * statistics.median(once),
            "scales_ms": 1000 * statistics.median(at_scales)}


def time_to_target(histories: list[str], target: float) -> str:
    """Training stages run one after the other (e.g. a run, then a fine-tune started from it)."""
    rows = [r for h in histories for r in csv.DictReader(open(h))]
    elapsed = 0.0
    for r in rows:
        elapsed += float(r["seconds"])
        ap = r.get("Car_2d_R40_moderate") or ""
        if ap and float(ap) >= target:
            return (f"Car 2D AP|R40 moderate >= {target} first after {rows.index(r) + 1} epochs "
                    f"({float(ap):.2f}) after {elapsed / 60:.1f} min of training (evaluations included)")
    last = [r for r in rows if r.get("Car_2d_R40_moderate")]
    best = max((float(r["Car_2d_R40_moderate"]) for r in last), default=float("nan"))
    return f"target {target} not reached in {len(rows)} epochs ({elapsed / 60:.1f} min); best {best:.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", default=str(DEFAULT_WEIGHTS))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--history", nargs="+", default=None,
                    help="history.csv of a training run (several: stages run one after the other)")
    ap.add_argument("--target", type=float, default=90.0)
    ap.add_argument("--data", default=None, help="KITTI root whose first frame is timed (default: noise)")
    ap.add_argument("--scales", default=",".join(f"{v:g}" for v in DEFAULT_SCALES),
                    help="also time the mirrored read at these input scales (comma-separated, "
                         "`testbed detect --scales`; default: the shipped read)")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    det = Detector.load(a.weights, mirror=True, scales=(1.0,))
    w, h = det.input_size
    if a.data:
        from kitti.dataset import KittiDataset
        ds = KittiDataset(a.data)
        img, src = ds.image(ds.ids(None)[0]), f"frame {ds.ids(None)[0]} of {a.data}"
    else:
        img, src = np.random.default_rng(0).integers(0, 256, (375, 1242, 3), dtype=np.uint8), "uniform noise"
    if img.shape[:2] != (375, 1242):
        raise SystemExit(f"{src} is {img.shape[1]}x{img.shape[0]}, not 1242x375")
    scales = parse_scales(a.scales)
    t = time_inference(det, a.runs, img, scales)
    print(f"weights {a.weights}: {sum(map(count_parameters, det.models)) / 1e6:.2f} M parameters (BN folded), "
          f"input {w}x{h}, {a.threads} thread(s), median of {a.runs}, image: {src}")
    print(f"  network forward (one of {len(det.models)}):           {t['network_ms']:.1f} ms per 1242x375 image")
    print(f"  letterbox + network + NMS + mapping, the image and its mirror at scale 1: {t['end_to_end_ms']:.1f} ms "
          "per 1242x375 image")
    print(f"  the same, one pass (--no-mirror):   {t['one_pass_ms']:.1f} ms per 1242x375 image")
    print(f"  the image and its mirror at scales {a.scales}: {t['scales_ms']:.1f} ms per 1242x375 image")
    if a.history:
        print("  " + time_to_target(a.history, a.target))


if __name__ == "__main__":
    main()
