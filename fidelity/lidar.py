"""LiDAR statistics of one sweep, from the .bin alone (plus calib and labels for the road plane
and the points on each Car), so a real scan and a generated one are measured the same way."""

from __future__ import annotations

import numba
import numpy as np

from kitti.boxes import points_in_boxes
from kitti.calib import Calibration
from kitti.labels import Object3D
from kitti.rings import recover_rings
from lifter.ground import fit_ground_plane, height_above
from lifter.points import frame_points
from lifter.road import scan_road

from .stats import Acc

RINGS = 64
GROUND_M = 0.2  # a return this close to the fitted road plane is ground
NEAR_M = 8.0  # m (bird's-eye): the near field, about half of a sweep's returns, split by side
FAR_M = (40.0, 80.0)
# Where the returns beyond FAR_M[0] lie: within this many degrees of straight ahead or behind,
# or beside (a street's far end, its sides and side streets, what lies behind the car).
SECTOR_DEG = 30.0
PERCENTILES = (10, 50, 90, 99)


def lidar_stats(acc: Acc, scan: np.ndarray, calib: Calibration,
                labels: list[Object3D] | None) -> tuple[np.ndarray, np.ndarray] | None:
    """Per-frame values and pooled histograms of one (N, 4) scan; the returns in the rectified
    frame and their heights above the fitted road plane (None for an empty scan), which the
    image statistics of the road surface read."""
    pts = scan[:, :3].astype(np.float64)
    refl = scan[:, 3]
    acc.put("lidar.points", len(pts))
    if not len(pts):
        return None
    r = np.sqrt(np.einsum("ij,ij->i", pts, pts))
    for q, v in zip(PERCENTILES, np.percentile(r, PERCENTILES)):
        acc.put(f"lidar.range_p{q}_m", v)
    for far in FAR_M:
        acc.put(f"lidar.beyond_{far:.0f}m", np.count_nonzero(r > far) / len(r))
    acc.hist("lidar.range_m", r)
    acc.put("lidar.reflectance_mean", refl.mean(dtype=np.float64))
    acc.put("lidar.reflectance_zero", np.count_nonzero(refl == 0) / len(refl))
    acc.hist("lidar.reflectance", refl)
    bev = np.hypot(pts[:, 0], pts[:, 1])  # bird's-eye range
    # elevation (kitti.rings.elevation) and azimuth, computed once for the rings and the far field
    el, az = np.arctan2(pts[:, 2], bev), np.arctan2(pts[:, 1], pts[:, 0])
    _rings(acc, pts, el, az)
    rect = calib.lidar_to_rect(pts)
    height = height_above(rect, fit_ground_plane(rect))
    ground = np.abs(height) < GROUND_M
    acc.put("lidar.ground_share", np.count_nonzero(ground) / len(pts))
    _far(acc, az, r > FAR_M[0], height, refl)
    # where the ground share comes from: what stands beside the sensor on each side (LiDAR y left)
    near = bev < NEAR_M
    for side, m in (("left", near & (pts[:, 1] > 0)), ("right", near & (pts[:, 1] < 0))):
        if m.any():
            acc.put(f"lidar.near_ground_{side}", np.count_nonzero(ground[m]) / np.count_nonzero(m))
    if labels is not None:
        cars = [o for o in labels if o.type == "Car"]
        _car_points(acc, rect, refl, cars)
        _car_bottoms(acc, scan, calib, cars)
    return rect, height


def _far(acc: Acc, az: np.ndarray, far: np.ndarray, height: np.ndarray, refl: np.ndarray) -> None:
    """Where the far returns lie: their share of the sweep ahead, beside and behind the sensor
    (SECTOR_DEG), and their median height above the fitted road plane. Alike shares in every
    sector and alike heights say that a surplus of far returns is the view open more often,
    not one kind of surface. And how they read: the median of their nonzero reflectance (a
    sensor that compensates range fully reads far surfaces as near ones; KITTI's read dimmer)."""
    bearing = np.degrees(np.abs(az[far]))  # of the far returns (az: LiDAR azimuth), 0 ahead
    ahead, behind = bearing < SECTOR_DEG, bearing >= 180.0 - SECTOR_DEG
    for name, m in (("ahead", ahead), ("beside", ~ahead & ~behind), ("behind", behind)):
        acc.put(f"lidar.beyond_40m_{name}", np.count_nonzero(m) / len(az))
    if far.any():
        acc.put("lidar.far_height_m", np.median(height[far]))
    lit = refl[far]
    lit = lit[lit > 0]
    if len(lit):
        acc.put("lidar.far_reflectance_nonzero", np.median(lit))


