"""The strongest LiDAR lifter here: per-frame road plane, the object's own returns separated in the
frustum, an oriented box fitted to them with the network's size and orientation as priors.

Per 2D box, nearest first (depth from the road point under the box's bottom edge; boxes scoring
under CLAIM_MIN_SCORE after the others):
1. frustum returns above the road (ROAD_CUT .. MAX_HEIGHT), minus those already claimed by a
   nearer box's fit (an occluder with its own 2D box);
2. bird's-eye Euclidean clusters (a vertical surface stays connected however few beams hit it),
   each grown by the neighbouring clusters that keep it car-sized (a far car's bumper and roof
   fall apart); the set that best covers the box's columns at the depth the road predicts wins;
3. yaw by L-shape search (closeness criterion) over 0..90 degrees; of the four yaws it allows, the
   one nearest the network's; too few or collinear-in-one-point returns keep the network's yaw;
4. size: the network's, measured where both ends show, grown to hold the returns (capped);
   the height brought within ROOF_GAP of the roof returns when the roof is hit; a length the
   returns do not measure is chosen among LENGTH_GRID x the network's by how well the fitted
   box's outline meets the 2D box's left and right sides;
5. translation (x, z) by weighted least squares: the faces the returns confirm must touch the
   extreme returns, the box's outline must meet the 2D box's left and right sides (across the
   camera ray only: a 2D side fixes a bearing, not a depth), and the bottom sits on the road
   plane; two passes (the corner that touches each side may change);
6. fewer than MIN_POINTS returns: the image-only solution constrained to the road plane;
7. score = 2D score x a quality from the number of returns and the faces that pin the box.

Step 2 is `clusters.object_returns`, steps 4-5 are `placement`'s kernels.
"""

from __future__ import annotations

import numba
import numpy as np

from kitti.boxes import wrap_angle
from kitti.calib import Calibration

from .clusters import MIN_POINTS, object_returns
from .mono import contact_of, solve_from_alpha, solve_translation
from .placement import (
    FOCAL_PX,
    MAX_GROW_L,
    MAX_GROW_W,
    SIGMA_SIDE_PX,
    length_from_sides,
    percentile,
    road_y,
    side_misfit,
    translation,
)
from .points import FramePoints, rowdot
from .types import Box2D, Lifted, Prior

ROAD_CUT = 0.15        # m above the fitted plane: lower returns are road
MAX_HEIGHT = 4.0       # m above the plane: higher returns are no road user
MIN_LSHAPE = 8         # fewer returns: keep the network's yaw
LSHAPE_D0 = 0.05       # m, closeness floor of the L-shape criterion
MAX_LSHAPE_POINTS = 300  # returns used for the yaw search (evenly strided)
CLAIM_MARGIN = 0.3     # m around a fitted box whose returns it claims
CLAIM_MIN_SCORE = 0.3  # 2D score a box needs to claim returns
ROOF_SEEN = 0.75       # highest return above this share of the prior height: the roof is hit
ROOF_GAP = 0.2         # m, the top lies at most this far above the highest roof return (64 beams:
                       # 90 % within 0.14 m on the testbed's cars; sparse scans a little more)
LOW_RETURNS = 0.4      # share of the height: no return below it, and the face may be unseen
IMAGE_DEPTH_K = 0.15   # returns this many image-depth sigmas behind the road contact are
                       # bonnet, boot or windows: the image's depth is taken
SIGMA_YAW_PRIOR = np.deg2rad(20.0)  # the network's orientation, against the 2D box's evidence
SMALL_CLASSES = ("Pedestrian", "Cyclist", "Person_sitting")

_COARSE = np.deg2rad(np.arange(0.0, 90.0, 3.0))
_FINE = np.deg2rad(np.arange(-1.5, 1.5001, 0.1))


