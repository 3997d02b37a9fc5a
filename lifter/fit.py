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
   returns do not measure is chosen among LENGTH_STEPS x the network's by how well the fitted
   box's outline meets the 2D box's left and right sides;
5. translation (x, z) by weighted least squares: the faces the returns confirm must touch the
   extreme returns, the box's outline must meet the 2D box's left and right sides (across the
   camera ray only: a 2D side fixes a bearing, not a depth), and the bottom sits on the road
   plane; two passes (the corner that touches each side may change);
6. fewer than MIN_POINTS returns: the image-only solution constrained to the road plane;
7. score = 2D score x a quality from the number of returns and the faces that pin the box.
"""

from __future__ import annotations

import numba
import numpy as np

from kitti.boxes import box_corners, wrap_angle
from kitti.calib import Calibration

from .mono import contact_of, solve_from_alpha, solve_translation
from .points import FramePoints, rowdot
from .types import Box2D, Lifted, Prior

ROAD_CUT = 0.15        # m above the fitted plane: lower returns are road
MAX_HEIGHT = 4.0       # m above the plane: higher returns are no road user
CLUSTER_R = 0.6        # m, bird's-eye linking distance
CELL = 0.1             # m, bird's-eye cell the returns are pooled in before clustering
MIN_POINTS = 3         # fewer returns: image-only fallback
MIN_SEED = 2           # returns of a cluster that may seed an object
MAX_SEEDS = 3          # best-scoring clusters tried as seeds
MIN_LSHAPE = 8         # fewer returns: keep the network's yaw
LSHAPE_D0 = 0.05       # m, closeness floor of the L-shape criterion
MAX_LSHAPE_POINTS = 300  # returns used for the yaw search (evenly strided)
SIGMA_FACE = 0.05      # m, weight of a face row
SIGMA_IMAGE = 0.15     # m at the object, weight of a 2D-side row (mesh silhouette vs box)
CLAIM_MARGIN = 0.3     # m around a fitted box whose returns it claims
CLAIM_MIN_SCORE = 0.3  # 2D score a box needs to claim returns
SIGMA_CENTROID = 3.0   # m, weak pull to the returns' centroid
FACE_BAND = 0.25       # m, returns this close to an extreme are "at" it
FACE_SPREAD = 0.3      # of the face's width: returns spreading this far across it show the face
FACE_MAX_SLIDE = 0.3   # m, how far an end may hide within the 2D side tolerance
FOCAL_PX = 720.0       # px, a KITTI-like focal length: only for pixel-to-metre sensitivities
WEAK_FACE = 0.1        # weight of an unconfirmed near face, relative to a confirmed one
FACE_TOL_PX = 3.0      # px, an extreme this close to a 2D side is the outline's end
FACE_TOL_FRAC = 0.06   # ... or this share of the box width
MAX_GROW_L = 0.4       # m, most the returns may lengthen the prior box
MAX_GROW_W = 0.25      # m, most they may widen it
SHRINK = 0.15          # most the returns may shorten or narrow it (share of the prior)
ROOF_SEEN = 0.75       # highest return above this share of the prior height: the roof is hit
ROOF_GAP = 0.2         # m, the top lies at most this far above the highest roof return (64 beams:
                       # 90 % within 0.14 m on the testbed's cars; sparse scans a little more)
MERGE_SLACK = 0.3      # m, how much larger than the size prior's diagonal a merged set may be
LENGTH_GRID = 1.0 + 0.01 * np.arange(-25, 26)  # x prior length tried against the 2D box
SIGMA_LENGTH = 0.35    # m, the size network's length error on cars (MAE 0.35 m on held-out worlds)
LOW_RETURNS = 0.4      # share of the height: no return below it, and the face may be unseen
IMAGE_DEPTH_K = 0.15   # returns this many image-depth sigmas behind the road contact are
                       # bonnet, boot or windows: the image's depth is taken
SIGMA_YAW_PRIOR = np.deg2rad(20.0)  # the network's orientation, against the 2D box's evidence
SIGMA_SIDE_PX = 2.0    # px, a 2D box side vs the projected 3D box (the body's outline lies 1-3 px
                       # inside the box's corners on the testbed's cars)
SMALL_CLASSES = ("Pedestrian", "Cyclist", "Person_sitting")

_COARSE = np.deg2rad(np.arange(0.0, 90.0, 3.0))
_FINE = np.deg2rad(np.arange(-1.5, 1.5001, 0.1))


def _pct(v: np.ndarray, q: float) -> float:
    """The q-th percentile (nearest rank): np.percentile's interpolation costs ten times more."""
    k = round(q / 100.0 * (len(v) - 1))
    return float(np.partition(v, k)[k])


