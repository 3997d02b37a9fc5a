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

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from kitti.boxes import box_corners, wrap_angle
from kitti.calib import Calibration

from .mono import solve_from_alpha
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
FOCAL_PX = 720.0       # px, a KITTI-like focal length: only for that sensitivity
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
LENGTH_STEPS = np.array([0.85, 0.9, 0.95, 1.05, 1.1, 1.15])  # x prior length tried against the 2D box
SMALL_CLASSES = ("Pedestrian", "Cyclist", "Person_sitting")

_COARSE = np.deg2rad(np.arange(0.0, 90.0, 1.0))
_FINE = np.deg2rad(np.arange(-1.0, 1.0001, 0.1))


def _pct(v: np.ndarray, q: float) -> float:
    """The q-th percentile (nearest rank): np.percentile's interpolation costs ten times more."""
    k = int(round(q / 100.0 * (len(v) - 1)))
    return float(np.partition(v, k)[k])


def _bev_clusters(xz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bird's-eye cells (CELL m) of the returns, their cluster labels, and each return's cell:
    clustering cells instead of returns bounds the cost on a dense near car."""
    ij = np.floor(xz / CELL).astype(np.int64)
    ij -= ij.min(axis=0)
    key = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]  # one integer per cell: a 1-D unique
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    cells = (np.floor(xz[first] / CELL) + 0.5) * CELL
    pairs = cKDTree(cells).query_pairs(CLUSTER_R, output_type="ndarray")
    n = len(cells)
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return cells, connected_components(g, directed=False)[1], inverse.reshape(-1)


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
    xz = xz - xz.mean(axis=0)
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


def _depth_sigma(d: float) -> float:
    """Uncertainty of the road depth under a box's bottom edge: 0.5 m, 5 %, and the depth change
    of a 2 px error in the edge (d^2 / (f h), f ~ 720 px, camera ~1.65 m above the road)."""
    return 0.5 + 0.05 * d + 2.0 * d * d / (720.0 * 1.65)


def _fallback(box, prior, calib, image_size, plane, cam) -> Lifted:
    sol = solve_from_alpha(prior.dims, prior.alpha, box.bbox, calib, image_size, plane, cam,
                           cut_ok=True)
    return Lifted(sol.location, sol.rotation_y, np.asarray(prior.dims, dtype=float), quality=0.2)


def _faces(pxz: np.ndarray, puv: np.ndarray, e: np.ndarray, e_other: np.ndarray, size: float,
           other: float, grow: float, sensor_xz: np.ndarray, box: Box2D,
           width: int) -> tuple[float, float, float]:
    """The centre coordinate along axis e implied by the faces the returns show.

    The extreme of the returns facing the sensor is a face when the returns beside it spread
    across it (the face is seen), or when it reaches a 2D box side (the outline ends there: the
    end of a face seen edge-on). The far extreme is trusted only in the second case (far roof or
    bonnet returns are no face). An extreme that touches a box side at the image border is cut
    there, and one that ends inside the box without showing its face is cut by an occluder:
    neither is used. When both ends are shown, their distance is the size (within SHRINK below
    and `grow` above the prior). Returns the centre coordinate, a weight factor and the size.
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
        a = pxz[at].mean(axis=0)
        px_per_m = abs(FOCAL_PX * ((a[0] + e[0]) / (a[1] + e[1]) - a[0] / a[1]))
        ends = px_per_m * FACE_MAX_SLIDE >= tol and any(np.abs(u - s).min() < tol for s in sides)
        ok[near] = ends or (near and np.ptp(q[at]) >= FACE_SPREAD * other)
    near_face, near_sign = (lo, 1.0) if near_lo else (hi, -1.0)
    far_face, far_sign = (hi, -1.0) if near_lo else (lo, 1.0)
    if ok[True] and ok[False]:  # both ends shown: the returns measure the size too
        measured = float(np.ptp(p))
        if (1 - SHRINK) * size <= measured <= size + grow:
            return 0.5 * (p.min() + p.max()), 1.0, measured
        return near_face + near_sign * size / 2, 1.0, size
    if ok[True]:
        return near_face + near_sign * size / 2, 1.0, size
    if ok[False]:
        return far_face + far_sign * size / 2, 1.0, size
    # no face confirmed: returns lie on the surfaces facing the sensor, so the likeliest centre is
    # still half a size beyond the near extreme; a weak row
    return near_face + near_sign * size / 2, WEAK_FACE, size


def _translation(pxz: np.ndarray, puv: np.ndarray, dims: np.ndarray, ry: float, box: Box2D,
                 sensor: np.ndarray, start: np.ndarray, calib: Calibration, image_size,
                 plane: np.ndarray, cam: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Bottom-centre (x, y, z) by weighted least squares on faces, 2D sides and the road plane,
    the size with l and w measured where the returns show both ends, and how many of the two axes
    a confirmed face pins down."""
    h, w, l = dims
    ea = np.array([np.cos(ry), -np.sin(ry)])  # heading in (x, z)
    eb = np.array([np.sin(ry), np.cos(ry)])   # lateral
    sxz = sensor[[0, 2]]
    ray = start[[0, 2]] - sxz
    ray = ray / max(np.linalg.norm(ray), 1e-9)
    rows, rhs, wts = [], [], []
    sizes, pinned = [], 0
    for e, eo, size, other, grow in ((ea, eb, l, w, MAX_GROW_L), (eb, ea, w, l, MAX_GROW_W)):
        centre, weight, size = _faces(pxz, puv, e, eo, size, other, grow, sxz, box, image_size[0])
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
    xz, *_ = np.linalg.lstsq(A0 * w0[:, None], b0 * w0, rcond=None)
    for _ in range(2):
        # the 2D sides fix the bearing, not the depth: each side's row keeps only its component
        # across the camera ray (else a few pixels of silhouette-vs-box mismatch, which the LS
        # would absorb cheaply along the ray, pull the box by a metre in depth)
        y = -(n[0] * xz[0] + n[2] * xz[1] + plane[3]) / n[1]
        T = np.array([xz[0], y, xz[1]])
        r = xz / max(np.linalg.norm(xz), 1e-9)
        offs = box_corners(np.array([[0, 0, 0, h, w, l, ry]]))[0]
        uv, _ = calib.rect_to_image(offs + T, cam)
        extra_rows, extra_rhs, extra_w = [], [], []
        for u, pick, cut in ((box.bbox[0], np.argmin(uv[:, 0]), box.bbox[0] <= 1.0),
                             (box.bbox[2], np.argmax(uv[:, 0]), box.bbox[2] >= W - 2.0)):
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
        xz, *_ = np.linalg.lstsq(A * wv[:, None], b * wv, rcond=None)
    y = -(n[0] * xz[0] + n[2] * xz[1] + plane[3]) / n[1]
    return np.array([xz[0], y, xz[1]]), np.array([h, w, l]), pinned


def _side_error(T, dims, ry, box: Box2D, calib: Calibration, image_size, cam: int) -> float:
    """Mean |projected box side - 2D box side| in pixels over the left and right sides not cut by
    the image border."""
    uv, _ = calib.rect_to_image(box_corners(np.array([[*T, *dims, ry]]))[0], cam)
    errs = [abs(uv[:, 0].min() - box.bbox[0])] if box.bbox[0] > 1.0 else []
    if box.bbox[2] < image_size[0] - 2.0:
        errs.append(abs(uv[:, 0].max() - box.bbox[2]))
    return float(np.mean(errs)) if errs else 0.0


def _merge(xz: np.ndarray, labels: np.ndarray, seed: int, diag: float) -> np.ndarray:
    """The seed cluster plus the nearby clusters that keep the set car-sized: a far object's
    bumper, bonnet and roof returns fall apart in bird's-eye view but belong together."""
    take = labels == seed
    others = [k for k in range(labels.max() + 1) if k != seed]
    dist = {k: np.min(np.linalg.norm(xz[labels == k][:, None] - xz[take][None], axis=2))
            for k in others}
    for k in sorted(others, key=dist.get):
        if dist[k] > diag:
            break
        trial = take | (labels == k)
        pts = xz[trial]
        if 2 * np.linalg.norm(pts - pts.mean(axis=0), axis=1).max() <= diag + MERGE_SLACK:
            take = trial
    return take


def lift_fit(boxes: list[Box2D], priors: list[Prior], pts: FramePoints, calib: Calibration,
             image_size: tuple[int, int], plane: np.ndarray, cam: int = 2) -> list[Lifted]:
    n = len(boxes)
    out: list[Lifted | None] = [None] * n
    keep = (pts.height > ROAD_CUT) & (pts.height < MAX_HEIGHT)
    free = keep.copy()  # not yet claimed by a nearer box
    road_d = np.array([_ground_depth(b, calib, plane, cam) for b in boxes])
    # confident boxes first, nearest first, and only they claim returns: a detector's low-score
    # duplicates of an object must not take its returns away from it
    confident = np.array([b.score >= CLAIM_MIN_SCORE for b in boxes])
    order = np.lexsort((road_d, ~confident))
    for i in order:
        box, prior = boxes[i], priors[i]
        inbox = pts.in_box(box.bbox)
        inbox = inbox[keep[inbox]]
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

        def score(m: np.ndarray) -> float:
            coverage = min(1.0, np.ptp(u_all[m]) / width)
            gap = rng_all[m].min() - road_d[i]
            return (coverage + 0.05) * min(1.0, m.sum() / 10) * np.exp(-0.5 * (gap / sigma) ** 2)

        counts = np.bincount(labels)
        seeds = [k for k in np.flatnonzero(counts >= MIN_SEED)]
        seeds = sorted(seeds, key=lambda k: -score(labels == k))[:MAX_SEEDS]
        best, best_score = None, 0.0
        for k in seeds:  # the likeliest clusters, each grown by its car-sized neighbours
            m = _merge(cells, cell_labels, k, diag)[inverse]
            if m.sum() < MIN_POINTS:
                continue
            sc = score(m)
            if sc > best_score:
                best, best_score = m, sc
        if best is None or best_score < 0.02:
            out[i] = _fallback(box, prior, calib, image_size, plane, cam)
            continue
        obj = cand[best]
        oxz = xz[best]
        centroid = oxz.mean(axis=0)
        ry_prior = float(wrap_angle(prior.alpha + np.arctan2(centroid[0], centroid[1])))
        small = box.type in SMALL_CLASSES
        ry = ry_prior if small or len(obj) < MIN_LSHAPE else fit_yaw(oxz, ry_prior)
        ea = np.array([np.cos(ry), -np.sin(ry)])
        eb = np.array([np.sin(ry), np.cos(ry)])
        pa, pb = rowdot(oxz, ea), rowdot(oxz, eb)
        ext_a, ext_b = _pct(pa, 98.0) - _pct(pa, 2.0), _pct(pb, 98.0) - _pct(pb, 2.0)
        if not small:  # grow to hold the returns, unless they clearly hold something else too
            l = ext_a if l < ext_a <= l + MAX_GROW_L else l
            w = ext_b if w < ext_b <= w + MAX_GROW_W else w
        top = float(pts.height[obj].max())
        if top > ROOF_SEEN * h:  # the roof is hit: the top lies at most ROOF_GAP above its returns
            h = float(np.clip(h, top, top + ROOF_GAP))
        dims = np.array([h, w, l])
        start_xz = centroid
        start_y = -(plane[0] * start_xz[0] + plane[2] * start_xz[1] + plane[3]) / plane[1]
        start = np.array([start_xz[0], start_y, start_xz[1]])
        T, dims, pinned = _translation(oxz, pts.uv[obj], dims, ry, box, pts.sensor, start, calib,
                               image_size, plane, cam)
        if not small and dims[2] == l:  # length not measured: let the 2D box's width choose it
            best_err = _side_error(T, dims, ry, box, calib, image_size, cam)
            for cand_l in l * LENGTH_STEPS:
                T2, d2, p2 = _translation(oxz, pts.uv[obj], np.array([h, w, cand_l]), ry, box,
                                          pts.sensor, start, calib, image_size, plane, cam)
                err = _side_error(T2, d2, ry, box, calib, image_size, cam)
                if err < best_err - 0.5:
                    T, dims, pinned, best_err = T2, d2, p2, err
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
