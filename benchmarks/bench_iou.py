"""Pairwise 3D IoU of 2,000 x 2,000 boxes (the budget: under 1 s on a 2-core CPU).

Two sets: a KITTI-like street (boxes spread over 80 m x 80 m, each detection near a truth box, the
case the evaluation meets) and a worst case in which every pair overlaps (all boxes in 6 m x 6 m).
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import time

import numpy as np

from kitti.iou import iou_3d, iou_bev


def street(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    a = np.column_stack([rng.uniform(-40, 40, n), rng.uniform(1, 2, n), rng.uniform(0, 80, n),
                         rng.uniform(1.4, 1.7, n), rng.uniform(1.5, 1.8, n), rng.uniform(3.5, 4.5, n),
                         rng.uniform(-np.pi, np.pi, n)])
    b = a + rng.normal(0, 1, a.shape) * np.array([0.3, 0.03, 0.3, 0.05, 0.05, 0.1, 0.2])
    return a, b


def dense(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    def one():
        return np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-0.2, 0.2, n), rng.uniform(-3, 3, n),
                                rng.uniform(1, 2, n), rng.uniform(1, 3, n), rng.uniform(2, 5, n),
                                rng.uniform(-np.pi, np.pi, n)])
    return one(), one()


def best_of(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(0)
    for name, make in (("street", street), ("all pairs overlap", dense)):
        a, b = make(rng, 2000)
        t3 = best_of(lambda: iou_3d(a, b))
        tb = best_of(lambda: iou_bev(a, b))
        nz = int((iou_bev(a, b) > 0).sum())
        print(f"2000 x 2000 {name:18s}: 3D IoU {t3 * 1000:7.1f} ms, BEV IoU {tb * 1000:7.1f} ms "
              f"({nz} overlapping pairs)")


if __name__ == "__main__":
    main()
