"""Steps 4-5 of `fit` (see fit.py): where the box of a given yaw stands around an object's
returns. The faces the returns show, the 2D box's left and right sides and the road plane fix its
bird's-eye centre by weighted least squares; a length the returns do not measure is chosen against
the 2D box's sides.

Numba kernels: the arithmetic is a few dozen operations on 2-vectors and a pass over the object's
returns, which numpy would spend in call overhead (it was two thirds of `fit`'s time). Arrays in
the rectified camera frame; bird's-eye vectors are (x, z); a yaw ry has heading (cos ry, -sin ry)
and lateral (sin ry, cos ry) there; P is the (3, 4) projection, plane (a, b, c, d) the unit-normal
road plane; `up` the up axis of the box whose projection the 2D box is (CAMERA_UP for the label's
own box, the LiDAR's z for KITTI's 2D boxes: `mono.box_up_of`), whose corners the 2D sides are
compared with (`mono.standing_corners` on that up; the bottom centre stays on the road plane).
"""

from __future__ import annotations

import numba
import numpy as np

from .mono import _standing

SIGMA_FACE = 0.05      # m, weight of a face row
SIGMA_IMAGE = 0.15     # m at the object, weight of a 2D-side row (mesh silhouette vs box)
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
LENGTH_GRID = 1.0 + 0.01 * np.arange(-25, 26)  # x prior length tried against the 2D box
SIGMA_LENGTH = 0.35    # m, the size network's length error on cars (MAE 0.35 m on held-out worlds)
BORDER_LEFT = 1.0      # px: a 2D side at or beyond these is cut by the image border
BORDER_RIGHT = 2.0     # px from the right edge (image width - this)
# A car's outline is set in from its box above the bumpers: the bonnet slopes back to the
# windscreen's foot, the glasshouse (windows, pillars, roof) narrows above the belt line, so
# returns that look like a face up there lie inside the box. Set-in against height (rows: share of
# the height; share of the length from the front and the rear end, of the width from a side),
# linear between stations that are means over sedan, hatchback, estate and SUV profiles read off
# makers' side views (VW Golf VI, Passat B7 sedan and estate, Tiguan; bonnet front 0.46-0.60 h,
# belt line 0.57-0.65 h): front face to 0.44 h, bonnet front 0.51 h (0.12 m in), windscreen foot
# at the belt line 0.25-0.33 l in, roof front ~0.5 l (a 52-63 degree rake); tailgate or boot lid
# to 0.55 h, rear window foot 0.02-0.21 l in, roof end 0.04-0.34 l; the body 0.1 m inside the
# mirrors (the generator's box width) and the glass's top at ~0.8 of the body's half width (a
# KITTI label's box hugs the body: there these side set-ins are ~0.1 m too deep)
OUTLINE_FRONT = np.array([[0.44, 0.51, 0.61, 0.97], [0.0, 0.03, 0.30, 0.50]])
OUTLINE_REAR = np.array([[0.55, 0.61, 0.97], [0.0, 0.07, 0.14]])
OUTLINE_SIDE = np.array([[0.61, 0.62, 0.97], [0.0, 0.07, 0.15]])
SIGMA_OUTLINE = (0.3, 0.1)  # m, spread of the end and the side set-ins over those profiles
# A box upright in the camera frame: its up axis (rect y points down).
CAMERA_UP = np.array([0.0, -1.0, 0.0])


@numba.njit(cache=True, nogil=True)
def cut_sides(bbox: np.ndarray, width: int) -> tuple[bool, bool]:
    """Whether the image border cuts the 2D box's left and its right side (BORDER_LEFT,
    BORDER_RIGHT): such a side is the border's column, no constraint on the object."""
    return bbox[0] <= BORDER_LEFT, bbox[2] >= width - BORDER_RIGHT


@numba.njit(cache=True, nogil=True)
def percentile(v: np.ndarray, q: float) -> float:
    """The q-th percentile by nearest rank: np.percentile's interpolation costs ten times more."""
    k = round(q / 100.0 * (len(v) - 1))
    return np.partition(v, k)[k]


@numba.njit(cache=True, nogil=True)
def road_y(x: float, z: float, plane: np.ndarray) -> float:
    """Height coordinate (rect y) of the road plane at bird's-eye (x, z)."""
    return -(plane[0] * x + plane[2] * z + plane[3]) / plane[1]


