"""Ring bookkeeping: keep every k-th ring (thesis 000: 64 -> 32 -> 16) and recover the rings
of a real KITTI scan that has no side file.

Recovery. KITTI .bin points are stored laser by laser, each laser one revolution in firing
order, so within a ring the azimuth moves steadily one way and it jumps back by about 2 pi where
the next ring starts. Where a revolution starts (the seam) depends on the recording: KITTI's
start at the front (azimuth 0, where the camera is triggered), the simulator's at the back (pi).
Cut at the wrong seam, every laser's revolution splits in two and each run joins the second half
of one laser to the first half of the next (65 runs for 64 lasers, their elevations mixed), so
the seam is the one of {back, front} that gives exactly one run per laser. Rings are the runs
between those jumps, numbered from the top by their median elevation; a laser whose revolution does not start exactly at the back
wraps inside its own ring, and the few points that end up on the wrong side of a jump rejoin
the ring they share an elevation with. When the jumps do not give exactly the expected ring count
(an empty ring, a ring cut at the back), rings come from 1-D k-means on the elevation angle
instead, started from the HDL-64E table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .median import group_medians, median

# The HDL-64E S2 as mounted on the KITTI car (KITTI's only LiDAR): an upper block of 32 lasers
# from +2.0 deg down in 1/3 deg steps and a lower block of 32 lasers ending at -24.9 deg in about
# 1/2 deg steps. Ring recovery starts its elevation clustering from this table; the simulator's
# `hdl64e` preset uses the same one.
_HDL64E_UPPER = tuple(round(2.0 - i / 3.0, 4) for i in range(32))  # +2.0 ... -8.333
_HDL64E_LOWER = tuple(round(-8.83 - i * (24.9 - 8.83) / 31.0, 4) for i in range(32))  # -8.83 ...
HDL64E_ELEVATIONS = _HDL64E_UPPER + _HDL64E_LOWER


def kept_rings(beams_in: int, beams_out: int) -> np.ndarray:
    """Rings 0, k, 2k, ... with k = beams_in / beams_out (ring 0 = top beam)."""
    if beams_out <= 0 or beams_out > beams_in or beams_in % beams_out:
        raise ValueError(f"--beams {beams_out} must divide the scan's {beams_in} beams "
                         f"(keeps every {beams_in}//N-th ring)")
    return np.arange(0, beams_in, beams_in // beams_out)


def reduce_rings(ring: np.ndarray, beams_in: int, beams_out: int) -> tuple[np.ndarray, np.ndarray]:
    """(mask of points kept, their new ring index 0..beams_out-1)."""
    k = beams_in // beams_out
    kept_rings(beams_in, beams_out)
    mask = (ring.astype(np.int64) % k) == 0
    return mask, (ring[mask] // k).astype(np.uint8)


def elevation(points: np.ndarray) -> np.ndarray:
    return np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]))


SEAMS = ("back", "front")  # where a revolution may start: azimuth pi (simulator), 0 (KITTI)


def _median_sign(x: np.ndarray) -> float:
    """np.sign(np.median(x)) for a non-empty x without NaN, by counting: when more than half
    of x is positive (negative), so are the middle values and their mean, and only a near tie
    needs the median itself. Partitioning x for its median took as long as the rest of the run
    search, and only the sign is used."""
    if np.count_nonzero(x > 0) > len(x) / 2:
        return 1.0
    if np.count_nonzero(x < 0) > len(x) / 2:
        return -1.0
    return np.sign(np.median(x))


def rings_from_azimuth_wraps(points: np.ndarray, jitter_deg: float = 0.25,
                             seam: str = "back", az: np.ndarray | None = None) -> np.ndarray:
    """Run index per point: a new run starts wherever the azimuth wraps at the seam (jumps by
    more than pi either way) or steps back against the rotation by more than `jitter_deg`.

    `az`, if given, is np.arctan2(y, x) of the points: recover_rings tries both seams on one
    scan and computes it once."""
    if len(points) < 2:
        return np.zeros(len(points), np.int64)
    if az is None:
        az = np.arctan2(points[:, 1], points[:, 0])  # (-pi, pi]: wraps at the back
    if seam == "front":  # [0, 2 pi): wraps at the front
        # np.mod(az, 2 pi) bit for bit, as az is in [-pi, pi], without np.mod's slow division
        # (+ 0.0 turns -0.0 into 0.0, as np.mod does)
        az = np.where(az < 0, az + 2 * np.pi, az + 0.0)
    d = np.diff(az)
    small = d[np.abs(d) < np.pi]
    direction = _median_sign(small) if len(small) else 1.0  # the way the lasers rotate
    starts = (np.abs(d) > np.pi) | (direction * d < -np.deg2rad(jitter_deg))
    runs = np.zeros(len(az), np.int64)
    np.cumsum(starts, out=runs[1:])  # in place: one scan-sized array fewer
    return runs


def rings_from_elevation(points: np.ndarray, beams: int, iterations: int = 30,
                         el: np.ndarray | None = None) -> np.ndarray:
    """1-D k-means on elevation (`el`, if given, is elevation(points)); ring 0 is the highest
    cluster."""
    el = np.degrees(elevation(points) if el is None else el)
    if beams == len(HDL64E_ELEVATIONS):
        centres = np.asarray(HDL64E_ELEVATIONS, float)[::-1].copy()  # ascending
    else:
        centres = np.quantile(el, (np.arange(beams) + 0.5) / beams)
    for _ in range(iterations):
        centres = np.sort(centres)
        lab = np.searchsorted(0.5 * (centres[1:] + centres[:-1]), el)
        sums = np.bincount(lab, weights=el, minlength=beams)
        cnt = np.bincount(lab, minlength=beams)
        new = np.where(cnt > 0, sums / np.maximum(cnt, 1), centres)
        if np.allclose(new, centres, atol=1e-6):
            break
        centres = new
    centres = np.sort(centres)
    lab = np.searchsorted(0.5 * (centres[1:] + centres[:-1]), el)
    return (beams - 1 - lab).astype(np.int64)


def merge_short_runs(runs: np.ndarray, el: np.ndarray, share: float = 0.05) -> np.ndarray:
    """Fold runs shorter than `share` of the median run into the neighbour nearest in elevation.

    A laser whose revolution does not start exactly at the back wraps inside its own ring: a
    few of its points land beyond the wrap, next to the neighbouring laser's, and form short
    runs; each rejoins the ring it shares an elevation with.

    The work is done on stretches (maximal slices of equal `runs`; a run of
    rings_from_azimuth_wraps is one slice), never on the points: a merge relabels stretches,
    and a run's elevations are its stretches' slices of `el`, in scan order as el[runs == id].
    Sorting every point (np.unique) and masking the whole scan per run cost more than the
    merging, which a scan mostly does not need.
    """
    cut = np.flatnonzero(runs[1:] != runs[:-1]) + 1
    first = np.concatenate([[0], cut]) if len(runs) else cut  # where each stretch starts
    size = np.diff(np.append(first, len(runs)))  # points per stretch
    owner = runs[first]  # run of each stretch, relabelled by merges

    def elevations(run):
        at = owner == run
        return np.concatenate([el[a:a + n] for a, n in zip(first[at], size[at])])

    while True:
        ids, of = np.unique(owner, return_inverse=True)
        length = np.bincount(of, weights=size, minlength=len(ids)).astype(np.int64)
        short = np.flatnonzero(length < share * np.median(length))
        if len(ids) < 2 or not len(short):
            break
        k = short[np.argmin(length[short])]
        med = [np.median(elevations(ids[j])) if 0 <= j < len(ids) else np.inf
               for j in (k - 1, k, k + 1)]
        into = k - 1 if abs(med[0] - med[1]) <= abs(med[2] - med[1]) else k + 1
        owner[owner == ids[k]] = ids[into]
    return np.repeat(np.unique(owner, return_inverse=True)[1], size)


@dataclass(frozen=True)
class RecoveredRings:
    """A scan's rings: which ring each return belongs to, and where the rings point."""

    ring: np.ndarray       # (N,) uint8, 0 = top
    elevation: np.ndarray  # (beams,) each ring's median elevation, radians (NaN: a ring without returns)
    method: str            # "azimuth-wrap" or "elevation-kmeans"


