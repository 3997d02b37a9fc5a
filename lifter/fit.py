"""The strongest LiDAR lifter here: the road under each object, the object's own returns separated
in the frustum, an oriented box fitted to them with the network's size and orientation as priors.

Per 2D box, nearest first (depth from the road point under the box's bottom edge; boxes scoring
under CLAIM_MIN_SCORE after the others):
0. the road: the plane the scan shows under the box's bottom edge (`lifter.road`: real roads
   slope and curve, one plane per frame is 0.3 m off at 40 m on KITTI);
1. frustum returns above that road (ROAD_CUT .. MAX_HEIGHT), minus those already claimed by a
   nearer box's fit (an occluder with its own 2D box); a side the image border cuts is opened,
   since the scan sees past the border (`opened_at_border`);
2. bird's-eye Euclidean clusters (a vertical surface stays connected however few beams hit it),
   each grown by the neighbouring clusters that keep it car-sized (a far car's bumper and roof
   fall apart); the set that best covers the box's columns at the depth the road predicts wins,
   then takes the returns past a cut side that keep it car-sized (`clusters.grown_beyond`);
3. yaw by L-shape search (closeness criterion) over 0..90 degrees on the returns below the belt
   line (the body's outline; the glasshouse is set in); of the four yaws it allows, the one
   nearest the network's; too few or collinear-in-one-point returns keep the network's yaw. The
   other axis and the network's own yaw are tried too, weighed by the network's orientation
   prior, how much worse a rectangle fits the returns, the 2D box's sides and the length prior
   (for a box the border cuts, also the returns its box leaves out: SIGMA_EXTENT);
   (3b) where the winner's box still misses the 2D box's sides by more than their noise, the yaws
   within SIGMA_YAW_PRIOR of it are weighed the same way (a real car's rounded corners and curved
   faces can leave the closeness criterion's L-shape 10-20 degrees off, where both the 2D box
   and a rectangle's fit to the returns show it);
4. size: the network's, measured where both ends show, grown to hold the returns (capped); a
   car's width both sides of which show is taken across its mirrors, across its body below them
   or as the network's, whichever's box meets the 2D box's sides best (labels differ on mirrors);
   the height brought within ROOF_GAP of the roof returns when the roof is hit; a length the
   returns do not measure is chosen among LENGTH_GRID x the network's by how well the fitted
   box's outline meets the 2D box's left and right sides;
5. translation (x, z) by weighted least squares: the faces the returns confirm must touch the
   extreme returns, the box's outline must meet the 2D box's left and right sides (across the
   camera ray only: a 2D side fixes a bearing, not a depth), and the bottom sits on the road
   plane; two passes (the corner that touches each side may change). A car's face whose
   returns all lie above its bumpers is its bonnet's or glasshouse's (a sparse scan's one ring
   over a far car): the box's face lies nearer by the outline's set-in at that height
   (`placement.OUTLINE_*`). (5b) where the 2D box is the projection of the 3D box (KITTI's
   labels), its top edge then fixes the height exactly;
6. fewer than MIN_POINTS returns: the image-only solution constrained to the road plane;
7. score = 2D score x a quality from the number of returns, the faces that pin the box, the
   winning yaw's cost and the share of the box the image shows (`visible_share`); an image-only
   box (step 6) is trusted as `mono`'s is, less with distance (d^2 / (f H) metres of depth per
   pixel of its bottom edge).

Step 2 is `clusters.object_returns`, steps 4-5 are `placement`'s kernels. Wherever the 2D box's
left and right sides are weighed (steps 3-4), their errors are the box's own (`Box2D.side_sigma`,
`side_dof`): a label's Gaussian 2 px; a detection's its detector's besides, a Student-t whose
heavy tails let a side far off go (`lifter.pipeline.SHIPPED_SIDE_ERRORS`, `placement.side_cost`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numba
import numpy as np

from kitti.boxes import wrap_angle
from kitti.calib import Calibration

from .clusters import MERGE_SLACK, MIN_POINTS, grown_beyond, object_returns
from .mono import box_up_of, contact_of, solve_from_alpha, wrap_one
from .placement import (
    CAMERA_UP,
    FOCAL_PX,
    MAX_GROW_L,
    MAX_GROW_W,
    SIGMA_LENGTH,
    cut_sides,
    height_from_box,
    length_from_sides,
    percentile,
    side_cost,
    translation,
)
from .points import FramePoints
from .road import FixedRoad, LocalRoad, camera_rays, plane_on_ray, ray_depth
from .types import Box2D, Lifted, Prior

ROAD_CUT = 0.15        # m above the fitted plane: lower returns are road
MAX_HEIGHT = 4.0       # m above the plane: higher returns are no road user
MIN_LSHAPE = 8         # fewer returns: keep the network's yaw
BELT_LINE = 0.6        # share of the height below which a vehicle's sides are its outline (the belt
                       # line of a 1.45-1.5 m car lies at ~0.9 m; above it the glasshouse narrows)
MIRROR_FOOT = 0.57     # share of a car's height below which no door mirror reaches: they stand on
                       # the belt line, 0.57-0.65 h on makers' side views (`placement.OUTLINE_*`)
LSHAPE_D0 = 0.05       # m, closeness floor of the L-shape criterion
MAX_LSHAPE_POINTS = 300  # returns used for the yaw search (evenly strided)
CLAIM_MARGIN = 0.3     # m around a fitted box whose returns it claims
CLAIM_MIN_SCORE = 0.3  # 2D score a box needs to claim returns
ROOF_SEEN = 0.75       # highest return above this share of the prior height: the roof is hit
ROOF_GAP = 0.2         # m, the top lies at most this far above the highest roof return (64 beams:
                       # 90 % within 0.14 m on the testbed's cars; sparse scans a little more)
SIGMA_YAW_PRIOR = np.deg2rad(20.0)  # the network's orientation, against the 2D box's evidence
SAME_YAW = np.deg2rad(1.0)  # an L-shape this close to the network's yaw is taken as agreeing
COST_SCALE = 8.0       # the winning yaw's cost (squared normalised misfits: yaw prior, rectangle,
                       # 2D sides, length) that halves the quality: on held-out generated cars the
                       # share placed within IoU 0.7 falls from 0.97 (cost < 0.5) to 0.79 (> 8)
SIGMA_RECT = 0.005      # m, a yaw whose rectangle fits the returns this much worse (RMS) than the
                       # L-shape's costs one sigma: the HDL-64E's range noise (< 2 cm, Velodyne)
SIGMA_EXTENT = MERGE_SLACK  # m, returns left out of the box along an axis: the slack a merged set
                           # of them may have beyond the size prior (`clusters.MERGE_SLACK`)
SMALL_CLASSES = ("Pedestrian", "Cyclist", "Person_sitting")
REFINE_STEP = np.deg2rad(5.0)  # step 3b's yaws, one SIGMA_YAW_PRIOR each side of the winner's,
                               # lie this far apart; then a half and a quarter step around the best

_COARSE = np.deg2rad(np.arange(0.0, 90.0, 3.0))
_FINE = np.deg2rad(np.arange(-1.5, 1.5001, 0.1))


@numba.njit(cache=True, nogil=True)
def _closeness(xz: np.ndarray, thetas: np.ndarray) -> np.ndarray:
    """L-shape closeness score per candidate yaw (Zhang et al. 2017's criterion). Plain loops:
    the projections, their extremes and the score in two passes per yaw (array expressions made
    temporaries and four more passes: 2.5 times slower)."""
    score = np.zeros(len(thetas))
    a, b = np.empty(len(xz)), np.empty(len(xz))
    for k in range(len(thetas)):
        c, s = np.cos(thetas[k]), np.sin(thetas[k])
        a_lo = b_lo = np.inf
        a_hi = b_hi = -np.inf
        for i in range(len(xz)):
            # heading of yaw ry in (x, z) is (cos ry, -sin ry); lateral (sin ry, cos ry)
            a[i] = c * xz[i, 0] - s * xz[i, 1]
            b[i] = s * xz[i, 0] + c * xz[i, 1]
            a_lo, a_hi = min(a_lo, a[i]), max(a_hi, a[i])
            b_lo, b_hi = min(b_lo, b[i]), max(b_hi, b[i])
        for i in range(len(xz)):
            d = min(min(a_hi - a[i], a[i] - a_lo), min(b_hi - b[i], b[i] - b_lo))
            score[k] += 1.0 / max(d, LSHAPE_D0)
    return score


@numba.njit(cache=True, nogil=True)
def fit_yaw(xz: np.ndarray, ry_prior: float) -> float:
    """The yaw of the rectangle the returns outline, of the four it allows the one nearest ry_prior."""
    theta = _lshape_angle(xz)
    k = np.round((ry_prior - theta) / (np.pi / 2))
    return wrap_one(theta + k * np.pi / 2)


@numba.njit(cache=True, nogil=True)
def _lshape_angle(xz: np.ndarray) -> float:
    """The rectangle's axis angle in [0, 90) degrees: a coarse search, then a fine one around it."""
    if len(xz) > MAX_LSHAPE_POINTS:
        xz = xz[:: -(-len(xz) // MAX_LSHAPE_POINTS)]
    xz = xz - xz.sum(axis=0) / len(xz)
    coarse = _COARSE[np.argmax(_closeness(xz, _COARSE))]
    fine = coarse + _FINE
    return fine[np.argmax(_closeness(xz, fine))]


def _depth_per_px(d: float) -> float:
    """How far the road point under a box's bottom edge moves per pixel of that edge at depth d:
    d^2 / (f h), f ~ FOCAL_PX, camera ~1.65 m above the road."""
    return d * d / (FOCAL_PX * 1.65)


def _depth_sigma(d: float) -> float:
    """Uncertainty of the road depth under a box's bottom edge: 0.5 m, 5 %, and the depth change
    of a 2 px error in the edge."""
    return 0.5 + 0.05 * d + 2.0 * _depth_per_px(d)


def _image_depth_trust(location: np.ndarray) -> float:
    """How far to trust a depth taken from the road under a 2D box's bottom edge, as `mono`'s
    is (`lifter.mono.mono_quality`): 1 / (1 + the metres of depth one pixel of that edge is worth
    at the box's distance)."""
    return 1.0 / (1.0 + _depth_per_px(float(np.hypot(location[0], location[2]))))


@dataclass(frozen=True)
class _View:
    """The camera and frame facts every per-box step needs."""

    calib: Calibration
    image_size: tuple[int, int]
    cam: int
    outline: str          # how the 2D boxes outline their objects (lifter.methods.OUTLINES)
    sensor_xz: np.ndarray  # (2,) LiDAR origin, bird's-eye (rect x, z)

    @property
    def P(self) -> np.ndarray:
        return self.calib.P(self.cam)

    @cached_property
    def box_up(self) -> np.ndarray | None:
        """The up axis of the box whose projection a 2D box is (`mono.box_up_of`): the LiDAR's z
        for KITTI's 2D boxes, None for a silhouette's."""
        return box_up_of(self.outline, self.calib)

    @property
    def up(self) -> np.ndarray:
        """`box_up` for the placement kernels, which compare a silhouette with the camera-upright
        box."""
        return CAMERA_UP if self.box_up is None else self.box_up


class _Placed(NamedTuple):
    """One yaw hypothesis placed: its yaw, bottom centre, size, the faces its returns pin and its
    cost."""

    ry: float
    T: np.ndarray
    dims: np.ndarray
    pinned: int
    cost: float


@dataclass
class _Returns:
    """An object's returns: bird's-eye (x, z), image column, height above its road."""

    xz: np.ndarray
    u: np.ndarray
    height: np.ndarray

    centroid: np.ndarray = field(init=False)  # every yaw hypothesis pulls its box towards it

    def __post_init__(self):
        self.centroid = self.xz.sum(axis=0) / len(self.xz)


def _fallback(box: Box2D, prior: Prior, view: _View, plane: np.ndarray) -> Lifted:
    sol = solve_from_alpha(prior.dims, prior.alpha, box.bbox, view.calib, view.image_size, plane,
                           view.cam, cut_ok=True, contact=contact_of(box.type, view.outline),
                           box_up=view.box_up)
    return Lifted(sol.location, sol.rotation_y, np.asarray(prior.dims, dtype=float),
                  quality=0.2 * _image_depth_trust(sol.location))


def _box_for_yaw(ry: float, obj: _Returns, prior: Prior, small: bool, box: Box2D, view: _View,
                 plane: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, float]:
    """Size and bottom centre of the box with yaw ry around the object's returns (steps 4-5,
    `_size_and_place`), the faces they pin, and its cost: its misfit to the 2D box's sides and
    its length's to the prior's (0 when the returns measure the length)."""
    h, w, l = (float(v) for v in prior.dims)
    T, dims, pinned, misfit, length_cost = _size_and_place(
        obj.xz, obj.u, obj.height, h, w, l, ry, small, box.type == "Car", box.bbox,
        view.sensor_xz, obj.centroid, view.P, view.image_size[0], plane, view.up, box.side_sigma,
        box.side_dof)
    return T, dims, pinned, misfit + length_cost


@numba.njit(cache=True, nogil=True)
def _size_and_place(xz: np.ndarray, u: np.ndarray, height: np.ndarray, h: float, w: float,
                    l: float, ry: float, small: bool, car: bool, bbox: np.ndarray,
                    sensor_xz: np.ndarray, centroid: np.ndarray, P: np.ndarray, width: int,
                    plane: np.ndarray, up: np.ndarray, side_sigma: float,
                    side_dof: float) -> tuple[np.ndarray, np.ndarray, int, float, float]:
    """The prior size (h, w, l) grown to hold the returns and brought to the roof, the faces, 2D
    sides and road fixing the centre (a `car`'s faces above its bumpers set in), and an unmeasured
    length chosen with the 2D box (its sides' scale `side_sigma` px, `side_dof`): the bottom
    centre, the size, the pinned count, the box's misfit to the 2D box's sides (`side_cost`) and
    its length's cost (for a box the border cuts, with the returns it leaves out: SIGMA_EXTENT).
    One kernel: tried for every yaw hypothesis, its dozen small steps cost more in numpy's call
    overhead than in arithmetic."""
    c, s = np.cos(ry), np.sin(ry)
    pa = xz[:, 0] * c + xz[:, 1] * -s
    pb = xz[:, 0] * s + xz[:, 1] * c
    ext_a = percentile(pa, 98.0) - percentile(pa, 2.0)
    ext_b = percentile(pb, 98.0) - percentile(pb, 2.0)
    if not small:  # grow to hold the returns, unless they clearly hold something else too
        l = ext_a if l < ext_a <= l + MAX_GROW_L else l
        w = ext_b if w < ext_b <= w + MAX_GROW_W else w
    top = height.max()
    if top > ROOF_SEEN * h:  # the roof is hit: the top lies at most ROOF_GAP above its returns
        h = min(max(h, top), top + ROOF_GAP)
    best = _place(xz, u, height, h, w, l, ry, small, car, bbox, sensor_xz, centroid, P, width,
                  plane, up, np.inf, True, side_sigma, side_dof)
    if car and not small:  # the width across the mirrors, across the body below them, or the prior's
        for measure in (True, False):
            alt = _place(xz, u, height, h, w, l, ry, small, car, bbox, sensor_xz, centroid, P,
                         width, plane, up, MIRROR_FOOT * h, measure, side_sigma, side_dof)
            if alt[1][1] != best[1][1] and alt[3] + alt[4] < best[3] + best[4]:
                best = alt
    cut_left, cut_right = cut_sides(bbox, width)
    if small or not (cut_left or cut_right):
        return best
    # a box the image border cuts: its cut side fixes nothing and the network read a part of the
    # object, so the returns left out of the box along an axis weigh the yaw (at a wrong one a near
    # car's long side, which the scan sees past the border, lies across the box)
    out_l = max(0.0, ext_a - best[1][2])
    out_w = max(0.0, ext_b - best[1][1])
    return best[0], best[1], best[2], best[3], best[4] + (out_l ** 2 + out_w ** 2) / SIGMA_EXTENT ** 2


@numba.njit(cache=True, nogil=True)
def _place(xz: np.ndarray, u: np.ndarray, height: np.ndarray, h: float, w: float, l: float,
           ry: float, small: bool, car: bool, bbox: np.ndarray, sensor_xz: np.ndarray,
           centroid: np.ndarray, P: np.ndarray, width: int, plane: np.ndarray, up: np.ndarray,
           body_top: float, measure_w: bool, side_sigma: float,
           side_dof: float) -> tuple[np.ndarray, np.ndarray, int, float, float]:
    """`_size_and_place` for one way of taking a width both sides of which show: centred on
    the returns lower than body_top, measured by them or not (measure_w; `placement.translation`).
    Whether a box's width holds the door mirrors is a labelling convention (the generator's does,
    KITTI's hugs the body), which the 2D box's sides tell where the returns cannot."""
    T, dims, pinned, slide = translation(xz, u, height, h, w, l, ry, bbox, sensor_xz, centroid, P,
                                         width, plane, car, up, body_top, measure_w)
    length_cost = 0.0
    if not small and slide.any():  # length not measured: let the 2D box's width choose it
        T, dims[2] = length_from_sides(T, dims[0], dims[1], dims[2], ry, slide, bbox, P, width,
                                       plane, up, side_sigma, side_dof)
        length_cost = ((dims[2] - l) / SIGMA_LENGTH) ** 2
    box7 = np.array([[T[0], T[1], T[2], dims[0], dims[1], dims[2], ry]])
    return T, dims, pinned, side_cost(box7, P, bbox, width, up, side_sigma, side_dof)[0], length_cost


def lift_fit(boxes: list[Box2D], priors: list[Prior], pts: FramePoints, calib: Calibration,
             image_size: tuple[int, int], road: LocalRoad | FixedRoad | np.ndarray, cam: int = 2,
             outline: str = "silhouette") -> list[Lifted]:
    """One Lifted per box. `road`: the scan's road (`lifter.road.LocalRoad`: the plane under each
    box) or one plane (a, b, c, d; rect frame)."""
    road = FixedRoad(road) if isinstance(road, np.ndarray) else road
    view = _View(calib, image_size, cam, outline, pts.sensor[[0, 2]])
    c, dirs = camera_rays(view.P, np.array([[b.centre[0], b.bbox[3]] for b in boxes]))
    rays = [(c, d) for d in dirs]  # under the middle of each box's bottom edge
    planes = [plane_on_ray(road, *ray) for ray in rays]
    # the returns that may belong to a road user (above their local road, checked per box)
    pool = np.flatnonzero(road.may_stand(pts.rect, ROAD_CUT, MAX_HEIGHT))
    pool_u = pts.uv[pool, 0]  # image columns: the first test, and most returns fail it
    free = np.ones(len(pts.rect), dtype=bool)  # not yet claimed by a nearer box
    road_d = np.array([ray_depth(*ray, pl) for ray, pl in zip(rays, planes)])
    # confident boxes first, nearest first, and only they claim returns: a detector's low-score
    # duplicates of an object must not take its returns away from it
    confident = np.array([b.score >= CLAIM_MIN_SCORE for b in boxes])
    out: list[Lifted | None] = [None] * len(boxes)
    for i in np.lexsort((road_d, ~confident)):
        cand, hl = _frustum_returns(pts.rect, pts.uv, pool, pool_u, free,
                                    opened_at_border(boxes[i].bbox, image_size[0]), planes[i],
                                    float(image_size[0]))
        frame_d = ray_depth(*rays[i], road.plane)
        out[i], claimed = _fit_box(boxes[i], priors[i], cand, hl, pts, view, planes[i], road_d[i],
                                   frame_d)
        if confident[i] and claimed is not None:
            free[claimed] = False
    return out  # type: ignore[return-value]


def opened_at_border(bbox: np.ndarray, width: int) -> np.ndarray:
    """bbox [x1, y1, x2, y2] with each side the image border cuts moved out to infinity. The
    scan sees past the image's edge (`points.frame_points` keeps a 100-degree wedge), so a car
    the border cuts keeps the returns of the part the image does not show: its length and both
    its faces, which the yaw search and the placement need."""
    out = np.asarray(bbox, dtype=np.float64).copy()
    cut_left, cut_right = cut_sides(out, width)
    if cut_left:
        out[0] = -np.inf
    if cut_right:
        out[2] = np.inf
    return out


@numba.njit(cache=True, nogil=True)
def _frustum_returns(rect: np.ndarray, uv: np.ndarray, pool: np.ndarray, pool_u: np.ndarray,
                     free: np.ndarray, bbox: np.ndarray, plane: np.ndarray,
                     width: float) -> tuple[np.ndarray, np.ndarray]:
    """Steps 0-1 for one box: the returns of `pool` (image columns pool_u) not yet claimed whose
    pixel lies in bbox [x1, y1, x2, y2] and that lie ROAD_CUT..MAX_HEIGHT above `plane`, and their
    heights. Beyond the image's columns (0..width: where `opened_at_border` opened a side) the
    rows are no test: the box's rows are those of the part in view. One pass over the pool:
    numpy's masks and gathers over it, per box, were a tenth of `fit`'s time."""
    idx, hl = np.empty(len(pool), dtype=np.int64), np.empty(len(pool))
    n = 0
    for j in range(len(pool)):
        u = pool_u[j]
        if not bbox[0] <= u <= bbox[2]:
            continue
        i = pool[j]
        if not free[i] or (0.0 <= u <= width and not bbox[1] <= uv[i, 1] <= bbox[3]):
            continue
        h = rect[i, 0] * plane[0] + rect[i, 1] * plane[1] + rect[i, 2] * plane[2] + plane[3]
        if ROAD_CUT < h < MAX_HEIGHT:
            idx[n], hl[n] = i, h
            n += 1
    return idx[:n].copy(), hl[:n].copy()


@numba.njit(cache=True, nogil=True)
def _bev(rect: np.ndarray, uv: np.ndarray, idx: np.ndarray,
         sensor_xz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The returns rect[idx] in bird's-eye view (x, z), their image columns and their bird's-eye
    range from the sensor."""
    xz, u, rng = np.empty((len(idx), 2)), np.empty(len(idx)), np.empty(len(idx))
    for k in range(len(idx)):
        xz[k, 0], xz[k, 1], u[k] = rect[idx[k], 0], rect[idx[k], 2], uv[idx[k], 0]
        dx, dz = xz[k, 0] - sensor_xz[0], xz[k, 1] - sensor_xz[1]
        rng[k] = np.sqrt(dx * dx + dz * dz)
    return xz, u, rng


def visible_share(T: np.ndarray, dims: np.ndarray, ry: float, P: np.ndarray, width: int) -> float:
    """The share of the box's bearings (seen from the camera, bird's-eye) that the image covers.
    A box mostly beyond the image border is fitted to a piece of its object: on held-out
    generated frames (64 beams, oracle boxes) the Cars placed within IoU 0.7 fall from 0.67 of
    those inside the image to 0.43, 0.50 and 0.19 of those truncated 0.3-0.5, 0.5-0.7 and over
    0.7 (`benchmarks/lifter_by_truncation.py`, results/lifter.md)."""
    c, s = np.cos(ry), np.sin(ry)
    heading, lateral = np.array([c, -s]), np.array([s, c])
    half_l, half_w = dims[2] / 2, dims[1] / 2
    centre = np.array([T[0], T[2]])
    corners = np.array([centre + a * half_l * heading + b * half_w * lateral
                        for a in (-1, 1) for b in (-1, 1)])
    cam_x = -P[0, 3] / P[0, 0]  # the camera centre's x in the rect frame
    bearings = np.arctan2(corners[:, 0] - cam_x, corners[:, 1])
    lo_img, hi_img = np.arctan(-P[0, 2] / P[0, 0]), np.arctan((width - P[0, 2]) / P[0, 0])
    lo, hi = bearings.min(), bearings.max()
    span = hi - lo
    return float(np.clip((min(hi, hi_img) - max(lo, lo_img)) / span, 0.0, 1.0)) if span > 0 else 1.0


def _fit_box(box: Box2D, prior: Prior, cand: np.ndarray, height: np.ndarray, pts: FramePoints,
             view: _View, plane: np.ndarray, road_d: float,
             frame_d: float) -> tuple[Lifted, np.ndarray | None]:
    """Steps 2-7 for one box, its candidate returns `cand` (height above its road): the lifted
    box and the returns it claims (None for the image-only fallback)."""
    if len(cand) < MIN_POINTS:
        return _fallback(box, prior, view, plane), None
    xz, u, rng = _bev(pts.rect, pts.uv, cand, view.sensor_xz)
    # the road under the box may be off: the frame's plane's depth for it (frame_d) bounds how far
    sigma = float(np.hypot(_depth_sigma(road_d), road_d - frame_d))
    if box.bbox[3] >= view.image_size[1] - 2.0:  # bottom cut by the border: the road depth only bounds
        sigma = max(sigma, road_d)
    diag = float(np.hypot(prior.dims[2], prior.dims[1]))
    strip = float(min(prior.dims[1], prior.dims[2]))
    # the object is found among the returns in the box; those beyond a cut side (`opened_at_border`)
    # then add the part of it the image does not show
    in_view = (u >= box.bbox[0]) & (u <= box.bbox[2])
    if in_view.sum() < MIN_POINTS:
        return _fallback(box, prior, view, plane), None
    best, best_score = object_returns(xz[in_view], u[in_view], rng[in_view],
                                      max(box.bbox[2] - box.bbox[0], 1.0), road_d, sigma, diag,
                                      strip)
    if best_score < 0.02:
        return _fallback(box, prior, view, plane), None
    best = np.flatnonzero(in_view)[best]
    if not in_view.all():
        beyond = np.flatnonzero(~in_view)
        best = np.concatenate((best, beyond[grown_beyond(xz[best], xz[beyond], diag, strip)]))
    obj = _Returns(xz[best], u[best], height[best])
    c = obj.centroid
    ry_prior = float(wrap_angle(prior.alpha + np.arctan2(c[0], c[1])))
    small = box.type in SMALL_CLASSES
    ry, T, dims, pinned, cost = _best_yaw(obj, prior, ry_prior, small, box, view, plane)
    dims = dims.copy()
    dims[0] = height_from_box(T, dims, ry, box.bbox, view.outline, view.image_size[1], view.P,
                              view.up)
    h, w, l = dims
    # claim this object's returns so a farther box does not take them as its own
    grown = np.array([T[0], T[1] + CLAIM_MARGIN, T[2], h + 2 * CLAIM_MARGIN,
                      w + 2 * CLAIM_MARGIN, l + 2 * CLAIM_MARGIN, ry])
    claimed = _in_box_bev(pts.rect, cand, grown)
    # ranking: many returns and faces that pin the box down make a fit trustworthy, and a box that
    # needed its yaw, length or 2D sides far from what the evidence says less so
    quality = ((0.5 + 0.5 * min(1.0, len(obj.xz) / 30)) * (0.6 + 0.2 * pinned)
               / (1.0 + cost / COST_SCALE) * visible_share(T, dims, ry, view.P, view.image_size[0]))
    return Lifted(T, ry, dims, quality=quality), claimed


def _best_yaw(obj: _Returns, prior: Prior, ry_prior: float, small: bool, box: Box2D, view: _View,
              plane: np.ndarray) -> _Placed:
    """Step 3 and the yaw hypotheses: the L-shape's axes (or the network's yaw) fix the axes and
    the network picks which one is the length; it is sometimes wrong by ~90 degrees, so the other
    axis is tried too, and so is the network's own yaw. Each costs its distance from the
    network's yaw (SIGMA_YAW_PRIOR), how much worse a rectangle fits the returns than at the
    L-shape's (SIGMA_RECT), its box's misfit to the 2D box's sides and its length's to the prior.
    Returns the winner."""
    # the outline is the body's: windows and roof are set in from it (a real car's glasshouse
    # narrows above the belt line), so the returns below it give the L-shape where enough do
    body = obj.xz[obj.height < BELT_LINE * prior.dims[0]]
    body = body if len(body) >= MIN_LSHAPE else obj.xz
    yaws, costs = _yaw_hypotheses(body, ry_prior, small)
    best_fit, best_cost, best_box_cost = None, np.inf, 0.0
    for ry_h, cost in zip(yaws.tolist(), costs.tolist()):
        if cost >= best_cost:  # its misfit to the 2D box could only add to that
            continue
        T_h, dims_h, pinned_h, fit_cost = _box_for_yaw(ry_h, obj, prior, small, box, view, plane)
        cost += fit_cost
        if cost < best_cost:
            best_fit = _Placed(ry_h, T_h, dims_h, pinned_h, cost)
            best_cost, best_box_cost = cost, fit_cost
    if small or len(body) < MIN_LSHAPE or best_box_cost <= 1.0:
        return best_fit
    return _refine_yaw(best_fit, best_box_cost, body, obj, prior, ry_prior, box, view, plane)


def _refine_yaw(best_fit: _Placed, box_cost: float, body: np.ndarray, obj: _Returns,
                prior: Prior, ry_prior: float, box: Box2D, view: _View,
                plane: np.ndarray) -> _Placed:
    """Step 3b: the yaws near the winner's (whose box costs `box_cost` against the 2D box and
    the length prior), each costing its distance from the network's yaw, how much worse a
    rectangle fits the returns than the best-fitting of them, and its box's misfit; the cheapest
    wins, the winner included. Yaws whose first two terms alone cost more than the best so far
    are not placed."""
    pts = body[:: -(-len(body) // MAX_LSHAPE_POINTS)]
    ry0 = best_fit.ry
    n = int(round(SIGMA_YAW_PRIOR / REFINE_STEP))
    yaws = np.array([ry0] + [float(ry0 + k * REFINE_STEP) for k in range(-n, n + 1) if k])
    rms = _rect_rms_each(pts, yaws)
    rms_min = float(rms.min())
    pre = _yaw_pre(yaws, rms, ry_prior, rms_min)
    best = [best_fit._replace(cost=float(pre[0]) + box_cost)]

    def tried(y: float, c: float) -> None:
        if c >= best[0].cost:  # its misfit to the 2D box could only add to that
            return
        T, dims, pinned, fit_cost = _box_for_yaw(y, obj, prior, False, box, view, plane)
        if c + fit_cost < best[0].cost:
            best[0] = _Placed(wrap_one(y), T, dims, pinned, c + fit_cost)

    for k in sorted(range(1, len(yaws)), key=lambda k: pre[k]):
        tried(float(yaws[k]), float(pre[k]))
    for step in (REFINE_STEP / 2, REFINE_STEP / 4):  # halve the step twice around the best
        y1 = best[0].ry
        ys = np.array([y1 - step, y1 + step])
        costs = _yaw_pre(ys, _rect_rms_each(pts, ys), ry_prior, rms_min)
        for y, c in zip(ys.tolist(), costs.tolist()):
            tried(y, c)
    return best[0]


@numba.njit(cache=True, nogil=True)
def _yaw_pre(yaws: np.ndarray, rms: np.ndarray, ry_prior: float, rms_min: float) -> np.ndarray:
    """Step 3b's cost of each yaw before its box is placed: its distance from the network's yaw
    and how much worse its rectangle fits the returns (RMS `rms`) than the best one's."""
    out = np.empty(len(yaws))
    for k in range(len(yaws)):
        out[k] = ((wrap_one(2 * (yaws[k] - ry_prior)) / 2 / SIGMA_YAW_PRIOR) ** 2
                  + (max(rms[k] - rms_min, 0.0) / SIGMA_RECT) ** 2)
    return out


@numba.njit(cache=True, nogil=True)
def _rect_rms_each(xz: np.ndarray, yaws: np.ndarray) -> np.ndarray:
    """`_rect_rms` for each of the yaws."""
    out = np.empty(len(yaws))
    for k in range(len(yaws)):
        out[k] = _rect_rms(xz, yaws[k])
    return out


@numba.njit(cache=True, nogil=True)
def _yaw_hypotheses(body: np.ndarray, ry_prior: float,
                    small: bool) -> tuple[np.ndarray, np.ndarray]:
    """`_best_yaw`'s yaws, the L-shape's first, and what each costs before its box is placed: its
    distance from the network's yaw and how much worse a rectangle fits the returns."""
    ry = ry_prior if small or len(body) < MIN_LSHAPE else fit_yaw(body, ry_prior)
    if small:
        yaws, offs = np.array([ry]), np.array([0.0])
    else:
        best, perp = np.inf, 0.0  # of the L-shape's other axis, the direction nearest the network's
        for k in range(4):
            p = ry + np.pi / 2 * (1.0 - 2.0 * (k % 2)) + np.pi * (k // 2)
            if abs(wrap_one(p - ry_prior)) < best:
                best, perp = abs(wrap_one(p - ry_prior)), wrap_one(p)
        # the network's own yaw too: a real car's rounded corners and short L legs can leave the
        # L-shape a few degrees off at hardly any cost in how well a rectangle fits the returns,
        # and the 2D box's sides then show it
        yaws = np.array([ry, ry_prior, perp])
        offs = np.array([wrap_one(2 * (ry - ry_prior)) / 2, 0.0,
                         wrap_one(2 * (perp - ry_prior)) / 2])
        if abs(offs[0]) < SAME_YAW:  # the L-shape agrees with the network: nothing to weigh
            yaws, offs = yaws[::2].copy(), offs[::2].copy()
    pts = body[:: -(-len(body) // MAX_LSHAPE_POINTS)]
    rms_best = _rect_rms(pts, ry) if len(pts) >= MIN_LSHAPE else 0.0
    costs = (offs / SIGMA_YAW_PRIOR) ** 2
    for k in range(len(yaws)):
        if len(pts) >= MIN_LSHAPE and yaws[k] != ry:  # how much worse a rectangle fits the returns
            costs[k] += ((_rect_rms(pts, yaws[k]) - rms_best) / SIGMA_RECT) ** 2
    return yaws, costs


@numba.njit(cache=True, nogil=True)
def _rect_rms(xz: np.ndarray, ry: float) -> float:
    """RMS distance of the returns to the nearest side of their rectangle of yaw ry (2nd to 98th
    percentile along each axis)."""
    c, s = np.cos(ry), np.sin(ry)
    a = c * xz[:, 0] - s * xz[:, 1]
    b = s * xz[:, 0] + c * xz[:, 1]
    a0, a1 = percentile(a, 2.0), percentile(a, 98.0)
    b0, b1 = percentile(b, 2.0), percentile(b, 98.0)
    total = 0.0
    for i in range(len(xz)):
        d = min(min(abs(a[i] - a0), abs(a1 - a[i])), min(abs(b[i] - b0), abs(b1 - b[i])))
        total += d * d
    return np.sqrt(total / len(xz))


@numba.njit(cache=True, nogil=True)
def _in_box_bev(rect: np.ndarray, idx: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Those of the returns rect[idx] inside the box b [x, y, z, h, w, l, ry] in bird's-eye view."""
    c, s = np.cos(b[6]), np.sin(b[6])
    inside = np.empty(len(idx), dtype=np.bool_)
    for k in range(len(idx)):
        dx, dz = rect[idx[k], 0] - b[0], rect[idx[k], 2] - b[2]
        inside[k] = abs(dx * c - dz * s) <= b[5] / 2 and abs(dx * s + dz * c) <= b[4] / 2
    return idx[inside]