@numba.njit(cache=True, nogil=True)
def corner_columns(x: float, y: float, z: float, h: float, w: float, l: float, ry: float,
                   P: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Image columns of the 8 corners (kitti.boxes order) of the box [x, y, z, h, w, l, ry]
    standing on `up`."""
    off = _standing(h, w, l, ry, up)
    u = np.empty(8)
    for k in range(8):
        px, py, pz = off[k, 0] + x, off[k, 1] + y, off[k, 2] + z
        u[k] = ((P[0, 0] * px + P[0, 1] * py + P[0, 2] * pz + P[0, 3])
                / (P[2, 0] * px + P[2, 1] * py + P[2, 2] * pz + P[2, 3]))
    return u


@numba.njit(cache=True, nogil=True)
def side_cost(boxes7: np.ndarray, P: np.ndarray, bbox: np.ndarray, width: int, up: np.ndarray,
              sigma: float, dof: float) -> np.ndarray:
    """Per 3D box (N, 7) standing on `up`, how far its projected left/right extremes miss the 2D
    box's sides not cut by the image border, as minus twice their log-likelihood (up to a
    constant) for sides of scale `sigma` px: Gaussian (dof inf) the sum of squared misses over
    sigma^2; Student-t with `dof` degrees of freedom (dof + 1) log(1 + (miss / sigma)^2 / dof) a
    side, which grows like the Gaussian's for small misses and only logarithmically for the far
    ones (a detector's tail: `types.Box2D.side_dof`)."""
    err = np.zeros(len(boxes7))
    gaussian = np.isinf(dof)
    cut_left, cut_right = cut_sides(bbox, width)
    for i in range(len(boxes7)):
        b = boxes7[i]
        u = corner_columns(b[0], b[1], b[2], b[3], b[4], b[5], b[6], P, up)
        total = 0.0
        if not cut_left:
            total += _side_term(u.min() - bbox[0], sigma, dof, gaussian)
        if not cut_right:
            total += _side_term(u.max() - bbox[2], sigma, dof, gaussian)
        err[i] = total / sigma ** 2 if gaussian else total
    return err


@numba.njit(cache=True, nogil=True)
def _side_term(miss: float, sigma: float, dof: float, gaussian: bool) -> float:
    """One side's term of `side_cost`: its squared miss (px^2, the sum divided by sigma^2 after),
    or the Student-t's (dof + 1) log(1 + (miss / sigma)^2 / dof)."""
    if gaussian:
        return miss ** 2
    return (dof + 1.0) * np.log(1.0 + (miss / sigma) ** 2 / dof)


@numba.njit(cache=True, nogil=True)
def _faces(pxz: np.ndarray, pu: np.ndarray, ph: np.ndarray, e: np.ndarray, e_other: np.ndarray,
           size: float, other: float, grow: float, sensor_xz: np.ndarray, bbox: np.ndarray,
           width: int, h: float, car: bool, end: bool,
           body_top: float, measure: bool) -> tuple[float, float, float, float]:
    """The centre coordinate along axis e implied by the faces the returns show.

    The extreme of the returns facing the sensor is a face when the returns beside it spread
    across it (the face is seen), or when it reaches a 2D box side (the outline ends there: the
    end of a face seen edge-on). The far extreme is trusted only in the second case (far roof or
    bonnet returns are no face). An extreme that touches a box side at the image border is cut
    there, and one that ends inside the box without showing its face is cut by an occluder:
    neither is used. When both ends are shown, the returns' extremes lower than `body_top` above
    the road (all of them where fewer than two are) centre the box and, if `measure`, their
    distance is the size (within SHRINK below and `grow` above the prior). A car's near face
    whose lowest return lies above its bumpers
    (ph: heights above the road, h the car's height; `end`: e is its heading, whose + end is the
    front) is its bonnet's or glasshouse's: the box's face lies the set-in of OUTLINE_* at that
    height nearer, known to SIGMA_OUTLINE (vans and trucks have other outlines: none is taken).
    Returns the centre coordinate, a weight factor, the size, and which way the centre moves
    along e when the size grows with the anchoring face kept (+1, -1; 0 when the returns measure
    the size).
    """
    n = len(pxz)
    p = pxz[:, 0] * e[0] + pxz[:, 1] * e[1]
    q = pxz[:, 0] * e_other[0] + pxz[:, 1] * e_other[1]
    lo, hi = percentile(p, 2.0), percentile(p, 98.0)
    near_lo = sensor_xz[0] * e[0] + sensor_xz[1] * e[1] < 0.5 * (lo + hi)
    x1, x2 = bbox[0], bbox[2]
    tol = max(FACE_TOL_PX, FACE_TOL_FRAC * (x2 - x1))
    cut1, cut2 = cut_sides(bbox, width)
    ok_near = ok_far = False
    near_low = np.inf  # the lowest return at the near face
    for which in range(2):
        near = (which == 0) == near_lo  # face lo first, then hi
        face = lo if which == 0 else hi
        dmin = np.inf
        for j in range(n):
            dmin = min(dmin, abs(p[j] - face))
        band = max(FACE_BAND, dmin)  # the percentile may fall between sparse returns
        cut = reach = False
        a0 = a1 = 0.0
        count = 0
        q_lo, q_hi = np.inf, -np.inf
        for j in range(n):
            if abs(p[j] - face) > band:
                continue
            d1, d2 = abs(pu[j] - x1) < tol, abs(pu[j] - x2) < tol
            cut |= (cut1 and d1) or (cut2 and d2)
            reach |= (not cut1 and d1) or (not cut2 and d2)
            a0 += pxz[j, 0]
            a1 += pxz[j, 1]
            count += 1
            if near:
                near_low = min(near_low, ph[j])
            q_lo, q_hi = min(q_lo, q[j]), max(q_hi, q[j])
        if cut:
            ok = False
        else:
            # reaching a 2D side only proves an end where moving along e moves the image point
            # enough
            a0, a1 = a0 / count, a1 / count
            px_per_m = abs(FOCAL_PX * ((a0 + e[0]) / (a1 + e[1]) - a0 / a1))
            ends = px_per_m * FACE_MAX_SLIDE >= tol and reach
            ok = ends or (near and q_hi - q_lo >= FACE_SPREAD * other)
        if near:
            ok_near = ok
        else:
            ok_far = ok
    if near_lo:
        near_face, near_sign, far_face, far_sign = lo, 1.0, hi, -1.0
    else:
        near_face, near_sign, far_face, far_sign = hi, -1.0, lo, 1.0
    if ok_near and car:
        if end:  # stations of (height / h, set-in / size), linear between, flat beyond
            prof = OUTLINE_REAR if near_lo else OUTLINE_FRONT
        else:
            prof = OUTLINE_SIDE
        setin = size * np.interp(near_low / h, prof[0], prof[1])
        if setin > 0.0:  # a bonnet's or the glasshouse's face: the box's lies nearer
            return (near_face + near_sign * (size / 2 - setin),
                    SIGMA_FACE / SIGMA_OUTLINE[0 if end else 1], size, near_sign)
    if ok_near and ok_far:  # both ends shown: the returns measure the size too
        p_lo, p_hi = _span_below(p, ph, body_top)
        measured = p_hi - p_lo
        if (1 - SHRINK) * size <= measured <= size + grow:
            return 0.5 * (p_lo + p_hi), 1.0, measured if measure else size, 0.0
        return near_face + near_sign * size / 2, 1.0, size, near_sign
    if ok_near:
        return near_face + near_sign * size / 2, 1.0, size, near_sign
    if ok_far:
        return far_face + far_sign * size / 2, 1.0, size, far_sign
    # no face confirmed: returns lie on the surfaces facing the sensor, so the likeliest centre is
    # still half a size beyond the near extreme; a weak row
    return near_face + near_sign * size / 2, WEAK_FACE, size, near_sign


@numba.njit(cache=True, nogil=True)
def _span_below(p: np.ndarray, ph: np.ndarray, top: float) -> tuple[float, float]:
    """The extremes of p over the returns lower than `top` (ph: their heights), or over all of
    them where fewer than two are."""
    lo, hi, n = np.inf, -np.inf, 0
    for j in range(len(p)):
        if ph[j] < top:
            lo, hi, n = min(lo, p[j]), max(hi, p[j]), n + 1
    if n < 2:
        return p.min(), p.max()
    return lo, hi


@numba.njit(cache=True, nogil=True)
def _wls2(A: np.ndarray, b: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """Weighted least squares in two unknowns by the 2x2 normal equations (rows scaled by w)."""
    a11 = a12 = a22 = r1 = r2 = 0.0
    for i in range(len(b)):
        u, v, t = A[i, 0] * w[i], A[i, 1] * w[i], b[i] * w[i]
        a11 += u * u
        a12 += u * v
        a22 += v * v
        r1 += u * t
        r2 += v * t
    det = a11 * a22 - a12 * a12
    return (a22 * r1 - a12 * r2) / det, (a11 * r2 - a12 * r1) / det


@numba.njit(cache=True, nogil=True)
def translation(pxz: np.ndarray, pu: np.ndarray, ph: np.ndarray, h: float, w: float, l: float,
                ry: float, bbox: np.ndarray, sensor_xz: np.ndarray, start_xz: np.ndarray,
                P: np.ndarray, width: int, plane: np.ndarray, car: bool, up: np.ndarray,
                body_top: float = np.inf,
                measure_w: bool = True) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """Bottom-centre (x, y, z) by weighted least squares on faces, 2D sides and the road plane,
    the size (h, w, l) with l and w measured where the returns show both ends, how many of the two
    axes a confirmed face pins down, and the (x, z) direction the centre moves per metre of length
    with the anchoring face kept (zero when the returns measure the length).

    pxz, pu, ph: the object's returns (bird's-eye), their image columns and heights above the
    road; start_xz: where the centroid pull starts; car: its outline is a car's, set in above the
    bumpers (`_faces`); body_top, measure_w: where both sides show, the returns lower than
    body_top centre the box and, if measure_w, measure its width (`_faces`)."""
    ea = np.array([np.cos(ry), -np.sin(ry)])  # heading in (x, z)
    eb = np.array([np.sin(ry), np.cos(ry)])   # lateral
    ray = start_xz - sensor_xz
    ray = ray / max(np.sqrt(ray[0] * ray[0] + ray[1] * ray[1]), 1e-9)
    A = np.zeros((6, 2))
    rhs = np.zeros(6)
    wts = np.zeros(6)
    pinned = 0
    slide = np.zeros(2)
    sizes = np.array([l, w])
    for k in range(2):
        e, eo = (ea, eb) if k == 0 else (eb, ea)
        size, other, grow = (l, w, MAX_GROW_L) if k == 0 else (w, l, MAX_GROW_W)
        centre, weight, sizes[k], sl = _faces(pxz, pu, ph, e, eo, size, other, grow, sensor_xz,
                                              bbox, width, h, car, k == 0,
                                              np.inf if k == 0 else body_top,
                                              k == 0 or measure_w)
        if k == 0:
            slide = 0.5 * sl * e
        pinned += weight == 1.0
        A[2 * k] = e
        rhs[2 * k] = centre
        wts[2 * k] = weight * (0.2 + 0.8 * abs(ray[0] * e[0] + ray[1] * e[1])) / SIGMA_FACE
        A[2 * k + 1] = e  # weak pull to the returns' centroid: only matters when nothing else binds
        rhs[2 * k + 1] = start_xz[0] * e[0] + start_xz[1] * e[1]
        wts[2 * k + 1] = 1.0 / SIGMA_CENTROID
    l, w = sizes[0], sizes[1]
    x, z = _wls2(A[:4], rhs[:4], wts[:4])
    n0, n1, n2, d = plane[0], plane[1], plane[2], plane[3]
    off = _standing(h, w, l, ry, up)
    for _ in range(2):
        # the 2D sides fix the bearing, not the depth: each side's row keeps only its component
        # across the camera ray (else a few pixels of silhouette-vs-box mismatch, which the LS
        # would absorb cheaply along the ray, pull the box by a metre in depth)
        y = road_y(x, z, plane)
        norm = max(np.sqrt(x * x + z * z), 1e-9)
        r0, r1 = x / norm, z / norm
        u = corner_columns(x, y, z, h, w, l, ry, P, up)
        m = 4
        cut = cut_sides(bbox, width)
        for side in range(2):
            if cut[side]:
                continue
            us = bbox[0] if side == 0 else bbox[2]
            pick = np.argmin(u) if side == 0 else np.argmax(u)
            pr = P[0] - us * P[2]
            r_0 = pr[3] + (pr[0] * off[pick, 0] + pr[1] * off[pick, 1] + pr[2] * off[pick, 2])
            # the row in (x, y, z) with y on the road: a row in (x, z)
            a0 = pr[0] - pr[1] * n0 / n1
            a1 = pr[2] - pr[1] * n2 / n1
            b2 = -(r_0 - pr[1] * d / n1)
            along = a0 * r0 + a1 * r1
            A[m, 0] = (a0 - along * r0) / P[0, 0]
            A[m, 1] = (a1 - along * r1) / P[0, 0]
            rhs[m] = (b2 - along * (r0 * x + r1 * z)) / P[0, 0]
            wts[m] = 1.0 / SIGMA_IMAGE
            m += 1
        x, z = _wls2(A[:m], rhs[:m], wts[:m])
    return np.array([x, road_y(x, z, plane), z]), np.array([h, w, l]), pinned, slide


@numba.njit(cache=True, nogil=True)
def length_from_sides(T: np.ndarray, h: float, w: float, l: float, ry: float, slide: np.ndarray,
                      bbox: np.ndarray, P: np.ndarray, width: int, plane: np.ndarray,
                      up: np.ndarray, side_sigma: float, side_dof: float) -> tuple[np.ndarray, float]:
    """A length the returns do not measure, chosen with the 2D box: every length of LENGTH_GRID x
    the prior, the box's anchoring face kept (the centre slides by `slide` per metre); the one
    that best balances the outline's misfit to the 2D box's left and right sides (`side_cost`
    with the box's `side_sigma` and `side_dof`, `types.Box2D`) against its distance from the
    prior (SIGMA_LENGTH) wins. Seen from behind, the sides
    hardly move with the length and the prior stands; seen from the side, they decide.
    Returns the centre and the length."""
    k = len(LENGTH_GRID)
    boxes = np.empty((k, 7))
    for i in range(k):
        li = l * LENGTH_GRID[i]
        x, z = T[0] + (li - l) * slide[0], T[2] + (li - l) * slide[1]
        boxes[i] = (x, road_y(x, z, plane), z, h, w, li, ry)
    cost = (((boxes[:, 5] - l) / SIGMA_LENGTH) ** 2
            + side_cost(boxes, P, bbox, width, up, side_sigma, side_dof))
    best = np.argmin(cost)
    return boxes[best, :3].copy(), boxes[best, 5]


# the height from a 2D box's top may be this far from the fitted one (else the box says nothing)
HEIGHT_RANGE = (0.5, 1.6)


@numba.njit(cache=True, nogil=True)
def height_from_top(T: np.ndarray, dims: np.ndarray, ry: float, top: float, P: np.ndarray,
                    up: np.ndarray = CAMERA_UP) -> float:
    """The height that puts the box's projected top edge at the 2D box's top `top` (`fit`'s step 5b, `mono`).

    A 2D box that is the projection of the 3D box (KITTI's labels, `outline` "box") has its top
    at the highest-projecting of the four top corners. The box stands on its bottom centre T along
    `up` (rect frame, unit: CAMERA_UP for the label's own box, the LiDAR's z for KITTI's 2D boxes,
    `mono.box_up_of`), its footprint that of `mono.standing_corners` on that up. With the
    footprint fixed, each top corner B_k + h up reaches row `top` at one height h_k (P's row
    equation, linear in h), and the projected top reaches it at the least of them. Kept only within HEIGHT_RANGE x the current height (a 2D box
    cut at the top, or an object bigger than its box, says nothing about the height). A kernel:
    numpy spent forty microseconds a box on four corners."""
    h = dims[0]
    feet = _standing(1.0, dims[1], dims[2], ry, up)[:4] + T  # the bottom corners
    r = P[1] - top * P[2]
    rise = r[0] * up[0] + r[1] * up[1] + r[2] * up[2]
    h_new = np.inf
    for k in range(4):
        h_new = min(h_new, -(r[0] * feet[k, 0] + r[1] * feet[k, 1] + r[2] * feet[k, 2] + r[3]) / rise)
    return h_new if HEIGHT_RANGE[0] * h <= h_new <= HEIGHT_RANGE[1] * h else h


def height_from_box(T: np.ndarray, dims: np.ndarray, ry: float, bbox: np.ndarray, outline: str,
                    image_height: int, P: np.ndarray, up: np.ndarray | None = None) -> float:
    """The box's height from its 2D box where that box is the 3D box's projection (`outline`
    "box") and cut neither at the top nor at the bottom; else the height it has. `up`: the up axis
    of the box the 2D box projects (`mono.box_up_of`; None: the camera's)."""
    if outline != "box" or bbox[1] <= 1.0 or bbox[3] >= image_height - 2.0:
        return float(dims[0])
    return height_from_top(np.asarray(T, dtype=np.float64), np.asarray(dims, dtype=np.float64),
                           float(ry), float(bbox[1]), P,
                           CAMERA_UP if up is None else np.asarray(up, dtype=np.float64))
