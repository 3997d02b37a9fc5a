"""Road geometry: a straight or circular road through the ego lane centre at the world origin.

Positions on the road are (s, d): s the arc length along the ego-lane centre line (heading +x
at s = 0), d the lateral offset to the left of it. Offset curves of a circle are concentric
circles, so every lane, curb and sidewalk edge is exact. Right-hand traffic: the ego direction's
lanes lie right of the divider, the oncoming lanes left of it; when the spec parks cars, a
parking strip lines each curb that `parking_sides` names. An intersection is a straight road
crossed at s = cross_s by a perpendicular street (world x = cross_s) with lanes of the same width.

The road need not be flat: a `VerticalProfile` gives its height z(s) along the centre line, the
same across it, so the cross street is level along its length. The world's z axis stays the
vertical and the ego's stretch of road is level (the sensors ride on the ego vehicle, so only the
change of grade from the ego's own shows in its camera and LiDAR); the road then bends up or down
ahead and behind it on parabolic vertical curves, as roads are designed.

Across, a carriageway is crowned: it falls from its crown (the divider) to each curb at the cross
slope `crown`, so that rain runs off. The ego vehicle rolls with its own lane, so in its frame
its side of the road is level and the oncoming side falls away at twice the cross slope, to the
far curb; beyond each curb the sidewalk and the land keep the height of that curb.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

PARKING_WIDTH = 2.3
_SCALARS = (int, float, np.number)  # one point's coordinates, as RoadLayout.xy takes them


@dataclass(frozen=True)
class VerticalProfile:
    """The road's height along its centre line, relative to the level road under the ego.

    On each side of the ego (ahead: s > 0, behind: s < 0) the road stays level for `start` metres,
    then its grade changes at a constant rate on a parabolic vertical curve until it reaches that
    side's grade, and keeps it. A curve's length follows design practice: L = K x |grade change in
    percent|, K the metres of road per 1 % change (AASHTO's Green Book sets K by design speed; its
    minimum at 50 km/h is 7 m on a crest, 13 m in a sag).
    """

    grade_ahead: float  # rise per metre reached ahead (negative: the road falls away)
    grade_behind: float  # rise per metre reached behind, going backwards from the ego
    k: float  # metres per percent of grade change
    start: float  # metres of level road each side of the ego before the curve begins

    def _side(self, u: np.ndarray, grade: float) -> tuple[np.ndarray, np.ndarray]:
        """Height and slope du at distances u >= 0 beyond the curve's start, one side."""
        length = max(self.k * abs(grade) * 100.0, 1e-9)
        u = np.maximum(u, 0.0)
        on = u < length
        z = np.where(on, grade * u * u / (2.0 * length), grade * (u - length / 2.0))
        g = np.where(on, grade * u / length, grade)
        return z, g

    def height_and_grade(self, s) -> tuple[np.ndarray, np.ndarray]:
        """z(s) and dz/ds, broadcasting."""
        s = np.asarray(s, dtype=float)
        za, ga = self._side(s - self.start, self.grade_ahead)
        zb, gb = self._side(-s - self.start, self.grade_behind)
        ahead = s >= 0
        return np.where(ahead, za, zb), np.where(ahead, ga, -gb)


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
    profile: VerticalProfile | None = None  # None: the whole world is flat at z = 0
    crown: float = 0.0  # cross slope each side of the crown (fall per metre); 0: flat across
    parking_sides: str = "both"  # the curbs a parking strip lines (with `parking`): right, left, none

    def __post_init__(self):
        if isinstance(self.profile, dict):  # rebuilt from its to_dict() form (meta/)
            object.__setattr__(self, "profile", VerticalProfile(**self.profile))

    def to_dict(self) -> dict:
        """Plain values; a road flat along (across) has no `profile` (`crown`) key, and one with
        both parking strips no `parking_sides`, as before each existed."""
        out = asdict(self)
        if self.profile is None:
            del out["profile"]
        if self.crown == 0.0:
            del out["crown"]
        if self.parking_sides == "both":
            del out["parking_sides"]
        return out

    @property
    def flat(self) -> bool:
        """Whether the whole road is the plane z = 0."""
        return self.profile is None and self.crown == 0.0

    def parks(self, side: int) -> bool:
        """Whether a parking strip lines the right (side -1) or the left (+1) curb."""
        return self.parking and self.parking_sides in ("both", "right" if side < 0 else "left")

    # Lateral positions (d) of the road's lines, left of the ego-lane centre.
    @property
    def right_lane_edge(self) -> float:
        return -(self.ego_lane + 0.5) * self.lane_width

    @property
    def right_curb(self) -> float:
        return self.right_lane_edge - (PARKING_WIDTH if self.parks(-1) else 0.0)

    @property
    def divider(self) -> float:
        return self.right_lane_edge + self.lanes * self.lane_width

    @property
    def left_lane_edge(self) -> float:
        return self.divider + self.lanes * self.lane_width

    @property
    def left_curb(self) -> float:
        return self.left_lane_edge + (PARKING_WIDTH if self.parks(1) else 0.0)

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
        """World (x, y) of road coordinates (s, d), broadcasting. Elementwise, so the arrays
        broadcast in the arithmetic itself (np.broadcast_arrays and np.stack cost more than it)."""
        if isinstance(s, _SCALARS) and isinstance(d, _SCALARS):
            return self._point_xy(float(s), float(d))
        s, d = np.asarray(s, dtype=float), np.asarray(d, dtype=float)
        k = self.curvature
        psi = k * s
        sin, cos = np.sin(psi), np.cos(psi)
        cx, cy = (s, 0.0) if k == 0.0 else (sin / k, (1.0 - cos) / k)
        out = np.empty(np.broadcast_shapes(s.shape, d.shape) + (2,))
        out[..., 0] = cx - d * sin
        out[..., 1] = cy + d * cos
        return out

    def _point_xy(self, s: float, d: float) -> np.ndarray:
        """xy() of one point: the same operations on scalars, without the broadcasting set-up that
        costs several times their arithmetic (a frame asks for thousands of single points)."""
        k = self.curvature
        psi = k * s
        sin, cos = np.sin(psi), np.cos(psi)
        cx, cy = (s, 0.0) if k == 0.0 else (sin / k, (1.0 - cos) / k)
        return np.array([cx - d * sin, cy + d * cos])

    def s_of(self, x, y) -> np.ndarray:
        """Arc length s of the centre-line point nearest to world (x, y), broadcasting: on a
        circle it is the point on the same radius, s = atan2(k x, 1 - k y) / k."""
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        k = self.curvature
        if k == 0.0:
            return x + 0.0 * y
        return np.arctan2(k * x, 1.0 - k * y) / k

    def d_of(self, x, y) -> np.ndarray:
        """Lateral offset d of world (x, y), broadcasting: on a circle, its radius less the
        point's distance from the centre (0, 1/k)."""
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        k = self.curvature
        if k == 0.0:
            return y + 0.0 * x
        return 1.0 / k - np.sign(k) * np.hypot(x, y - 1.0 / k)

    def _crown_height_and_slope(self, d) -> tuple[np.ndarray, np.ndarray]:
        """Height across the road and its slope dz/dd (ego's frame): level on the ego's side,
        falling at twice the cross slope from the divider to the far curb, level beyond."""
        u = np.asarray(d, dtype=float) - self.divider
        far = self.left_curb - self.divider
        on = (u > 0.0) & (u < far)
        return -2.0 * self.crown * np.clip(u, 0.0, far), np.where(on, -2.0 * self.crown, 0.0)

    def height(self, x, y) -> np.ndarray:
        """Road surface height z at world (x, y) (0 on a flat road), broadcasting."""
        if self.flat:
            return np.zeros(np.broadcast(np.asarray(x), np.asarray(y)).shape)
        along = None if self.profile is None else self.profile.height_and_grade(self.s_of(x, y))[0]
        if self.crown == 0.0:
            return along
        across = self._crown_height_and_slope(self.d_of(x, y))[0]
        return across if along is None else along + across

    def surface_normal(self, x: float, y: float) -> np.ndarray:
        """Unit upward normal of the road surface z = height(x, y) at one point."""
        return self.surface(x, y)[1]

    def surface(self, x: float, y: float) -> tuple[float, np.ndarray]:
        """height() and surface_normal() at one point, from one evaluation of the profile and
        the crown (for one point, their numpy calls cost more than their arithmetic)."""
        if self.flat:
            return 0.0, np.array([0.0, 0.0, 1.0])
        along, g = self.profile.height_and_grade(self.s_of(x, y)) if self.profile else (None, 0.0)
        across, c = self._crown_height_and_slope(self.d_of(x, y)) if self.crown else (None, 0.0)
        z = along if across is None else (across if along is None else along + across)
        return float(z), self._normal(x, y, float(g), float(c))

    def _normal(self, x: float, y: float, g: float, c: float) -> np.ndarray:
        """The unit upward normal where the grade along is g and the slope across c: g times the
        gradient of s plus c times the gradient of d."""
        k = self.curvature
        if k == 0.0:
            grad_s, grad_d = np.array([1.0, 0.0]), np.array([0.0, 1.0])
        else:
            a, b = k * x, 1.0 - k * y  # ds/dx, ds/dy of s = atan2(a, b) / k
            grad_s = np.array([b, a]) / (a * a + b * b)
            grad_d = -np.sign(k) * np.array([x, y - 1.0 / k]) / np.hypot(x, y - 1.0 / k)
        gx, gy = g * grad_s + c * grad_d
        n = np.array([-gx, -gy, 1.0])
        return n / np.linalg.norm(n)

    def fitted_plane(self, s0: float = 0.0, s1: float = 40.0, step: float = 1.0) -> np.ndarray:
        """The least-squares plane (a, b, c, d), a x + b y + c z + d = 0 with unit upward normal,
        through the carriageway between s0 and s1: the one road plane per frame that KITTI's
        planes/ files hold, fitted where the camera sees most of its labelled road users."""
        if self.flat:
            return np.array([0.0, 0.0, 1.0, 0.0])
        s = np.arange(s0, s1 + step / 2, step)
        d = np.linspace(self.right_curb, self.left_curb, 5)
        S, D = np.meshgrid(s, d)
        xy = self.xy(S.ravel(), D.ravel())
        z = self.height(xy[:, 0], xy[:, 1])
        A = np.column_stack([xy, np.ones(len(xy))])
        (gx, gy, z0), *_ = np.linalg.lstsq(A, z, rcond=None)
        n = np.array([-gx, -gy, 1.0, -z0])
        return n / np.linalg.norm(n[:3])

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
        return np.array([[c, -sn, 0.0, x], [sn, c, 0.0, y], [0.0, 0.0, 1.0, z], [0.0, 0.0, 0.0, 1.0]], dtype=float)