def recover_rings(points: np.ndarray, beams: int = 64, el: np.ndarray | None = None,
                  az: np.ndarray | None = None) -> RecoveredRings:
    """Rings of a KITTI-ordered scan (0 = top), their median elevations and the method that
    found them.

    The azimuth is computed once for both seams. The runs come out in scan order (a short run
    joins a neighbour: elevations are finite), so ring k is the slice of the scan between its
    bounds, and its median elevation is taken on that slice instead of on a mask of the whole
    scan per ring. `el` and `az`, if given, are elevation(points) and np.arctan2(y, x): a caller
    that reads them too (the fidelity report) computes them once."""
    el = elevation(points) if el is None else el
    az = np.arctan2(points[:, 1], points[:, 0]) if az is None else az
    for seam in SEAMS if len(points) else ():
        runs = merge_short_runs(rings_from_azimuth_wraps(points, seam=seam, az=az), el)
        if runs.max() + 1 == beams:
            bounds = np.searchsorted(runs, np.arange(beams + 1))
            med = np.array([median(el[a:b]) for a, b in zip(bounds[:-1], bounds[1:])])
            rank = np.empty(beams, np.int64)
            rank[np.argsort(-med)] = np.arange(beams)
            elevations = np.empty(beams)
            elevations[rank] = med
            return RecoveredRings(rank.astype(np.uint8)[runs], elevations, "azimuth-wrap")
    ring = rings_from_elevation(points, beams, el=el).astype(np.uint8)
    return RecoveredRings(ring, group_medians(ring, el, beams), "elevation-kmeans")