def _bev_clusters(xz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bird's-eye cells (CELL m) of the returns, their cluster labels, and each return's cell:
    clustering cells instead of returns bounds the cost on a dense near car."""
    ij = np.floor(xz / CELL).astype(np.int64)
    ij -= ij.min(axis=0)
    key = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]  # one integer per cell: a 1-D unique
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    cells = (np.floor(xz[first] / CELL) + 0.5) * CELL
    return cells, _link_components(cells, CLUSTER_R), inverse.reshape(-1)


@numba.njit(cache=True, nogil=True)
def _link_components(p: np.ndarray, r: float) -> np.ndarray:
    """Connected components of the points under 'closer than r' (labels 0, 1, ... in order of
    each component's first point): a flood fill over all pairs, cheaper than a k-d tree and a
    sparse graph for the few hundred cells of one frustum."""
    n = len(p)
    label = np.full(n, -1, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    r2 = r * r
    k = 0
    for s in range(n):
        if label[s] >= 0:
            continue
        label[s] = k
        top = 0
        stack[0] = s
        while top >= 0:
            i = stack[top]
            top -= 1
            for j in range(n):
                if label[j] < 0:
                    dx = p[i, 0] - p[j, 0]
                    dz = p[i, 1] - p[j, 1]
                    if dx * dx + dz * dz <= r2:
                        label[j] = k
                        top += 1
                        stack[top] = j
        k += 1
    return label


def _closeness(xz: np.ndarray, thetas: np.ndarray) -> np.ndarray:
    """L-shape closeness score per candidate yaw (Zhang et al. 2017's criterion)."""
    c, s = np.cos(thetas)[:, None], np.sin(thetas)[:, None]
    # heading of yaw ry in (x, z) is (cos ry, -sin ry); lateral (sin ry, cos ry)
    a = c * xz[None, :, 0] - s * xz[None, :, 1]
    b = s * xz[None, :, 0] + c * xz[None, :, 1]
    da = np.minimum(a.max(1, keepdims=True) - a, a - a.min(1, keepdims=True))
    db = np.minimum(b.max(1, keepdims=True) - b, b - b.min(1, keepdims=True))
    return (1.0 / np.maximum(np.minimum(da, db), LSHAPE_D0)).sum(axis=1)


def fit_yaw(xz: np.ndarray, ry_prior: float) -> float:
    """The yaw of the rectangle the returns outline, of the four it allows the one nearest ry_prior."""
    if len(xz) > MAX_LSHAPE_POINTS:
        xz = xz[:: int(np.ceil(len(xz) / MAX_LSHAPE_POINTS))]
    xz = xz - xz.sum(axis=0) / len(xz)
    coarse = _COARSE[np.argmax(_closeness(xz, _COARSE))]
    fine = coarse + _FINE
    theta = fine[np.argmax(_closeness(xz, fine))]
    k = np.round((ry_prior - theta) / (np.pi / 2))
    return float(wrap_angle(theta + k * np.pi / 2))


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


def _faces(pxz: np.ndarray, puv: np.ndarray, e: np.ndarray, e_other: np.ndarray, size: float,
           other: float, grow: float, sensor_xz: np.ndarray, box: Box2D,
           width: int) -> tuple[float, float, float, float]:
    """The centre coordinate along axis e implied by the faces the returns show.

    The extreme of the returns facing the sensor is a face when the returns beside it spread
    across it (the face is seen), or when it reaches a 2D box side (the outline ends there: the
    end of a face seen edge-on). The far extreme is trusted only in the second case (far roof or
    bonnet returns are no face). An extreme that touches a box side at the image border is cut
    there, and one that ends inside the box without showing its face is cut by an occluder:
    neither is used. When both ends are shown, their distance is the size (within SHRINK below
    and `grow` above the prior). Returns the centre coordinate, a weight factor, the size, and
    which way the centre moves along e when the size grows with the anchoring face kept (+1, -1;
    0 when the returns measure the size).
    """
    p, q = rowdot(pxz, e), rowdot(pxz, e_other)
    lo, hi = _pct(p, 2.0), _pct(p, 98.0)
    near_lo = sensor_xz @ e < 0.5 * (lo + hi)
    tol = max(FACE_TOL_PX, FACE_TOL_FRAC * (box.bbox[2] - box.bbox[0]))
    x1, x2 = box.bbox[0], box.bbox[2]
    border = [u for u, cut in ((x1, x1 <= 1.0), (x2, x2 >= width - 2.0)) if cut]
    sides = [u for u, cut in ((x1, x1 <= 1.0), (x2, x2 >= width - 2.0)) if not cut]
    ok = {}
    for face, near in ((lo, near_lo), (hi, not near_lo)):
        dist = np.abs(p - face)
        at = dist <= max(FACE_BAND, dist.min())  # the percentile may fall between sparse returns
        u = puv[at, 0]
        if any(np.abs(u - b).min() < tol for b in border):
            ok[near] = False
            continue
        # reaching a 2D side only proves an end where moving along e moves the image point enough
        a = pxz[at].sum(axis=0) / at.sum()
        px_per_m = abs(FOCAL_PX * ((a[0] + e[0]) / (a[1] + e[1]) - a[0] / a[1]))
        ends = px_per_m * FACE_MAX_SLIDE >= tol and any(np.abs(u - s).min() < tol for s in sides)
        ok[near] = ends or (near and np.ptp(q[at]) >= FACE_SPREAD * other)
    near_face, near_sign = (lo, 1.0) if near_lo else (hi, -1.0)
    far_face, far_sign = (hi, -1.0) if near_lo else (lo, 1.0)
    if ok[True] and ok[False]:  # both ends shown: the returns measure the size too
        measured = float(np.ptp(p))
        if (1 - SHRINK) * size <= measured <= size + grow:
            return 0.5 * (p.min() + p.max()), 1.0, measured, 0.0
        return near_face + near_sign * size / 2, 1.0, size, near_sign
    if ok[True]:
        return near_face + near_sign * size / 2, 1.0, size, near_sign
    if ok[False]:
        return far_face + far_sign * size / 2, 1.0, size, far_sign
    # no face confirmed: returns lie on the surfaces facing the sensor, so the likeliest centre is
    # still half a size beyond the near extreme; a weak row
    return near_face + near_sign * size / 2, WEAK_FACE, size, near_sign


def _on_road(xz: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """(..., 3) points of the road plane at bird's-eye positions xz (..., 2)."""
    x, z = xz[..., 0], xz[..., 1]
    return np.stack([x, -(plane[0] * x + plane[2] * z + plane[3]) / plane[1], z], axis=-1)


def _columns(pts: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Image column of rect-frame points (..., 3)."""
    x, y, z = pts[..., 0], pts[..., 1], pts[..., 2]
    return ((P[0, 0] * x + P[0, 1] * y + P[0, 2] * z + P[0, 3])
            / (P[2, 0] * x + P[2, 1] * y + P[2, 2] * z + P[2, 3]))


def _wls2(A: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted least squares in two unknowns by the 2x2 normal equations (rows scaled by w):
    LAPACK's lstsq costs more in set-up than this whole solve."""
    Aw = A * w[:, None]
    bw = b * w
    a11, a12, a22 = Aw[:, 0] @ Aw[:, 0], Aw[:, 0] @ Aw[:, 1], Aw[:, 1] @ Aw[:, 1]
    r1, r2 = Aw[:, 0] @ bw, Aw[:, 1] @ bw
    det = a11 * a22 - a12 * a12
    return np.array([a22 * r1 - a12 * r2, a11 * r2 - a12 * r1]) / det


def _translation(pxz: np.ndarray, puv: np.ndarray, dims: np.ndarray, ry: float, box: Box2D,
                 sensor: np.ndarray, start: np.ndarray, calib: Calibration, image_size,
                 plane: np.ndarray, cam: int) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """Bottom-centre (x, y, z) by weighted least squares on faces, 2D sides and the road plane,
    the size with l and w measured where the returns show both ends, how many of the two axes a
    confirmed face pins down, and the (x, z) direction the centre moves per metre of length with
    the anchoring face kept (zero when the returns measure the length)."""
    h, w, l = dims
    ea = np.array([np.cos(ry), -np.sin(ry)])  # heading in (x, z)
    eb = np.array([np.sin(ry), np.cos(ry)])   # lateral
    sxz = sensor[[0, 2]]
    ray = start[[0, 2]] - sxz
    ray = ray / max(np.linalg.norm(ray), 1e-9)
    rows, rhs, wts = [], [], []
    sizes, pinned, slides = [], 0, []
    for e, eo, size, other, grow in ((ea, eb, l, w, MAX_GROW_L), (eb, ea, w, l, MAX_GROW_W)):
        centre, weight, size, slide = _faces(pxz, puv, e, eo, size, other, grow, sxz, box,
                                             image_size[0])
        slides.append(0.5 * slide * e)
        sizes.append(size)
        pinned += weight == 1.0
        rows.append(e)
        rhs.append(centre)
        wts.append(weight * (0.2 + 0.8 * abs(ray @ e)) / SIGMA_FACE)
        rows.append(e)  # weak pull to the returns' centroid: only matters when nothing else binds
        rhs.append(start[[0, 2]] @ e)
        wts.append(1.0 / SIGMA_CENTROID)
    l, w = sizes
    P = calib.P(cam)
    W = image_size[0]
    n = plane[:3]

    def lift_row(r3, r0):  # a row in (x, y, z) -> (x, z) with y on the plane
        return np.array([r3[0] - r3[1] * n[0] / n[1], r3[2] - r3[1] * n[2] / n[1]]), \
            -(r0 - r3[1] * plane[3] / n[1])
    A0, b0, w0 = np.array(rows), np.array(rhs), np.array(wts)
    xz = _wls2(A0, b0, w0)
    offs = box_corners(np.array([[0, 0, 0, h, w, l, ry]]))[0]
    for _ in range(2):
        # the 2D sides fix the bearing, not the depth: each side's row keeps only its component
        # across the camera ray (else a few pixels of silhouette-vs-box mismatch, which the LS
        # would absorb cheaply along the ray, pull the box by a metre in depth)
        T = _on_road(xz, plane)
        r = xz / max(np.linalg.norm(xz), 1e-9)
        u_corner = _columns(offs + T, P)
        extra_rows, extra_rhs, extra_w = [], [], []
        for u, pick, cut in ((box.bbox[0], np.argmin(u_corner), box.bbox[0] <= 1.0),
                             (box.bbox[2], np.argmax(u_corner), box.bbox[2] >= W - 2.0)):
            if cut:
                continue
            pr = P[0] - u * P[2]
            a2, b2 = lift_row(pr[:3], pr[3] + pr[:3] @ offs[pick])
            along = a2 @ r
            extra_rows.append((a2 - along * r) / P[0, 0])
            extra_rhs.append((b2 - along * (r @ xz)) / P[0, 0])
            extra_w.append(1.0 / SIGMA_IMAGE)
        A = np.vstack([A0] + [np.array(extra_rows)] * bool(extra_rows))
        b = np.concatenate([b0, extra_rhs])
        wv = np.concatenate([w0, extra_w])
        xz = _wls2(A, b, wv)
    return _on_road(xz, plane), np.array([h, w, l]), pinned, slides[0]


def _length_from_sides(T: np.ndarray, dims: np.ndarray, ry: float, slide: np.ndarray,
                       box: Box2D, calib: Calibration, image_size, plane: np.ndarray,
                       cam: int) -> tuple[np.ndarray, float]:
    """A length the returns do not measure, chosen with the 2D box: every length of LENGTH_GRID x the
    prior, the box's anchoring face kept (the centre slides by `slide` per metre); the one that
    best balances the outline's misfit to the 2D box's left and right sides (SIGMA_SIDE_PX each)
    against its distance from the prior (SIGMA_LENGTH) wins. Seen from behind, the sides hardly
    move with the length and the prior stands; seen from the side, they decide.
    Returns the centre and the length."""
    h, w, l = dims
    lengths = l * LENGTH_GRID
    centres = _on_road(T[[0, 2]] + np.outer(lengths - l, slide), plane)
    k = len(lengths)
    boxes = np.column_stack([centres, np.full(k, h), np.full(k, w), lengths, np.full(k, ry)])
    cost = (((lengths - l) / SIGMA_LENGTH) ** 2
            + _side_misfit(boxes, box, calib, image_size, cam) / SIGMA_SIDE_PX ** 2)
    best = int(np.argmin(cost))
    return centres[best], float(lengths[best])


def _groups(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Order that sorts the items by cluster, and where each cluster starts in it: for
    `ufunc.reduceat` per cluster (the labels run 0..k-1, every one present)."""
    order = np.argsort(labels, kind="stable")
    return order, np.flatnonzero(np.concatenate(([True], np.diff(labels[order]) > 0)))


def _cluster_bounds(xz: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per cluster, the lower and upper corners of its bird's-eye bounding box."""
    order, starts = _groups(labels)
    return (np.minimum.reduceat(xz[order], starts, axis=0),
            np.maximum.reduceat(xz[order], starts, axis=0))


def _merge(xz: np.ndarray, labels: np.ndarray, seed: int, diag: float,
           bounds: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The seed cluster plus the nearby clusters that keep the set car-sized: a far object's
    bumper, bonnet and roof returns fall apart in bird's-eye view but belong together."""
    take = labels == seed
    lo, hi = bounds
    # the gap between bounding boxes bounds the distance from below: only clusters within diag
    # of the seed's box get the exact point-to-point distance
    gap = np.maximum(0.0, np.maximum(lo - hi[seed], lo[seed] - hi))
    near = np.flatnonzero(np.hypot(gap[:, 0], gap[:, 1]) <= diag)
    seed_xz = xz[take]
    dist = {int(k): float(np.sqrt(((xz[labels == k][:, None] - seed_xz[None]) ** 2).sum(axis=2).min()))
            for k in near if k != seed}
    for k in sorted(dist, key=dist.get):
        if dist[k] > diag:
            break
        trial = take | (labels == k)
        pts = xz[trial]
        d = pts - pts.sum(axis=0) / len(pts)
        if 2 * np.sqrt((d * d).sum(axis=1).max()) <= diag + MERGE_SLACK:
            take = trial
    return take


def _box_for_yaw(ry: float, oxz: np.ndarray, ouv: np.ndarray, oheight: np.ndarray, prior: Prior,
                 small: bool, box: Box2D, sensor: np.ndarray, centroid: np.ndarray,
                 calib: Calibration, image_size, plane: np.ndarray,
                 cam: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Size and bottom centre of the box with yaw ry around the object's returns (steps 4-5):
    the prior size grown to hold them and brought to the roof, the faces, 2D sides and road
    fixing the centre, and an unmeasured length chosen with the 2D box."""
    h, w, l = (float(v) for v in prior.dims)
    ea = np.array([np.cos(ry), -np.sin(ry)])
    eb = np.array([np.sin(ry), np.cos(ry)])
    pa, pb = rowdot(oxz, ea), rowdot(oxz, eb)
    ext_a, ext_b = _pct(pa, 98.0) - _pct(pa, 2.0), _pct(pb, 98.0) - _pct(pb, 2.0)
    if not small:  # grow to hold the returns, unless they clearly hold something else too
        l = ext_a if l < ext_a <= l + MAX_GROW_L else l
        w = ext_b if w < ext_b <= w + MAX_GROW_W else w
    top = float(oheight.max())
    if top > ROOF_SEEN * h:  # the roof is hit: the top lies at most ROOF_GAP above its returns
        h = float(np.clip(h, top, top + ROOF_GAP))
    start = _on_road(centroid, plane)
    T, dims, pinned, slide = _translation(oxz, ouv, np.array([h, w, l]), ry, box, sensor, start,
                                          calib, image_size, plane, cam)
    if not small and slide.any():  # length not measured: let the 2D box's width choose it
        T, dims[2] = _length_from_sides(T, dims, ry, slide, box, calib, image_size, plane, cam)
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
    return _on_road(sensor[[0, 2]] + ray * (d_img / d_fit), plane)


def _side_misfit(boxes7: np.ndarray, box: Box2D, calib: Calibration, image_size,
                 cam: int) -> np.ndarray:
    """Per 3D box (N, 7), the sum of squared pixel distances between its projected left/right
    extremes and the 2D box's sides not cut by the image border."""
    u = _columns(box_corners(boxes7), calib.P(cam))  # (N, 8)
    err = np.zeros(len(u))
    if box.bbox[0] > 1.0:
        err += (u.min(axis=1) - box.bbox[0]) ** 2
    if box.bbox[2] < image_size[0] - 2.0:
        err += (u.max(axis=1) - box.bbox[2]) ** 2
    return err


def _explain_score(u_span, count, gap, width: float, sigma: float):
    """How well a set of returns explains a 2D box: wide in the image (its column span against the
    box's width), many returns, its nearest return near the depth the road predicts (gap, m)."""
    return ((np.minimum(1.0, u_span / width) + 0.05) * np.minimum(1.0, count / 10)
            * np.exp(-0.5 * (gap / sigma) ** 2))


def _seed_clusters(labels: np.ndarray, u: np.ndarray, rng: np.ndarray, width: float, road_d: float,
                   sigma: float) -> np.ndarray:
    """The MAX_SEEDS clusters (of MIN_SEED returns or more) that best explain the box, scored all
    at once."""
    order, starts = _groups(labels)
    counts = np.diff(np.append(starts, len(labels)))
    ptp = np.maximum.reduceat(u[order], starts) - np.minimum.reduceat(u[order], starts)
    gap = np.minimum.reduceat(rng[order], starts) - road_d
    score = _explain_score(ptp, counts, gap, width, sigma)
    seeds = np.flatnonzero(counts >= MIN_SEED)
    return seeds[np.argsort(-score[seeds], kind="stable")][:MAX_SEEDS]


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
        cells, cell_labels, inverse = _bev_clusters(xz)
        labels = cell_labels[inverse]
        width = max(box.bbox[2] - box.bbox[0], 1.0)
        h, w, l = (float(v) for v in prior.dims)
        sigma = _depth_sigma(road_d[i])
        if box.bbox[3] >= image_size[1] - 2.0:  # bottom cut by the border: the road depth only bounds
            sigma = max(sigma, road_d[i])
        diag = np.hypot(l, w)
        rng_all = np.linalg.norm(xz - pts.sensor[[0, 2]], axis=1)
        u_all = pts.uv[cand, 0]

        seeds = _seed_clusters(labels, u_all, rng_all, width, road_d[i], sigma)
        best, best_score = None, 0.0
        bounds = _cluster_bounds(cells, cell_labels)
        for k in seeds:  # the likeliest clusters, each grown by its car-sized neighbours
            m = _merge(cells, cell_labels, k, diag, bounds)[inverse]
            if m.sum() < MIN_POINTS:
                continue
            sc = float(_explain_score(np.ptp(u_all[m]), m.sum(), rng_all[m].min() - road_d[i],
                                      width, sigma))
            if sc > best_score:
                best, best_score = m, sc
        if best is None or best_score < 0.02:
            out[i] = _fallback(box, prior, calib, image_size, plane, cam)
            continue
        obj = cand[best]
        oxz = xz[best]
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
            T_h, dims_h, pinned_h = _box_for_yaw(ry_h, oxz, pts.uv[obj], pts.height[obj], prior, small,
                                                 box, pts.sensor, centroid, calib, image_size, plane,
                                                 cam)
            misfit = _side_misfit(np.array([[*T_h, *dims_h, ry_h]]), box, calib, image_size, cam)[0]
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
