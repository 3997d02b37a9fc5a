"""The HDL-64E's reflectance channel as KITTI recorded it: the statistics behind the sensor
constants of `simgen.lidar` (LidarSpec's reflectance fields), measured on every frame of a real
KITTI root, pooled (no per-frame tuning).

Lasers are separated exactly: a KITTI .bin stores the sweep laser by laser in firing order, so
the runs between azimuth wraps are the lasers (64 runs plus the first laser's tail at the end).
Road points: within 0.1 m of the RANSAC road plane (`lifter.ground`), which also gives the
incidence (cos = |plane normal . ray|).

Usage: .venv/bin/python benchmarks/lidar_reflectance_stats.py --root REAL

Section 7 fits the reading's compensation range (LidarSpec.compensation_range) to the road's far
readings through the preset's own reading model.
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from pathlib import Path

import numpy as np

from kitti.calib import read_calib
from kitti.rings import elevation, rings_from_azimuth_wraps
from lifter.ground import fit_ground_plane, height_above

ROAD_M = 0.1  # a return this close to the road plane is road
NEAR_ROAD = (4.0, 20.0)  # road range where the reading is compensated (flat in range)
# probabilities at which section 4 prints the shape of the readings' scatter, denser in the tails
SHAPE_P = (0.001, 0.005, 0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99, 0.995, 0.999)
DARK_RANGE, GAMMA = 50.0, np.log(0.8 / 0.1) / np.log(120.0 / 50.0)  # hdl64e power law


def robust_sd(x: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def load(root: Path) -> list[dict]:
    frames = []
    for f in sorted((root / "training" / "velodyne").glob("*.bin")):
        p = np.fromfile(f, np.float32).reshape(-1, 4)
        laser = rings_from_azimuth_wraps(p, jitter_deg=5.0)
        if laser.max() == 64:
            laser[laser == 64] = 0  # the first laser's tail, after the wrap at the back
        else:
            laser = np.full(len(p), -1)
        calib = read_calib(root / "training" / "calib" / f"{f.stem}.txt")
        rect = calib.lidar_to_rect(p[:, :3].astype(np.float64))
        plane = fit_ground_plane(rect)
        r = np.linalg.norm(p[:, :3].astype(np.float64), axis=1)
        frames.append({"v": p[:, 3], "r": r, "laser": laser, "el": np.degrees(elevation(p)),
                       "road": np.abs(height_above(rect, plane)) < ROAD_M,
                       "cos": np.abs(rect @ plane[:3]) / np.maximum(r, 1e-9)})
    return frames


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", required=True, help="a real KITTI root (training/velodyne, calib)")
    args = ap.parse_args()
    frames = load(Path(args.root))
    cat = {k: np.concatenate([f[k] for f in frames]) for k in frames[0]}
    v, r, road = cat["v"], cat["r"], cat["road"]
    k100 = np.round(v.astype(np.float64) * 100).astype(int)
    print(f"{len(frames)} frames, {len(v)} returns; lasers separated in "
          f"{sum(f['laser'].max() >= 0 for f in frames)} frames")

    print("\n1. quantisation")
    print(f"   every value is float32(k/100): {np.array_equal(np.float32(k100 / 100.0), v)}; "
          f"{len(np.unique(k100))} distinct values, largest {v.max():.2f} "
          f"({100 * (v >= v.max()).mean():.2f} % of returns), none above")
    share = np.bincount(k100, minlength=101) / len(v)
    print("   share of 0.00, 0.01, ..., 0.06 (%): " + ", ".join(f"{100 * s:.2f}" for s in share[:7]))

    print("\n2. road reading against incidence (road, nonzero)")
    for lo, hi in [(0.25, 0.4), (0.15, 0.25), (0.10, 0.15), (0.07, 0.10), (0.05, 0.07)]:
        m = road & (cat["cos"] >= lo) & (cat["cos"] < hi) & (r < 25)
        nz = v[m][v[m] > 0]
        print(f"   cos {lo:.2f}-{hi:.2f}: {m.sum():7d} returns, median {np.median(nz):.2f}, "
              f"zero {100 * (v[m] == 0).mean():4.1f} %")

    print("\n3. road zero share against range")
    rows = []
    for lo, hi in [(4, 10), (10, 20), (20, 25), (25, 30), (30, 40), (40, 60)]:
        m = road & (r >= lo) & (r < hi)
        z = float((v[m] == 0).mean())
        rows.append((np.sqrt(lo * hi), z))
        print(f"   {lo:2d}-{hi:2d} m: {m.sum():7d} road returns, zero {100 * z:4.1f} %")
    near = road & (r >= NEAR_ROAD[0]) & (r < NEAR_ROAD[1])
    med = float(np.median(v[near][v[near] > 0]))
    d, z = np.array(rows).T
    i = int(np.flatnonzero(z >= 0.5)[0])
    d50 = float(np.exp(np.interp(0.5, [z[i - 1], z[i]], np.log([d[i - 1], d[i]]))))
    p0 = med / 0.1 * (DARK_RANGE / d50) ** GAMMA
    print(f"   median nonzero road reading at {NEAR_ROAD[0]:.0f}-{NEAR_ROAD[1]:.0f} m: {med:.3f}; "
          f"half the road returns read 0 at {d50:.1f} m (log-interpolated between bin centres)")
    print(f"   -> the reading floor reaches that median at {d50:.1f} m: floor = {0.1 * p0:.3f} * "
          f"(d / {DARK_RANGE:.0f} m)^{GAMMA:.3f}, i.e. a return reads 0 below {p0:.2f} x the "
          "detection threshold power")

    if any(f["laser"].max() >= 0 for f in frames):
        per_laser(frames)
    else:
        print("\n4.-5. per laser: skipped, no frame stores its sweep laser by laser")

    print("\n6. near range (all returns)")
    for lo, hi in [(0, 2.5), (2.5, 5), (5, 10), (10, 20), (20, 40)]:
        m = (r >= lo) & (r < hi)
        nz = v[m][v[m] > 0]
        print(f"   {lo:4.1f}-{hi:4.1f} m: zero {100 * (v[m] == 0).mean():4.1f} %, at 0.99 "
              f"{100 * (v[m] >= 0.99).mean():.2f} %, nonzero median {np.median(nz):.2f}")

    far_readings(v, r, road)


def per_laser(frames: list[dict]) -> None:
    """Sections 4 and 5: the lasers' gains, scatter and return counts (frames stored laser by laser)."""
    print("\n4. per laser (road at 4-20 m, nonzero readings)")
    meds = np.full((len(frames), 64), np.nan)
    spreads, devs = [], []
    jitter = np.random.default_rng(0)
    counts = np.full((len(frames), 64), np.nan)
    els = np.full((len(frames), 64), np.nan)
    for fi, f in enumerate(frames):
        if f["laser"].max() < 0:
            continue
        sel = f["road"] & (f["r"] >= NEAR_ROAD[0]) & (f["r"] < NEAR_ROAD[1]) & (f["v"] > 0)
        for k in range(64):
            m = sel & (f["laser"] == k)
            counts[fi, k] = np.count_nonzero(f["laser"] == k)
            els[fi, k] = np.median(f["el"][f["laser"] == k])
            if m.sum() >= 50:
                meds[fi, k] = np.median(f["v"][m])
                spreads.append(robust_sd(np.log(f["v"][m])))
                # spread evenly over its 0.01 step, so the quantiles do not step with KITTI's
                v = f["v"][m].astype(np.float64) + jitter.uniform(-0.005, 0.005, m.sum())
                devs.append(np.log(v) - np.median(np.log(v)))
    lm = np.nanmedian(meds, axis=0)
    lm = np.log(lm[np.isfinite(lm)] / np.median(lm[np.isfinite(lm)]))
    print(f"   {len(lm)} lasers see enough road: sd of log(laser median / all-laser median) = "
          f"{lm.std():.3f} (robust {robust_sd(lm):.3f}); range x{np.exp(lm.min()):.2f} to "
          f"x{np.exp(lm.max()):.2f}")
    lo, mid, hi = np.percentile(lm, [15.87, 50, 84.13])
    print(f"   one-sided spreads of the lasers' log medians (50th less 16th, 84th less 50th percentile): "
          f"below {mid - lo:.3f}, above {hi - mid:.3f}")
    print(f"   within one laser and frame, robust sd of log(reading): median {np.median(spreads):.3f} "
          f"(quartiles {np.percentile(spreads, 25):.3f}, {np.percentile(spreads, 75):.3f}; "
          f"{len(spreads)} laser-frames)")
    dev = np.concatenate(devs)
    sd = robust_sd(dev)
    print(f"   pooled deviations of log(reading) from their laser-frame's median ({len(dev)} returns; "
          f"readings spread over their 0.01 step): robust sd {sd:.3f}; in units of it, quantiles at "
          + ", ".join(f"{p:g}" for p in SHAPE_P) + " (the model's scatter is symmetric in log):")
    print("   " + ", ".join(f"{q:.2f}" for q in np.percentile(dev, 100 * np.asarray(SHAPE_P)) / sd))

    print("\n5. per-laser return count (lower block, -10 to -20 deg: road or an obstacle at every azimuth)")
    order = np.argsort(-np.nanmedian(els, axis=0))
    c = np.nanmedian(counts, axis=0)[order]
    e = np.nanmedian(els, axis=0)[order]
    rel = np.array([c[i] / np.median(c[max(0, i - 2):i + 3]) for i in range(64)])
    low = (e < -10) & (e > -20)
    print(f"   {low.sum()} lasers: count / median of its 5 elevation neighbours: sd {rel[low].std():.4f}, "
          f"robust {robust_sd(rel[low]):.4f}, range {rel[low].min():.3f}-{rel[low].max():.3f}")


