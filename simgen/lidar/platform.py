"""What KITTI's recording car hides from its own roof-mounted HDL-64E.

The lowest lasers meet the car's roof, bonnet and boot (and the rack's posts) before the ground,
and KITTI's scans hold no return there in any frame: ahead (the bonnet, lasers at -21 degrees and
lower, out to about 20 degrees either side), behind (the roof and boot, from -17 degrees down,
150-210 degrees), to the right (the rack, 280-305 degrees, from -13 degrees down) and a few narrow
sectors; the top lasers lose the sweep's seam directly behind (178-184 degrees). On the real dev
frames the lowest laser keeps about 1,100 returns a sweep against about 1,950 above the body's
edge. The car and the mount are the same in every KITTI frame, so these are the platform's, not
the scenes'. Measured on the real KITTI frames (a sector: no return of that laser in at least 90 %
of them, 1-degree bins):

    .venv/bin/python benchmarks/lidar_platform_mask.py --root ../shared/kitti_real_dev

The scene generator's onboard rig sits on the same car at the same height (1.73 m), so every
sensor on it loses these directions: a ray is hidden where the KITTI laser nearest its elevation
is hidden at its azimuth (sensors with other beam layouts, rescans and native beam counts alike).
Roadside and orbiting rigs stand on no car and lose nothing.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from kitti.rings import HDL64E_ELEVATIONS

from .rays import ray_table
from .spec import LidarSpec

# KITTI laser (0 = top, HDL64E_ELEVATIONS' order) -> hidden azimuth sectors [from, to), degrees of
# atan2(y, x) in the LiDAR frame (x forward, y left), 0-360.
HIDDEN: dict[int, tuple[tuple[float, float], ...]] = {
    1: ((179.0, 180.0),),
    2: ((178.0, 181.0), (182.0, 184.0)),
    3: ((178.0, 179.0), (180.0, 183.0)),
    4: ((180.0, 184.0),),
    5: ((180.0, 182.0), (183.0, 184.0)),
    6: ((180.0, 183.0),),
    7: ((179.0, 182.0), (183.0, 184.0)),
    42: ((158.0, 165.0), (199.0, 206.0)),
    43: ((155.0, 163.0), (196.0, 204.0)),
    44: ((157.0, 166.0), (198.0, 206.0)),
    45: ((155.0, 163.0), (196.0, 203.0)),
    46: ((158.0, 164.0), (199.0, 205.0), (298.0, 299.0)),
    47: ((155.0, 161.0), (197.0, 202.0), (288.0, 294.0)),
    48: ((160.0, 165.0), (199.0, 204.0), (286.0, 301.0)),
    49: ((158.0, 163.0), (196.0, 201.0), (280.0, 297.0)),
    50: ((161.0, 165.0), (198.0, 202.0), (283.0, 303.0)),
    51: ((159.0, 163.0), (196.0, 199.0), (277.0, 298.0)),
    52: ((161.0, 164.0), (169.0, 191.0), (198.0, 202.0), (282.0, 302.0)),
    53: ((157.0, 166.0), (167.0, 200.0), (277.0, 298.0)),
    54: ((160.0, 204.0), (283.0, 305.0)),
    55: ((128.0, 129.0), (157.0, 202.0), (279.0, 299.0)),
    56: ((130.0, 135.0), (159.0, 205.0), (231.0, 236.0), (283.0, 303.0)),
    57: ((1.0, 3.0), (4.0, 10.0), (126.0, 133.0), (154.0, 204.0), (226.0, 233.0), (279.0, 297.0),
        (350.0, 353.0)),
    58: ((0.0, 3.0), (4.0, 15.0), (132.0, 133.0), (135.0, 136.0), (155.0, 207.0), (229.0, 235.0),
        (236.0, 237.0), (283.0, 288.0), (289.0, 303.0), (347.0, 352.0), (355.0, 360.0)),
    59: ((0.0, 10.0), (11.0, 13.0), (14.0, 15.0), (125.0, 133.0), (152.0, 205.0), (225.0, 233.0),
        (278.0, 293.0), (345.0, 346.0), (347.0, 360.0)),
    60: ((0.0, 14.0), (130.0, 132.0), (133.0, 135.0), (136.0, 138.0), (155.0, 210.0),
        (230.0, 238.0), (284.0, 297.0), (324.0, 327.0), (332.0, 335.0), (344.0, 346.0),
        (347.0, 350.0), (352.0, 360.0)),
    61: ((0.0, 14.0), (26.0, 29.0), (34.0, 37.0), (129.0, 134.0), (137.0, 140.0), (151.0, 208.0),
        (226.0, 232.0), (280.0, 281.0), (283.0, 284.0), (288.0, 289.0), (321.0, 325.0),
        (328.0, 332.0), (342.0, 360.0)),
    62: ((0.0, 16.0), (29.0, 32.0), (36.0, 40.0), (130.0, 131.0), (134.0, 137.0), (140.0, 145.0),
        (153.0, 211.0), (222.0, 225.0), (229.0, 232.0), (233.0, 235.0), (285.0, 291.0),
        (323.0, 326.0), (327.0, 328.0), (331.0, 334.0), (342.0, 360.0)),
    63: ((0.0, 19.0), (26.0, 29.0), (32.0, 37.0), (126.0, 142.0), (145.0, 211.0), (216.0, 222.0),
        (224.0, 234.0), (279.0, 283.0), (321.0, 324.0), (326.0, 331.0), (340.0, 360.0)),
}


@lru_cache(maxsize=16)
def hidden_rays(spec: LidarSpec) -> np.ndarray:
    """(N,) bool over `ray_table(spec)`'s rays: hidden by the car (cached per spec)."""
    rays = ray_table(spec)
    kitti = np.asarray(HDL64E_ELEVATIONS, dtype=float)
    own = np.asarray(spec.elevations_deg, dtype=float)
    nearest = np.abs(own[:, None] - kitti[None, :]).argmin(axis=1)  # per beam of the spec
    laser = nearest[rays.ring]
    az = np.degrees(rays.azimuth.astype(np.float64)) % 360.0
    hidden = np.zeros(len(az), dtype=bool)
    for k, sectors in HIDDEN.items():
        on = laser == k
        for a0, a1 in sectors:
            hidden |= on & (az >= a0) & (az < a1)
    return hidden
