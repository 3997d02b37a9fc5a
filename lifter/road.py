"""The road under an object, from the scan: a plane fitted to the road returns around a bird's-eye
point.

One plane per frame (`ground.fit_ground_plane`) is what the generator's worlds have (their road
is the plane z = 0), but real roads slope and curve: in one KITTI dev frame the bottoms of the
labelled cars lie 1.6 to 3.0 m below the camera, and the frame's RANSAC plane, dominated by the
dense near returns, is 0.3 m off at 40 m. An image-only placement turns a road-height error dh
into a depth error of about d dh / 1.65 m (2.4 m at 40 m for 0.1 m), and `fit` puts the box's
bottom and its "above the road" cut on it. So the road near each object is fitted to the returns
near it.

Which returns are road: walking outwards from the sensor in each azimuth sector, a range bin's
lowest return continues the road when the bin is flat (most of its returns lie at its lowest) and
that lowest return lies within UP_TOL above or GROUND_TOL below the road height so far (+ GRADE_UP
or GRADE_DOWN per metre since the last road bin, the rise capped); a car's sill, a curb or a wall's
foot stands higher and is passed over. Returns within ROAD_BAND of their bin's lowest are road. The
road near (x, z) is the plane (offset and tilt against the frame's plane, the tilt held towards
zero where the returns say little about it) through the road returns in a square window grown
until it holds MIN_ROAD of them, else in a window stretched along the range (FAR_WINDOW: a sparse
scan's rings meet the far road tens of metres apart), else the frame's plane (a scan without far
road returns keeps the near road's plane).
"""

from __future__ import annotations

import numba
import numpy as np

from .ground import fit_ground_plane, height_above, normalise_plane
from .points import FramePoints

BAND = 2.0          # m around the frame's plane where road is looked for
MAX_DEVIATION = 1.0  # m, most a road user's local road may lie off the frame's plane (the dev
                     # frames' farthest car: 0.56 m below it at 58 m)
SECTOR = np.tan(np.deg2rad(1.0))  # sector of the walk, in tan(azimuth) (1 degree, 26 cm at 15 m, on the axis)
RANGE_BIN = 1.0     # m, range bin of the walk
MAX_RANGE = 100.0   # m, farthest range bin
GROUND_TOL = 0.1    # m, a bin's lowest return this far below the road so far continues it
UP_TOL = 0.05       # m, ... or this far above it (KITTI's range noise is ~2 cm; a curb is 0.1-0.15 m)
GRADE_UP = 0.01     # m per m of range since the last road bin: how far the road may rise against
                    # the frame's plane (1 %: a KITTI dev road 0.4 m above it at 43 m); kept small,
                    # as everything a false road return can be (a sill, a wall's foot) stands higher
GRADE_DOWN = 0.04   # ... and fall (nothing but noise lies below the road)
MAX_JUMP_UP = 0.05  # m, most the grade may add to UP_TOL across a gap (an occluder's shadow): the
                    # road beyond may have risen, but not by a curb (0.1-0.15 m) or a sill (0.2 m)
ROAD_BAND = 0.08    # m, returns this close to their sector's road height are road
FLAT_SHARE = 0.5    # share of a bin's returns within ROAD_BAND of its lowest, for a road bin
CELL = 1.0          # m, bird's-eye bucket of the road returns
PER_CELL = 6        # road returns kept per bucket (a near square metre holds hundreds; at 40 m
                    # the HDL-64E leaves a few): bounds a window's cost
GRID_X = (-60.0, 60.0)   # m, rect x covered by the buckets (returns outside share the edge ones)
GRID_Z = (0.0, 120.0)    # m, rect z
WINDOWS = (2.0, 4.0, 8.0)  # m, window half-sizes tried in turn
# m, half-sizes across (x) and along (z) of the window tried where no square one holds road: a
# sparse scan's rings meet the road 10-30 m apart beyond 20 m (16 of the HDL-64E's rings: 1.6-1.8
# deg apart, 1.73 m up), so a far object's road lies between two rings. Along the range, twice the
# largest square reaches them; across, a lane each way keeps a crowned road's fall towards its
# curb (3-5 % in the sensor's frame on the oncoming half) to a few centimetres, where the frame's
# plane, fitted mostly to the ego's half, misses it by 0.1-0.3 m.
FAR_WINDOW = (4.0, 16.0)
MIN_ROAD = 12       # road returns a window must hold (a plane from fewer is noise)
INLIER = 0.06       # m, refit on the returns this close to the first plane
LAYER = 6           # returns within INLIER of each other that make the lowest layer (the road)
SIGMA_TILT = 0.03   # the local tilt's prior spread against the frame's plane
SIGMA_H = 0.03      # m, a road return's height noise, weighing the tilt prior