def scatter_quantiles(sigma: float, n: int = 4096) -> np.ndarray:
    """The reading's scatter factor as `simgen.lidar.scan` tabulates it: log-logistic whose log
    has robust sd `sigma`, (v / (1 - v)) ** (sigma / (1.4826 ln 3)) at the centres of n equal
    steps of a uniform v."""
    v = (np.arange(n) + 0.5) / n
    return ((v / (1.0 - v)) ** (sigma / (1.4826 * np.log(3.0)))).astype(np.float32)


def model_readings(d: np.ndarray, rho: float, d0: float, same_draw: bool, seed: int = 0,
                    draws: int = 20) -> np.ndarray:
    """The hdl64e preset's reading model (simgen.lidar.scan) at ranges `d` on a surface whose
    compensated reading has median `rho`: per-laser gain and reading scatter as the preset draws
    them; 0 below the clamp (refl_floor_power x the detection threshold), decided on the reading's
    own scatter draw (`same_draw`) or on a draw of its own; dimmed beyond `d0`; 0 below refl_floor.
    Zero-share readings are left out (they do not move the nonzero median)."""
    from simgen.lidar import preset

    spec = preset("hdl64e")
    rng = np.random.default_rng(seed)
    d = np.repeat(d, draws)
    q = scatter_quantiles(spec.reading_sigma)
    gain = np.exp(rng.normal(0.0, spec.gain_sigma, len(d)))
    e2 = q[rng.integers(0, len(q), len(d))]
    e1 = e2 if same_draw else q[rng.integers(0, len(q), len(d))]
    need = spec.threshold(d)
    s = gain * e2 * rho * np.minimum(1.0, (d0 / d) ** spec.range_exponent)
    return np.where((gain * e1 * rho >= spec.refl_floor_power * need) & (s >= spec.refl_floor), s, 0.0)