@numba.njit(cache=True, nogil=True)
def _closeness(xz: np.ndarray, thetas: np.ndarray) -> np.ndarray:
    """L-shape closeness score per candidate yaw (Zhang et al. 2017's criterion)."""
    score = np.zeros(len(thetas))
    a, b = np.empty(len(xz)), np.empty(len(xz))
    for k in range(len(thetas)):
        c, s = np.cos(thetas[k]), np.sin(thetas[k])
        # heading of yaw ry in (x, z) is (cos ry, -sin ry); lateral (sin ry, cos ry)
        a[:] = c * xz[:, 0] - s * xz[:, 1]
        b[:] = s * xz[:, 0] + c * xz[:, 1]
        a_lo, a_hi, b_lo, b_hi = a.min(), a.max(), b.min(), b.max()
        for i in range(len(xz)):
            d = min(min(a_hi - a[i], a[i] - a_lo), min(b_hi - b[i], b[i] - b_lo))
            score[k] += 1.0 / max(d, LSHAPE_D0)
    return score


def fit_yaw(xz: np.ndarray, ry_prior: float) -> float:
    """The yaw of the rectangle the returns outline, of the four it allows the one nearest ry_prior."""
    theta = _lshape_angle(np.ascontiguousarray(xz))
    k = np.round((ry_prior - theta) / (np.pi / 2))
    return float(wrap_angle(theta + k * np.pi / 2))