_NX = int((GRID_X[1] - GRID_X[0]) / CELL)
_NZ = int((GRID_Z[1] - GRID_Z[0]) / CELL)
_NR = int(MAX_RANGE / RANGE_BIN)
_MAX_TAN = 1.5  # sectors cover azimuths within atan(1.5) = 56 degrees of the optical axis (the
                # returns come cut to lifter.points' 50-degree wedge)


def scan_road(pts: FramePoints) -> LocalRoad:
    """The road of a scan's returns in the camera's wedge (`points.frame_points`): the frame's
    RANSAC plane and the road returns near each object, what the lifter places boxes on where a
    frame has no planes/."""
    return LocalRoad(pts.rect, fit_ground_plane(pts.rect), pts.sensor[[0, 2]])


class LocalRoad:
    """The frame's plane, the road returns of the scan and each azimuth sector's road height."""

    def __init__(self, rect: np.ndarray, plane: np.ndarray, sensor_xz: np.ndarray,
                 height: np.ndarray | None = None):
        """`rect`: the returns (rect frame); `height`: their height above `plane` if known."""
        self.plane = normalise_plane(plane)
        h = height_above(rect, self.plane) if height is None else height
        rect = np.ascontiguousarray(rect, dtype=np.float64)
        h = np.ascontiguousarray(h, dtype=np.float64)
        road = _sector_walk(rect, h, np.asarray(sensor_xz, dtype=np.float64))
        self.height, self.is_road = h, road  # per return of `rect`
        self.xz, self.h = _gather(rect, h, road)
        self.order, self.start = _bucket(self.xz, GRID_X[0], GRID_Z[0], CELL, _NX, _NZ)

    def plane_at(self, x: float, z: float) -> np.ndarray:
        """The road plane (unit normal up, rect frame) near bird's-eye (x, z): fitted in the
        largest window from the lowest dense layer of road returns, then refined in the smallest
        window that still holds MIN_ROAD returns of it; the frame's plane where none holds."""
        a, bx, bz, ok = _road_at(self.xz, self.h, self.order, self.start, x, z)
        return _shifted(self.plane, a, bx, bz, x, z) if ok else self.plane.copy()

    def plane_on_ray(self, c: np.ndarray, d: np.ndarray, iters: int = 2) -> np.ndarray:
        """The road plane where the ray c + t d meets the road (`road.plane_on_ray`)."""
        a, bx, bz, x0, z0, ok = _on_ray(self.xz, self.h, self.order, self.start, self.plane,
                                        np.asarray(c, dtype=np.float64),
                                        np.asarray(d, dtype=np.float64), iters)
        return _shifted(self.plane, a, bx, bz, x0, z0) if ok else self.plane.copy()

    def may_stand(self, rect: np.ndarray, low: float, high: float) -> np.ndarray:
        """Mask of the returns (the `rect` this road was built from) that may lie between `low`
        and `high` above their local road: not road, and within MAX_DEVIATION of that range
        above the frame's plane (the local plane decides, per object)."""
        if len(rect) != len(self.height):
            raise ValueError("may_stand takes the returns the road was built from")
        return (~self.is_road & (self.height > low - MAX_DEVIATION)
                & (self.height < high + MAX_DEVIATION))


def _shifted(plane: np.ndarray, a: float, bx: float, bz: float, x0: float, z0: float) -> np.ndarray:
    """The plane whose height above `plane` is a + bx (x - x0) + bz (z - z0)."""
    n = plane[:3] - np.array([bx, 0.0, bz])
    d = plane[3] - a + bx * x0 + bz * z0
    return normalise_plane(np.append(n, d))


@numba.njit(cache=True, nogil=True)
def _polar(x: float, z: float, sensor_xz: np.ndarray) -> tuple[int, int]:
    """Sector and range bin of (x, z). A sector is a bin of dx / dz (the tangent of the azimuth
    from the optical axis, SECTOR wide at the axis, narrower to the sides: no arctangent per
    return); what lies behind or beside the sensor goes to the edge sectors."""
    dx, dz = x - sensor_xz[0], z - sensor_xz[1]
    ns = int(2 * _MAX_TAN / SECTOR)
    t = dx / dz if dz > 1e-6 else (_MAX_TAN if dx > 0 else -_MAX_TAN)
    s = min(max(int((t + _MAX_TAN) / SECTOR), 0), ns - 1)
    r = min(int(np.sqrt(dx * dx + dz * dz) / RANGE_BIN), _NR - 1)
    return s, r


