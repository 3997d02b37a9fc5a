"""The headline statistics: one number per dataset each, under a stable key shared by the report,
fidelity.json and tolerances.yaml. Per-frame values are summarised by their median over frames,
per-object ones (distance, 2D height, projection gap, points on a Car, the look of a near Car) by
their median over objects."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from .images import CANNY, HIGH_PASS_PX, NEAR_CAR_PX, ROAD_SURFACE_BANDS
from .lidar import FAR_M, GROUND_M, NEAR_M, SECTOR_DEG
from .stats import DatasetStats, Draws


class Summary(Protocol):
    """A statistic's one number: of a dataset (called on it) and of each bootstrap draw of its
    frames (`draws`: the same numbers as calling it on each draw's `DatasetStats.resample`)."""

    def __call__(self, d: DatasetStats) -> float: ...

    def draws(self, dr: Draws) -> np.ndarray: ...


@dataclass(frozen=True)
class Stat:
    key: str
    label: str
    unit: str
    value: Summary


def _median(v: np.ndarray) -> float:
    v = np.asarray(v, np.float64)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if len(v) else float("nan")


def _share(v: np.ndarray, test: Callable[[np.ndarray], np.ndarray]) -> float:
    return float(np.mean(test(v))) if len(v) else float("nan")


@dataclass(frozen=True)
class Median:
    """Median over the finite values of `key` (those `keep` selects)."""

    key: str
    keep: Callable[[DatasetStats], np.ndarray] | None = None

    def _kept(self, d: DatasetStats, a: np.ndarray) -> np.ndarray:
        return a if self.keep is None else a[self.keep(d)]

    def __call__(self, d: DatasetStats) -> float:
        return _median(self._kept(d, d.get(self.key)))

    def draws(self, dr: Draws) -> np.ndarray:
        d = dr.stats
        v, f = self._kept(d, d.get(self.key)), self._kept(d, d.frames_of(self.key))
        finite = np.isfinite(v)
        return dr.medians(v[finite], f[finite])


@dataclass(frozen=True)
class Share:
    """Share of the values of `key` that pass `test`."""

    key: str
    test: Callable[[np.ndarray], np.ndarray]

    def __call__(self, d: DatasetStats) -> float:
        return _share(d.get(self.key), self.test)

    def draws(self, dr: Draws) -> np.ndarray:
        return dr.shares(self.test(dr.stats.get(self.key)), dr.stats.frames_of(self.key))


def med(key: str) -> Median:
    return Median(key)


def column_nanmedians(rows: np.ndarray) -> np.ndarray:
    """np.nanmedian(rows, axis=0), the same numbers, by one sort (NaN sorts last): numpy's own
    runs a Python loop per column from 600 rows on."""
    s = np.sort(rows, axis=0)
    n = np.count_nonzero(~np.isnan(rows), axis=0)
    cols = np.arange(rows.shape[1])
    return (s[np.maximum(n - 1, 0) // 2, cols] + s[n // 2, cols]) / 2  # NaN where n == 0


@dataclass(frozen=True)
class RingMedian:
    """Median over frames per ring of the rows of `key`, then `pick` over the 64 rings (a ring
    empty in every frame stays NaN)."""

    key: str
    pick: Callable[[np.ndarray], float]

    def __call__(self, d: DatasetStats) -> float:
        rows = d.rows.get(self.key)
        if rows is None or not len(rows):
            return float("nan")
        return float(self.pick(column_nanmedians(rows)))

    def draws(self, dr: Draws) -> np.ndarray:
        if self.key not in dr.stats.rows:
            return np.full(len(dr.counts), np.nan)
        drawn = dr.drawn(dr.stats.row_frames[self.key])  # rows in each draw
        return np.array([self.pick(m) if n else np.nan
                         for m, n in zip(dr.column_medians(self.key), drawn)], np.float64)


def ring_median(key: str, pick: Callable[[np.ndarray], float]) -> RingMedian:
    return RingMedian(key, pick)


def car_points(lo: float, hi: float, visible: bool = False, key: str = "lidar.car_points") -> Median:
    """Median returns inside the Cars at lo-hi m (or another per-Car value, `key`); `visible`:
    only those labelled occlusion 0."""
    def keep(d: DatasetStats) -> np.ndarray:
        dist = d.get("lidar.car_distance_m")
        keep = (dist >= lo) & (dist < hi)
        if visible:
            keep &= d.get("lidar.car_occluded") == 0
        return keep
    return Median(key, keep)


STATS: tuple[Stat, ...] = (
    Stat("lidar.points_per_sweep", "points per sweep", "", med("lidar.points")),
    *(Stat(f"lidar.range_p{q}_m", f"range, {q}th percentile", "m", med(f"lidar.range_p{q}_m"))
      for q in (10, 50, 90, 99)),
    Stat("lidar.beyond_40m_share", "share of returns beyond 40 m", "", med("lidar.beyond_40m")),
    Stat("lidar.beyond_80m_share", "share of returns beyond 80 m", "", med("lidar.beyond_80m")),
    *(Stat(f"lidar.beyond_40m_{where}_share", f"share of returns beyond {FAR_M[0]:.0f} m, {what}", "",
           med(f"lidar.beyond_40m_{where}"))
      for where, what in (("ahead", f"within {SECTOR_DEG:.0f} deg of ahead"),
                          ("beside", "beside the sensor"),
                          ("behind", f"within {SECTOR_DEG:.0f} deg of behind"))),
    Stat("lidar.far_height_m", f"median height of the returns beyond {FAR_M[0]:.0f} m above the road "
         "plane", "m", med("lidar.far_height_m")),
    Stat("lidar.returns_per_ring", "returns per ring (median ring)", "",
         ring_median("lidar.ring_returns", np.median)),
    Stat("lidar.ring_elevation_top_deg", "elevation of the top ring", "deg",
         ring_median("lidar.ring_elevation_deg", lambda e: e[np.isfinite(e)][0])),
    Stat("lidar.ring_elevation_bottom_deg", "elevation of the lowest ring with returns", "deg",
         ring_median("lidar.ring_elevation_deg", lambda e: e[np.isfinite(e)][-1])),
    Stat("lidar.rings_with_returns", "rings with returns (of 64)", "",
         ring_median("lidar.ring_returns", lambda n: np.count_nonzero(n > 0))),
    Stat("lidar.reflectance_mean", "mean reflectance", "", med("lidar.reflectance_mean")),
    Stat("lidar.reflectance_zero_share", "share of reflectance exactly 0", "",
         med("lidar.reflectance_zero")),
    Stat("lidar.far_reflectance_nonzero_median", f"median nonzero reflectance of the returns beyond "
         f"{FAR_M[0]:.0f} m", "", med("lidar.far_reflectance_nonzero")),
    Stat("lidar.ground_share", f"share of ground returns (within {GROUND_M} m of the road plane)",
         "", med("lidar.ground_share")),
    *(Stat(f"lidar.near_ground_share_{side}", f"share of ground returns within {NEAR_M:.0f} m, {side} "
           "of the sensor", "", med(f"lidar.near_ground_{side}")) for side in ("left", "right")),
    Stat("lidar.car_points_0_20m", "points on a Car at 0-20 m", "", car_points(0, 20)),
    Stat("lidar.car_points_20_40m", "points on a Car at 20-40 m", "", car_points(20, 40)),
    Stat("lidar.car_points_40_80m", "points on a Car at 40-80 m", "", car_points(40, 80)),
    Stat("lidar.visible_car_points_20_40m", "points on a fully visible Car at 20-40 m", "",
         car_points(20, 40, visible=True)),
    Stat("lidar.visible_car_points_40_80m", "points on a fully visible Car at 40-80 m", "",
         car_points(40, 80, visible=True)),
    Stat("lidar.car_bottom_above_road_m", "a Car label's bottom above the scan's road under it", "m",
         med("lidar.car_bottom_above_road_m")),
    Stat("lidar.car_zero_share_0_20m", "share of the points on a Car at 0-20 m that read 0", "",
         car_points(0, 20, key="lidar.car_zero_share")),
    Stat("images.grey_mean", "mean grey level", "", med("images.grey_mean")),
    Stat("images.grey_sd", "grey standard deviation (contrast)", "", med("images.grey_sd")),
    Stat("images.saturation_mean", "mean HSV saturation", "", med("images.saturation_mean")),
    Stat("images.mean_abs_dx", "mean |dI/dx| of the grey image", "grey levels",
         med("images.mean_abs_dx")),
    Stat("images.flat_share", "share of flat pixels (|dI/dx| < 1)", "", med("images.flat_share")),
    Stat("images.edge_density", f"edge density (Canny {CANNY[0]}/{CANNY[1]})", "",
         med("images.edge_density")),
    Stat("images.png_bytes", "PNG size of its pixels (one fixed encoder)", "bytes",
         med("images.png_bytes")),
    Stat("images.road_colour_noise", f"bottom fifth's colour noise: robust SD of R - G after a "
         f"{HIGH_PASS_PX:g}-px high-pass", "grey levels", med("images.road_colour_noise")),
    Stat("images.road_detail", f"bottom fifth's detail: robust SD of the grey after a "
         f"{HIGH_PASS_PX:g}-px high-pass", "grey levels", med("images.road_detail")),
    *(Stat(f"images.road_surface_{kind}_{lo:g}_{hi:g}m",
           f"road surface at {lo:g}-{hi:g} m (pixels of the LiDAR's road returns): {what}",
           "grey levels", med(f"images.road_surface_{kind}_{lo:g}_{hi:g}m"))
      for lo, hi in ROAD_SURFACE_BANDS
      for kind, what in (("colour_noise", "colour noise"), ("detail", "detail"))),
    Stat("labels.objects_per_frame", "objects per frame (not DontCare)", "", med("labels.objects")),
    Stat("labels.cars_per_frame", "Cars per frame", "", med("labels.cars")),
    Stat("labels.distance_m", "object distance (ground x-z)", "m", med("labels.distance_m")),
    Stat("labels.fully_visible_share", "share of objects with occlusion 0", "",
         Share("labels.occlusion", lambda v: v == 0)),
    Stat("labels.truncated_share", "share of objects with truncation > 0", "",
         Share("labels.truncation", lambda v: v > 0)),
    Stat("labels.box_height_px", "2D box height", "px", med("labels.box_height_px")),
    Stat("labels.proj_gap_px", "2D box vs projected 3D box, max side gap", "px",
         med("labels.proj_gap_px")),
    Stat("labels.car_grey_mean", f"grey mean inside a near, whole Car's 2D box (>= {NEAR_CAR_PX} px)", "",
         med("labels.car_grey_mean")),
    Stat("labels.car_grey_sd", "grey standard deviation inside it (RMS contrast)", "",
         med("labels.car_grey_sd")),
    Stat("labels.car_abs_dx", "mean |dI/dx| inside it", "grey levels", med("labels.car_abs_dx")),
    Stat("labels.car_bottom_darkening", "its grey mean less that of its lowest eighth", "grey levels",
         med("labels.car_bottom_darkening")),
    Stat("labels.proj_within_1px_share", "share of objects with that gap within 1 px", "",
         Share("labels.proj_gap_px", lambda v: v <= 1.0)),
)
STAT_KEYS = frozenset(s.key for s in STATS)