@numba.njit(cache=True, nogil=True)
def _lshape_angle(xz: np.ndarray) -> float:
    """The rectangle's axis angle in [0, 90) degrees: a coarse search, then a fine one around it."""
    if len(xz) > MAX_LSHAPE_POINTS:
        xz = xz[:: -(-len(xz) // MAX_LSHAPE_POINTS)]
    xz = xz - xz.sum(axis=0) / len(xz)
    coarse = _COARSE[np.argmax(_closeness(xz, _COARSE))]
    fine = coarse + _FINE
    return fine[np.argmax(_closeness(xz, fine))]


def _ground_depth(box: Box2D, calib: Calibration, plane: np.ndarray, cam: int) -> float:
    """Distance to the road point seen under the middle of the box's bottom edge."""
    u, v = box.centre[0], box.bbox[3]
    p1 = calib.image_to_rect(np.array([[u, v]]), np.array([1.0]), cam)[0]
    ray = p1 / np.linalg.norm(p1)
    denom = ray @ plane[:3]
    if denom >= -1e-6:  # bottom edge above the horizon: far away
        return 200.0
    return float(min(-plane[3] / denom, 200.0))


def _depth_per_px(d: float) -> float:
    """How far the road point under a box's bottom edge moves per pixel of that edge at depth d:
    d^2 / (f h), f ~ FOCAL_PX, camera ~1.65 m above the road."""
    return d * d / (FOCAL_PX * 1.65)


def _depth_sigma(d: float) -> float:
    """Uncertainty of the road depth under a box's bottom edge: 0.5 m, 5 %, and the depth change
    of a 2 px error in the edge."""
    return 0.5 + 0.05 * d + 2.0 * _depth_per_px(d)


def _image_depth_sigma(d: float) -> float:
    """Depth error of the ground contact under a 2D box: 1.5 px of the bottom edge plus 2 % for
    the size and orientation behind the contact."""
    return 1.5 * _depth_per_px(d) + 0.02 * d


def _fallback(box, prior, calib, image_size, plane, cam) -> Lifted:
    sol = solve_from_alpha(prior.dims, prior.alpha, box.bbox, calib, image_size, plane, cam,
                           cut_ok=True, contact=contact_of(box.type))
    return Lifted(sol.location, sol.rotation_y, np.asarray(prior.dims, dtype=float), quality=0.2)


def _box_for_yaw(ry: float, oxz: np.ndarray, ou: np.ndarray, oheight: np.ndarray, prior: Prior,
                 small: bool, box: Box2D, sensor: np.ndarray, centroid: np.ndarray,
                 calib: Calibration, image_size, plane: np.ndarray,
                 cam: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Size and bottom centre of the box with yaw ry around the object's returns (steps 4-5):
    the prior size grown to hold them and brought to the roof, the faces, 2D sides and road
    fixing the centre, and an unmeasured length chosen with the 2D box."""
    h, w, l = (float(v) for v in prior.dims)
    pa = rowdot(oxz, np.array([np.cos(ry), -np.sin(ry)]))
    pb = rowdot(oxz, np.array([np.sin(ry), np.cos(ry)]))
    ext_a = percentile(pa, 98.0) - percentile(pa, 2.0)
    ext_b = percentile(pb, 98.0) - percentile(pb, 2.0)
    if not small:  # grow to hold the returns, unless they clearly hold something else too
        l = ext_a if l < ext_a <= l + MAX_GROW_L else l
        w = ext_b if w < ext_b <= w + MAX_GROW_W else w
    top = float(oheight.max())
    if top > ROOF_SEEN * h:  # the roof is hit: the top lies at most ROOF_GAP above its returns
        h = float(np.clip(h, top, top + ROOF_GAP))
    P, width = calib.P(cam), image_size[0]
    T, dims, pinned, slide = translation(oxz, ou, h, w, l, ry, box.bbox, sensor[[0, 2]], centroid,
                                         P, width, plane)
    if not small and slide.any():  # length not measured: let the 2D box's width choose it
        T, dims[2] = length_from_sides(T, *dims, ry, slide, box.bbox, P, width, plane)
    if not small and oheight.min() > LOW_RETURNS * dims[0] and box.bbox[3] < image_size[1] - 2.0:
        T = _image_depth_check(T, dims, ry, box, sensor, calib, image_size, plane, cam)
    return T, dims, pinned


def _image_depth_check(T: np.ndarray, dims: np.ndarray, ry: float, box: Box2D, sensor: np.ndarray,
                       calib: Calibration, image_size, plane: np.ndarray, cam: int) -> np.ndarray:
    """No return on the lower part of the object: a sparse scan's few rings crossed only its
    bonnet, boot or windows, and the extreme the fit took for a face may lie behind the real one.
    The road under the 2D box's bottom edge says where the object stands; returns cannot lie in
    front of that but may lie behind it: when they do by more than the image's depth error, the
    centre moves along the ray to the image's depth."""
    try:
        T_img = solve_translation(dims, ry, box.bbox, calib, image_size, plane, cam,
                                  contact=contact_of(box.type)).location
    except ValueError:
        return T
    ray = T[[0, 2]] - sensor[[0, 2]]
    d_fit = np.linalg.norm(ray)
    d_img = np.linalg.norm(T_img[[0, 2]] - sensor[[0, 2]])
    if d_fit - d_img <= IMAGE_DEPTH_K * _image_depth_sigma(d_img):
        return T
    x, z = sensor[[0, 2]] + ray * (d_img / d_fit)
    return np.array([x, road_y(x, z, plane), z])


def lift_fit(boxes: list[Box2D], priors: list[Prior], pts: FramePoints, calib: Calibration,
             image_size: tuple[int, int], plane: np.ndarray, cam: int = 2) -> list[Lifted]:
    n = len(boxes)
    out: list[Lifted | None] = [None] * n
    keep = (pts.height > ROAD_CUT) & (pts.height < MAX_HEIGHT)
    above = np.flatnonzero(keep)  # the returns that may belong to a road user
    above_uv = pts.uv[above]
    free = keep.copy()  # not yet claimed by a nearer box
    road_d = np.array([_ground_depth(b, calib, plane, cam) for b in boxes])
    # confident boxes first, nearest first, and only they claim returns: a detector's low-score
    # duplicates of an object must not take its returns away from it
    confident = np.array([b.score >= CLAIM_MIN_SCORE for b in boxes])
    order = np.lexsort((road_d, ~confident))
    for i in order:
        box, prior = boxes[i], priors[i]
        x1, y1, x2, y2 = box.bbox
        u, v = above_uv[:, 0], above_uv[:, 1]
        inbox = above[(u >= x1) & (u <= x2) & (v >= y1) & (v <= y2)]
        cand = inbox[free[inbox]]
        if len(cand) < MIN_POINTS:
            out[i] = _fallback(box, prior, calib, image_size, plane, cam)
            continue
        xz = pts.rect[cand][:, [0, 2]]
        sigma = _depth_sigma(road_d[i])
        if box.bbox[3] >= image_size[1] - 2.0:  # bottom cut by the border: the road depth only bounds
            sigma = max(sigma, road_d[i])
        best, best_score = object_returns(xz, pts.uv[cand, 0],
                                          np.linalg.norm(xz - pts.sensor[[0, 2]], axis=1),
                                          max(box.bbox[2] - box.bbox[0], 1.0), road_d[i], sigma,
                                          float(np.hypot(prior.dims[2], prior.dims[1])))
        if best_score < 0.02:
            out[i] = _fallback(box, prior, calib, image_size, plane, cam)
            continue
        obj = cand[best]
        oxz = xz[best]
        ou = pts.uv[obj, 0]
        centroid = oxz.sum(axis=0) / len(oxz)
        ry_prior = float(wrap_angle(prior.alpha + np.arctan2(centroid[0], centroid[1])))
        small = box.type in SMALL_CLASSES
        ry = ry_prior if small or len(obj) < MIN_LSHAPE else fit_yaw(oxz, ry_prior)
        hyps = [(ry, 0.0)]
        if not small:
            # the L-shape (or the network) fixes the axes and the network picks which one is the
            # length; it is sometimes wrong by ~90 degrees: the other axis is tried too, and the
            # 2D box's sides weigh against the network's orientation
            perp = ry + np.pi / 2 * np.array([1.0, -1.0, 1.0, -1.0]) + np.array([0, 0, np.pi, np.pi])
            perp = float(wrap_angle(perp[np.argmin(np.abs(wrap_angle(perp - ry_prior)))]))
            hyps.append((perp, float(wrap_angle(2 * (perp - ry_prior)) / 2)))
            hyps[0] = (ry, float(wrap_angle(2 * (ry - ry_prior)) / 2))
        best_fit, best_cost = None, np.inf
        for ry_h, off in hyps:
            prior_cost = (off / SIGMA_YAW_PRIOR) ** 2
            if prior_cost >= best_cost:  # its misfit to the 2D box could only add to that
                continue
            T_h, dims_h, pinned_h = _box_for_yaw(ry_h, oxz, ou, pts.height[obj], prior, small, box,
                                                 pts.sensor, centroid, calib, image_size, plane, cam)
            misfit = side_misfit(np.array([[*T_h, *dims_h, ry_h]]), calib.P(cam), box.bbox,
                                 image_size[0])[0]
            cost = prior_cost + misfit / SIGMA_SIDE_PX ** 2
            if cost < best_cost:
                best_fit, best_cost = (ry_h, T_h, dims_h, pinned_h), cost
        ry, T, dims, pinned = best_fit
        h, w, l = dims
        # claim this object's returns so a farther box does not take them as its own
        grown = np.array([[T[0], T[1] + CLAIM_MARGIN, T[2], h + 2 * CLAIM_MARGIN,
                           w + 2 * CLAIM_MARGIN, l + 2 * CLAIM_MARGIN, ry]])
        if confident[i]:
            free[cand[_in_box_bev(pts.rect[cand], grown[0])]] = False
        # ranking: many returns and faces that pin the box down make a fit trustworthy
        quality = (0.5 + 0.5 * min(1.0, len(obj) / 30)) * (0.6 + 0.2 * pinned)
        out[i] = Lifted(T, ry, dims, quality=quality)
    return out  # type: ignore[return-value]


def _in_box_bev(p: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = p[:, [0, 2]] - b[[0, 2]]
    c, s = np.cos(b[6]), np.sin(b[6])
    a = d[:, 0] * c - d[:, 1] * s
    lat = d[:, 0] * s + d[:, 1] * c
    return (np.abs(a) <= b[5] / 2) & (np.abs(lat) <= b[4] / 2)