@numba.njit(cache=True, nogil=True)
def _sector_walk(rect: np.ndarray, h: np.ndarray, sensor_xz: np.ndarray) -> np.ndarray:
    """The road mask of the returns (rect frame, height h above the frame's plane)."""
    ns = int(2 * _MAX_TAN / SECTOR)
    low = np.full((ns, _NR), np.inf)
    cell = np.full((len(rect), 2), -1, dtype=np.int64)
    for k in range(len(rect)):
        if abs(h[k]) < BAND:
            s, r = _polar(rect[k, 0], rect[k, 2], sensor_xz)
            cell[k, 0], cell[k, 1] = s, r
            low[s, r] = min(low[s, r], h[k])
    # a road bin is flat: most of its returns lie at its lowest (a car's side or a wall spreads
    # its returns over its height)
    n_all = np.zeros((ns, _NR))
    n_low = np.zeros((ns, _NR))
    for k in range(len(rect)):
        s, r = cell[k, 0], cell[k, 1]
        if s >= 0:
            n_all[s, r] += 1.0
            n_low[s, r] += h[k] - low[s, r] <= ROAD_BAND
    is_road = np.zeros((ns, _NR), dtype=np.bool_)
    for s in range(ns):
        g, last = 0.0, 0  # the frame's plane is the near road's
        for r in range(_NR):
            m = low[s, r]
            gap = (r - last) * RANGE_BIN
            up = UP_TOL + min(GRADE_UP * gap, MAX_JUMP_UP)
            flat = n_low[s, r] >= FLAT_SHARE * n_all[s, r]
            if m < np.inf and flat and g - GROUND_TOL - GRADE_DOWN * gap <= m <= g + up:
                g, last = m, r
                is_road[s, r] = True
    road = np.zeros(len(rect), dtype=np.bool_)
    for k in range(len(rect)):
        s, r = cell[k, 0], cell[k, 1]
        road[k] = s >= 0 and is_road[s, r] and h[k] - low[s, r] <= ROAD_BAND
    return road


