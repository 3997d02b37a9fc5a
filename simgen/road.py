"""Road geometry: a straight or circular road through the ego lane centre at the world origin.

Positions on the road are (s, d): s the arc length along the ego-lane centre line (heading +x
at s = 0), d the lateral offset to the left of it. Offset curves of a circle are concentric
circles, so every lane, curb and sidewalk edge is exact. Right-hand traffic: the ego direction's
lanes lie right of the divider, the oncoming lanes left of it; a parking strip lines each curb
when the spec parks cars. An intersection is a straight road crossed at s = cross_s by a
perpendicular street (world x = cross_s) with lanes of the same width.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

PARKING_WIDTH = 2.3


@dataclass(frozen=True)
class RoadLayout:
    curvature: float  # 1/m, left positive
    lanes: int  # per direction
    lane_width: float
    ego_lane: int  # 0 = the lane next to the right curb (or parking strip)
    sidewalk_width: float
    curb_height: float
    parking: bool
    s_min: float
    s_max: float
    cross_s: float | None = None  # s of a perpendicular cross street's centre line (straight roads)
    cross_lanes: int = 0  # per direction on the cross street

    def to_dict(self) -> dict:
        return asdict(self)

    # Lateral positions (d) of the road's lines, left of the ego-lane centre.
    @property
    def right_lane_edge(self) -> float:
        return -(self.ego_lane + 0.5) * self.lane_width

    @property
    def right_curb(self) -> float:
        return self.right_lane_edge - (PARKING_WIDTH if self.parking else 0.0)

    @property
    def divider(self) -> float:
        return self.right_lane_edge + self.lanes * self.lane_width

    @property
    def left_lane_edge(self) -> float:
        return self.divider + self.lanes * self.lane_width

    @property
    def left_curb(self) -> float:
        return self.left_lane_edge + (PARKING_WIDTH if self.parking else 0.0)

    @property
    def cross_half_width(self) -> float:
        return self.cross_lanes * self.lane_width

    def in_cross_street(self, s: float, margin: float = 0.0) -> bool:
        """Whether arc length s lies on the cross street (widened by margin each side)."""
        return self.cross_s is not None and abs(s - self.cross_s) <= self.cross_half_width + margin

    def lane_centre(self, lane: int, oncoming: bool = False) -> float:
        """d of a lane centre; lane 0 is the one next to its own curb (or parking strip)."""
        if oncoming:
            return self.left_lane_edge - (lane + 0.5) * self.lane_width
        return self.right_lane_edge + (lane + 0.5) * self.lane_width

    def heading(self, s) -> np.ndarray:
        return self.curvature * np.asarray(s, dtype=float)

    def xy(self, s, d) -> np.ndarray:
        """World (x, y) of road coordinates (s, d), broadcasting."""
        s, d = np.broadcast_arrays(np.asarray(s, dtype=float), np.asarray(d, dtype=float))
        k = self.curvature
        psi = k * s
        if k == 0.0:
            cx, cy = s, np.zeros_like(s)
        else:
            cx, cy = np.sin(psi) / k, (1.0 - np.cos(psi)) / k
        return np.stack([cx - d * np.sin(psi), cy + d * np.cos(psi)], axis=-1)

    def samples(self, s0: float, s1: float, step: float = 4.0) -> np.ndarray:
        """Arc-length samples for meshing: two suffice on a straight road."""
        if self.curvature == 0.0:
            return np.array([s0, s1])
        n = max(2, int(np.ceil((s1 - s0) / step)) + 1)
        return np.linspace(s0, s1, n)

    def pose(self, s: float, d: float, z: float, yaw_offset: float = 0.0) -> np.ndarray:
        """(4, 4) world pose at (s, d, z) facing along the road plus yaw_offset."""
        x, y = self.xy(s, d)
        yaw = float(self.heading(s)) + yaw_offset
        c, sn = np.cos(yaw), np.sin(yaw)
        T = np.eye(4)
        T[:3, :3] = [[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]]
        T[:3, 3] = [x, y, z]
        return T