def _rings(acc: Acc, pts: np.ndarray, el: np.ndarray, az: np.ndarray) -> None:
    """Returns and median elevation (degrees) per recovered ring, 0 = top; `el` and `az` are the
    returns' elevation and azimuth (radians) as kitti.rings.recover_rings reads them."""
    rings = recover_rings(pts, RINGS, el=el, az=az)
    acc.row("lidar.ring_returns", np.bincount(rings.ring, minlength=RINGS)[:RINGS])
    acc.row("lidar.ring_elevation_deg", np.degrees(rings.elevation))
    acc.put("lidar.ring_by_azimuth", rings.method == "azimuth-wrap")


def _car_points(acc: Acc, rect: np.ndarray, refl: np.ndarray, cars: list[Object3D]) -> None:
    """Returns inside each Car's 3D box and the share of them that read 0 (NaN for none),
    against its ground (x-z) distance, and its occlusion level (the mix of hidden cars differs
    between label sets: the fully visible ones compare the sensors)."""
    x, z = np.ascontiguousarray(rect[:, 0]), np.ascontiguousarray(rect[:, 2])
    counts, zeros = [], []
    for o in cars:
        inside = refl[returns_in_box(rect, x, z, o.box7)]
        counts.append(len(inside))
        zeros.append(np.count_nonzero(inside == 0) / len(inside) if len(inside) else np.nan)
    acc.put("lidar.car_points", counts)
    acc.put("lidar.car_zero_share", zeros)
    acc.put("lidar.car_distance_m", [np.hypot(o.location[0], o.location[2]) for o in cars])
    acc.put("lidar.car_occluded", [o.occluded for o in cars])


def _car_bottoms(acc: Acc, scan: np.ndarray, calib: Calibration, cars: list[Object3D]) -> None:
    """How high each Car label's bottom-face centre stands above the scan's road under it: the
    road the lifter stands boxes on where a frame has no planes/ (`lifter.road.scan_road`, the
    plane fitted to the road returns near the car). A generated box stands on the road surface;
    KITTI's were drawn in the point clouds, and an image-only lifter turns every centimetre
    between the two into d / 1.65 cm of depth at distance d."""
    if not cars:
        return
    road = scan_road(frame_points(scan, calib, None))
    acc.put("lidar.car_bottom_above_road_m",
            [float(height_above(np.asarray(o.location, dtype=np.float64)[None],
                                road.plane_at(o.location[0], o.location[2]))[0]) for o in cars])


def returns_in_box(rect: np.ndarray, x: np.ndarray, z: np.ndarray, box7: np.ndarray) -> np.ndarray:
    """Indices of the points (rect, with its x and z columns as contiguous arrays) inside a 3D box:
    a cheap square around the box first, then the exact test."""
    near = _in_square(x, z, box7[0], box7[2], np.hypot(box7[4], box7[5]) / 2)
    return near[points_in_boxes(rect[near], box7)[0]]


@numba.njit(cache=True, nogil=True)
def _in_square(x: np.ndarray, z: np.ndarray, cx: float, cz: float, reach: float) -> np.ndarray:
    """Indices of the points with |x - cx| <= reach and |z - cz| <= reach (the same float64
    comparisons as numpy's), in one pass instead of six arrays the size of the scan per Car."""
    out = np.empty(len(x), np.int64)
    k = 0
    for i in range(len(x)):
        if abs(x[i] - cx) <= reach and abs(z[i] - cz) <= reach:
            out[k] = i
            k += 1
    return out[:k]