@numba.njit(cache=True, nogil=True)
def _gather(rect: np.ndarray, h: np.ndarray, road: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The road returns' bird's-eye (x, z) and heights."""
    n = road.sum()
    xz, hr = np.empty((n, 2)), np.empty(n)
    k = 0
    for i in range(len(rect)):
        if road[i]:
            xz[k, 0], xz[k, 1], hr[k] = rect[i, 0], rect[i, 2], h[i]
            k += 1
    return xz, hr


@numba.njit(cache=True, nogil=True)
def _cell(x: float, z: float, x0: float, z0: float, cell: float, nx: int, nz: int) -> tuple[int, int]:
    i = min(max(int(np.floor((x - x0) / cell)), 0), nx - 1)
    j = min(max(int(np.floor((z - z0) / cell)), 0), nz - 1)
    return i, j


@numba.njit(cache=True, nogil=True)
def _bucket(xz: np.ndarray, x0: float, z0: float, cell: float, nx: int,
            nz: int) -> tuple[np.ndarray, np.ndarray]:
    """Counting sort of the returns by bird's-eye cell, at most PER_CELL of them per cell (evenly
    strided: a near cell holds hundreds of road returns, and a plane needs few):
    `order[start[c]:start[c + 1]]` are the returns kept in cell c = i nz + j."""
    key = np.empty(len(xz), dtype=np.int64)
    count = np.zeros(nx * nz, dtype=np.int64)
    for k in range(len(xz)):
        i, j = _cell(xz[k, 0], xz[k, 1], x0, z0, cell, nx, nz)
        key[k] = i * nz + j
        count[key[k]] += 1
    start = np.zeros(nx * nz + 1, dtype=np.int64)
    for c in range(nx * nz):
        start[c + 1] = start[c] + min(count[c], PER_CELL)
    fill = start[:-1].copy()
    seen = np.zeros(nx * nz, dtype=np.int64)
    order = np.empty(start[-1], dtype=np.int64)
    for k in range(len(xz)):
        c = key[k]
        # the t-th of n returns is kept when it is the next of PER_CELL evenly spaced picks
        if fill[c] < start[c + 1] and seen[c] * min(count[c], PER_CELL) // count[c] == fill[c] - start[c]:
            order[fill[c]] = k
            fill[c] += 1
        seen[c] += 1
    return order, start


@numba.njit(cache=True, nogil=True)
def _window(xz, order, start, x, z, half_x, half_z) -> np.ndarray:
    """Indices of the road returns within the window of half-sizes half_x, half_z around (x, z)."""
    i0, j0 = _cell(x - half_x, z - half_z, GRID_X[0], GRID_Z[0], CELL, _NX, _NZ)
    i1, j1 = _cell(x + half_x, z + half_z, GRID_X[0], GRID_Z[0], CELL, _NX, _NZ)
    n = 0
    for i in range(i0, i1 + 1):
        n += start[i * _NZ + j1 + 1] - start[i * _NZ + j0]
    out = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(i0, i1 + 1):
        for t in range(start[i * _NZ + j0], start[i * _NZ + j1 + 1]):
            k = order[t]
            if abs(xz[k, 0] - x) <= half_x and abs(xz[k, 1] - z) <= half_z:
                out[m] = k
                m += 1
    return out[:m]


@numba.njit(cache=True, nogil=True)
def _lowest_layer(h: np.ndarray) -> float:
    """The height of the lowest LAYER returns lying within INLIER of each other: the road under
    a few stray higher returns (a sill, a curb, a car's lowest edge) that passed the walk."""
    hs = np.sort(h)
    k = min(LAYER, len(hs)) - 1
    for i in range(len(hs) - k):
        if hs[i + k] - hs[i] <= INLIER:
            return hs[i]
    return hs[0]


@numba.njit(cache=True, nogil=True)
def _local_fit(xz, h, order, start, x, z, half_x, half_z, a, bx,
               bz) -> tuple[float, float, float, int]:
    """Offset and tilt (a, bx, bz) of the road's height above the frame plane around (x, z), by
    least squares on the road returns of the window (half-sizes half_x, half_z) within INLIER of
    the plane given (a NaN offset: of the window's lowest layer), three times over, and how many
    returns gave them. The tilt is fitted only where the returns surround (x, z); else the offset
    is their mean height."""
    idx = _window(xz, order, start, x, z, half_x, half_z)
    if len(idx) < MIN_ROAD:
        return 0.0, 0.0, 0.0, 0
    if np.isnan(a):
        a, bx, bz = _lowest_layer(h[idx]), 0.0, 0.0
    lam = (SIGMA_H / SIGMA_TILT) ** 2  # ridge on the tilt
    n = 0
    for _ in range(3):
        # normal equations of h = a + bx dx + bz dz, accumulated by hand
        s1 = sx = sz = sxx = sxz = szz = sh = sxh = szh = 0.0
        x_lo = z_lo = np.inf
        x_hi = z_hi = -np.inf
        n = 0
        for k in idx:
            dx, dz = xz[k, 0] - x, xz[k, 1] - z
            if abs(h[k] - (a + bx * dx + bz * dz)) > INLIER:
                continue
            x_lo, x_hi = min(x_lo, dx), max(x_hi, dx)
            z_lo, z_hi = min(z_lo, dz), max(z_hi, dz)
            s1 += 1.0
            sx += dx
            sz += dz
            sxx += dx * dx
            sxz += dx * dz
            szz += dz * dz
            sh += h[k]
            sxh += dx * h[k]
            szh += dz * h[k]
            n += 1
        if n < MIN_ROAD:
            return 0.0, 0.0, 0.0, n
        if x_lo < 0 < x_hi and z_lo < 0 < z_hi:
            M = np.array([[s1, sx, sz], [sx, sxx + lam, sxz], [sz, sxz, szz + lam]])
            a, bx, bz = np.linalg.solve(M, np.array([sh, sxh, szh]))
        else:  # the road returns lie to one side: a tilt would be extrapolated, keep the frame's
            a, bx, bz = sh / s1, 0.0, 0.0
    return a, bx, bz, n


@numba.njit(cache=True, nogil=True)
def _road_at(xz, h, order, start, x, z) -> tuple[float, float, float, bool]:
    """`LocalRoad.plane_at`'s offset and tilt against the frame's plane, and whether a window
    held enough road to give them."""
    big = WINDOWS[-1]
    a, bx, bz, n = _local_fit(xz, h, order, start, x, z, big, big, np.nan, 0.0, 0.0)
    if n < MIN_ROAD:  # no square holds road: the one stretched along the range
        a, bx, bz, n = _local_fit(xz, h, order, start, x, z, FAR_WINDOW[0], FAR_WINDOW[1], np.nan,
                                  0.0, 0.0)
        return a, bx, bz, n >= MIN_ROAD
    for half in WINDOWS[:-1]:
        a2, bx2, bz2, n2 = _local_fit(xz, h, order, start, x, z, half, half, a, bx, bz)
        if n2 >= MIN_ROAD:
            return a2, bx2, bz2, True
    return a, bx, bz, True


@numba.njit(cache=True, nogil=True)
def _on_ray(xz, h, order, start, plane, c, d, iters) -> tuple[float, float, float, float, float, bool]:
    """`plane_on_ray` for a `LocalRoad`: the local offset and tilt, the point (x0, z0) they are
    taken about, and whether any window held enough road."""
    rate = plane[0] * d[0] + plane[1] * d[1] + plane[2] * d[2]
    a = bx = bz = x0 = z0 = 0.0
    ok = False
    if rate >= -1e-9:  # parallel to or rising from the road
        return a, bx, bz, x0, z0, ok
    t = -(plane[0] * c[0] + plane[1] * c[1] + plane[2] * c[2] + plane[3]) / rate
    for _ in range(iters):
        p = c + t * d
        a2, bx2, bz2, ok2 = _road_at(xz, h, order, start, p[0], p[2])
        if not ok2:
            break
        a, bx, bz, x0, z0, ok = a2, bx2, bz2, p[0], p[2], True
        # the point's height above the local plane (which passes a above the frame's at p)
        above = plane[0] * p[0] + plane[1] * p[1] + plane[2] * p[2] + plane[3] - a
        t_new = t - above / rate
        if t_new <= 0:
            break
        t = t_new
    return a, bx, bz, x0, z0, ok


class FixedRoad:
    """One plane everywhere: planes/ (the generator's exact road, a gantry's known mounting) or,
    without a scan, the documented prior."""

    def __init__(self, plane: np.ndarray):
        self.plane = normalise_plane(plane)

    def plane_at(self, x: float, z: float) -> np.ndarray:
        return self.plane.copy()

    def plane_on_ray(self, c: np.ndarray, d: np.ndarray, iters: int = 2) -> np.ndarray:
        return self.plane.copy()

    def may_stand(self, rect: np.ndarray, low: float, high: float) -> np.ndarray:
        """Mask of the returns between `low` and `high` above the plane."""
        h = height_above(rect, self.plane)
        return (h > low) & (h < high)


def camera_rays(P: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rays through pixels uv (N, 2): the camera centre c (P [c; 1] = 0) and directions d
    (N, 3) with P [c + t d; 1] ~ (u, v, 1), rect frame."""
    M = np.linalg.inv(P[:, :3])
    uv1 = np.column_stack([np.asarray(uv, dtype=float).reshape(-1, 2), np.ones(len(uv))])
    return -M @ P[:, 3], uv1 @ M.T


def camera_ray(P: np.ndarray, u: float, v: float) -> tuple[np.ndarray, np.ndarray]:
    """`camera_rays` for one pixel."""
    c, d = camera_rays(P, np.array([[u, v]]))
    return c, d[0]


def plane_under(road: LocalRoad | FixedRoad, u: float, v: float, P: np.ndarray,
                iters: int = 2) -> np.ndarray:
    """The road plane where the ray through pixel (u, v) meets the road (`plane_on_ray`)."""
    return plane_on_ray(road, *camera_ray(P, u, v), iters=iters)


def plane_on_ray(road: LocalRoad | FixedRoad, c: np.ndarray, d: np.ndarray,
                 iters: int = 2) -> np.ndarray:
    """The road plane where the ray c + t d meets the road. The ray meets the frame's plane
    first; then the point moves along the ray until it lies on the local plane found there, each
    step measured with the frame's plane's slope along the ray (a local plane's tilt,
    extrapolated tens of metres, may even pass above the camera). A ray above the horizon keeps
    the frame's plane."""
    return road.plane_on_ray(c, d, iters)


@numba.njit(cache=True, nogil=True)
def ray_depth(c: np.ndarray, d: np.ndarray, plane: np.ndarray, far: float = 200.0) -> float:
    """Bird's-eye distance from the camera to where the ray c + t d meets `plane` (`far` when it
    does not, or beyond that). A kernel: `fit` asks it twice per box."""
    rate = plane[0] * d[0] + plane[1] * d[1] + plane[2] * d[2]
    if rate >= -1e-9:
        return far
    t = -(plane[0] * c[0] + plane[1] * c[1] + plane[2] * c[2] + plane[3]) / rate
    return min(np.hypot(c[0] + t * d[0], c[2] + t * d[2]), far)