def far_readings(v: np.ndarray, r: np.ndarray, road: np.ndarray) -> None:
    print("\n7. far readings: nonzero median and zero share against range")
    bins = [(4, 20), (20, 30), (30, 40), (40, 50), (50, 60), (60, 81)]
    for name, sel in (("road", road), ("off the road", ~road)):
        for lo, hi in bins:
            m = sel & (r >= lo) & (r < hi)
            nz = v[m][v[m] > 0]
            print(f"   {name:12s} {lo:2d}-{hi:2d} m: {m.sum():7d} returns, zero {100 * (v[m] == 0).mean():4.1f} %, "
                  f"nonzero median {np.median(nz):.3f}")
    near = road & (r >= 4) & (r < 20)
    ref = float(np.median(v[near & (v > 0)]))
    # the surface whose model readings at 4-20 m have KITTI's nonzero median there
    unit = model_readings(r[near][::50], 1.0, 1e9, False)
    rho = ref / float(np.median(unit[unit > 0]))
    far = []  # per bin: the road returns' ranges, KITTI's nonzero median, the nonzero count
    for lo, hi in bins[1:]:
        m = road & (r >= lo) & (r < hi)
        lit = v[m & (v > 0)]
        far.append((r[m], float(np.median(lit)), len(lit)))

    def medians(d0: float, same_draw: bool) -> list[float]:
        out = []
        for d, _, _ in far:
            s = model_readings(d, rho, d0, same_draw)
            out.append(float(np.median(s[s > 0])) if np.any(s > 0) else np.nan)
        return out

    print(f"   the road as the preset's reading model reads it (reflectivity {rho:.3f}: its nonzero median at "
          f"4-20 m is KITTI's {ref:.2f}), nonzero median per bin 20-30 ... 60-81 m:")
    print("   KITTI:                                   " + " ".join(f"{o:.3f}" for _, o, _ in far))
    print("   clamp on the reading's own draw, no dimming: " + " ".join(f"{m:.3f}" for m in medians(1e9, True)))
    print("   clamp on a draw of its own, no dimming:      " + " ".join(f"{m:.3f}" for m in medians(1e9, False)))
    grid = np.arange(20.0, 60.01, 0.5)
    err = [sum(n * (np.log(m) - np.log(o)) ** 2 for (_, o, n), m in zip(far, medians(d0, False)))
           for d0 in grid]
    d0 = float(grid[int(np.argmin(err))])
    print(f"   clamp on a draw of its own, dimmed beyond d0: least squares in log over the bins, "
          f"weighted by their nonzero counts: d0 = {d0:.1f} m")
    print(f"   with d0 = {d0:.1f} m:                    " + " ".join(f"{m:.3f}" for m in medians(d0, False)))


if __name__ == "__main__":
    main()
