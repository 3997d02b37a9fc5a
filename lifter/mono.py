"""Image-only lifting (003, Deep3DBox style): the translation that makes the projected 3D box fit
tightly in the 2D box.

Given the size and the orientation, each side of the 2D box is touched by one corner of the 3D box.
For a side at image column u and a corner c (object frame offset o = R·c from the bottom centre T),
`(P[0] - u·P[2]) · [o + T, 1] = 0` is linear in T; the row is the same for every corner, only the
right-hand side changes. So every corner assignment (left/right: any of 8 corners; top: a top corner;
bottom: a bottom corner, 1024 in all) is one column of right-hand sides solved through a single
pseudo-inverse; the assignment whose box projects closest to the 2D box wins.

With the road plane known, the bottom side is not touched by a box corner: the lowest point of a
vehicle in the image is where its nearest tyre meets the road, well inside the box's footprint
(`contact`: the tyres' footprint as a share of l and w). Which contact corner projects lowest depends on the
orientation, hardly on the position: it is found with the feet placed around the road point under
the bottom of the 2D box. The plane and that contact then fix the depth; the
left/right sides only place the box sideways. Letting the sides pull the depth instead turns
centimetres of predicted width or length error into a metre of depth error at 40 m.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from itertools import product

import numba
import numpy as np

from kitti.boxes import UNIT_CORNERS, box_corners, wrap_angle
from kitti.calib import Calibration

# Side is "cut by the border" when it lies within this many pixels of the image edge: its column is
# the border, not a corner of the object, so it is no constraint.
BORDER_PX = 1.0
# Row weights. A pixel row's residual is (pixel error x depth); the plane row's is metres x f.
# 1000 makes the bottom centre lie on the road to well under a millimetre; 30 lets the ground
# contact outweigh the left/right sides (whose corners move with the size and orientation errors).
PLANE_WEIGHT = 1000.0
CONTACT_WEIGHT = 30.0

# Where vehicles touch the road, as a share of the box's length and width: the tyres, inside the
# bumpers' overhang (a wheelbase of ~0.64 l and tyre outer edges at ~0.46 w, as on common cars and
# on the generator's meshes). The ground-contact row uses it; other classes touch at the corners.
CONTACT = {"Car": (0.64, 0.92), "Van": (0.64, 0.92), "Truck": (0.64, 0.92)}


def contact_of(cls: str, outline: str = "silhouette") -> tuple[float, float]:
    """Where the lowest point of a 2D box touches the road, as a share of (l, w). A silhouette's
    lowest point is a tyre's contact; a 2D box that is the projection of a 3D box (KITTI's labels:
    the labelled box stood upright in the LiDAR's frame, `box_up_of`) is bounded below by a bottom
    corner of that box."""
    return CONTACT.get(cls, (1.0, 1.0)) if outline == "silhouette" else (1.0, 1.0)


def box_up_of(outline: str, calib: Calibration) -> np.ndarray | None:
    """The up axis (rect frame) of the 3D box whose projection a 2D box is. KITTI's 2D boxes
    ("box") project the box stood upright in the LiDAR's frame (`kitti.boxes.
    lidar_upright_corners`): the LiDAR's z. A silhouette's object stands on the road: None (the
    road's normal, or the camera's up without one)."""
    if outline != "box":
        return None
    up = calib.lidar_to_rect(np.array([[0.0, 0.0, 1.0]])) - calib.lidar_to_rect(np.zeros((1, 3)))
    return up[0] / np.linalg.norm(up[0])


_ALL = np.arange(8)
_TOP = np.arange(4, 8)
_BOTTOM = np.arange(4)


@dataclass
class MonoSolution:
    location: np.ndarray  # (3,) bottom-face centre, rectified camera frame
    rotation_y: float
    box_error_px: float  # mean |projected box side - 2D box side| over the constrained sides
    cost: float = 0.0    # `solve_weighing_alpha`: its orientation's cost (box error and prior)


def ground_point(u: float, v: float, calib: Calibration, plane: np.ndarray, cam: int = 2) -> np.ndarray:
    """Where the ray through pixel (u, v) meets the road plane (rect frame); the closed-form inverse
    of 004's camera model for a known height."""
    P = calib.P(cam)
    o, p1 = _pixel_at_depth(P, u, v, 0.0), _pixel_at_depth(P, u, v, 1.0)
    d = p1 - o
    denom = d @ plane[:3]
    if abs(denom) < 1e-12:
        raise ValueError(f"pixel ({u:.1f}, {v:.1f}) looks along the road plane")
    return o - (o @ plane[:3] + plane[3]) / denom * d


@numba.njit(cache=True, nogil=True)
def _pixel_at_depth(P: np.ndarray, u: float, v: float, z: float) -> np.ndarray:
    """`Calibration.image_to_rect` of one pixel (the same arithmetic) as a kernel: numpy's version
    spends tens of microseconds on one pixel, and a fallback box asks for three."""
    a, b = P[0] - u * P[2], P[1] - v * P[2]
    ra, rb = -(a[2] * z + a[3]), -(b[2] * z + b[3])
    det = a[0] * b[1] - a[1] * b[0]
    return np.array([(ra * b[1] - a[1] * rb) / det, (a[0] * rb - ra * b[0]) / det, z])


@cache
def _grid(choices: tuple[tuple[int, ...], ...]) -> np.ndarray:
    """(K, len(choices)) every combination of one corner per constrained side, the last side's
    fastest. Cached: a handful of side sets recur (not to be written to)."""
    return np.array(list(product(*choices)), dtype=np.int64).reshape(-1, len(choices))


def _up(plane: np.ndarray) -> np.ndarray:
    n = np.asarray(plane[:3], dtype=float) / np.linalg.norm(plane[:3])
    return -n if n[1] > 0 else n  # camera y points down: up has a negative y


def standing_corners(h: float, w: float, l: float, rotation_y: float,
                     up: np.ndarray | None = None) -> np.ndarray:
    """(8, 3) corners, in kitti.boxes order, of a box standing on a surface with normal `up`
    (rect frame; None: the camera's own up, -y), relative to its bottom-face centre. Its heading
    lies in the surface with the x-z direction (cos ry, -sin ry), which is how a label gives it.
    For a camera tilted against the road (the 004 gantry) the box then stands on the road, not on
    the camera's x-z plane: the box a KITTI label describes is drawn upright in the camera frame,
    but the object it stands for is upright on the road, and that is what the image shows."""
    if up is None:
        return box_corners(np.array([[0, 0, 0, h, w, l, rotation_y]]))[0]
    return _standing(float(h), float(w), float(l), float(rotation_y), np.asarray(up, dtype=float))


@numba.njit(cache=True, nogil=True)
def _standing(h: float, w: float, l: float, rotation_y: float, up: np.ndarray) -> np.ndarray:
    """`standing_corners` on a surface: a kernel, as `_place` asks for it twice per yaw tried."""
    c, s = np.cos(rotation_y), np.sin(rotation_y)
    head = np.array([c, (up[2] * -s + up[0] * c) / -up[1], -s])  # in the surface: up . head = 0
    head /= np.sqrt(head[0] * head[0] + head[1] * head[1] + head[2] * head[2])
    side = np.array([up[1] * head[2] - up[2] * head[1], up[2] * head[0] - up[0] * head[2],
                     up[0] * head[1] - up[1] * head[0]])  # up x head
    out = np.empty((8, 3))
    for k in range(8):  # the unit corners' y runs down (0 to -1): the height goes along `up`
        for j in range(3):
            out[k, j] = (UNIT_CORNERS[k, 0] * l * head[j] - UNIT_CORNERS[k, 1] * h * up[j]
                         + UNIT_CORNERS[k, 2] * w * side[j])
    return out


@dataclass
class _Outline:
    """What a 2D box asks of any 3D box, whatever its size and yaw: the constrained sides (image
    rows, linear in the translation) with their pseudo-inverse, and the road point under the
    bottom edge. Built once per 2D box: `solve_from_alpha` re-solves it for several yaws."""

    P: np.ndarray
    image_size: tuple[int, int]
    bbox: np.ndarray           # [x1, y1, x2, y2] as floats
    up: np.ndarray | None      # the box's up: `box_up`, else the road's normal (None: neither)
    rows: np.ndarray           # (sides, 4) per constrained side, its row P[axis] - s P[2] (scaled)
    on_feet: np.ndarray        # (sides,) the side is the bottom edge: touched by a ground contact
    A_pinv: np.ndarray         # (3, k) pseudo-inverse of the sides' rows and the road's (last)
    plane_rhs: np.ndarray      # (8,) the road row's right-hand side ((0,): no road plane)
    combos: np.ndarray         # (K, k) every corner assignment (bottom column: set per yaw)
    bottom_col: int            # column of combos that is the lowest ground contact (-1: none)
    ground: np.ndarray         # road point under the bottom edge's middle (NaN: no road plane)


# Outlines already built, by their arguments: `fit` places a 2D box on the same road for each yaw
# it tries, `solve_weighing_alpha` for each orientation. Read-only once built.
_OUTLINES: dict[tuple, _Outline] = {}
_OUTLINES_KEPT = 64


def _outline(bbox: np.ndarray, calib: Calibration, image_size: tuple[int, int],
             plane: np.ndarray | None, cam: int, cut_ok: bool,
             box_up: np.ndarray | None = None) -> _Outline:
    """The yaw-independent half of `solve_translation` (its arguments are documented there),
    built once per set of arguments."""
    P = calib.P(cam)
    key = (np.asarray(bbox, dtype=float).tobytes(), P.tobytes(), tuple(image_size),
           None if plane is None else np.asarray(plane, dtype=float).tobytes(), cut_ok,
           None if box_up is None else np.asarray(box_up, dtype=float).tobytes())
    o = _OUTLINES.get(key)
    if o is None:
        if len(_OUTLINES) >= _OUTLINES_KEPT:
            _OUTLINES.clear()
        o = _OUTLINES[key] = _build_outline(bbox, calib, image_size, plane, cam, cut_ok, box_up)
    return o


def _build_outline(bbox: np.ndarray, calib: Calibration, image_size: tuple[int, int],
                   plane: np.ndarray | None, cam: int, cut_ok: bool,
                   box_up: np.ndarray | None = None) -> _Outline:
    P = calib.P(cam)
    W, H = image_size
    x1, y1, x2, y2 = (float(v) for v in bbox)
    # (axis, pixel, admissible corners, constrains?). With the road plane and a visible bottom edge,
    # the ground contact fixes the depth; the top edge would only add the predicted height's error
    # (7 % of the depth for a 0.1 m error on a car), so it is left out.
    bottom_seen = y2 < H - 1 - BORDER_PX
    lowest = _BOTTOM if plane is None else _BOTTOM[:1]  # with the plane: one contact, set per yaw
    sides = [(0, x1, _ALL, x1 > BORDER_PX), (0, x2, _ALL, x2 < W - 1 - BORDER_PX),
             (1, y1, _TOP, y1 > BORDER_PX and (plane is None or not bottom_seen)),
             (1, y2, lowest, bottom_seen)]
    if sum(side[3] for side in sides) + (plane is not None) < 3 and cut_ok:
        # cut on too many sides: take the border as the outline there (the box is then too small,
        # so the depth comes out too far; the only answer the image still gives)
        sides = [(axis, s, corner_set, True) for axis, s, corner_set, _ in sides]
    sides = [side for side in sides if side[3]]
    rows, on_feet, choices = [], [], []
    for axis, s, corner_set, _ in sides:
        r = P[axis] - s * P[2]  # (4,)
        bottom = axis == 1 and corner_set.max() < 4
        if bottom and plane is not None:
            r = r * CONTACT_WEIGHT
        rows.append(r)
        on_feet.append(bottom)
        choices.append(corner_set)
    A = [r[:3] for r in rows]
    plane_rhs, ground, bottom_col = np.zeros(0), np.full(3, np.nan), -1
    if plane is not None:
        n = np.asarray(plane, dtype=float)
        scale = PLANE_WEIGHT * P[0, 0]  # a metre of plane error ~ f pixels at 1 m
        A.append(n[:3] * scale)
        plane_rhs = np.full(8, -n[3] * scale)
        choices.append(np.zeros(1, dtype=int))
        ground = ground_point(0.5 * (x1 + x2), y2, calib, plane, cam)
        bottom_col = next((i for i, b in enumerate(on_feet) if b), -1)
    if len(A) < 3:
        raise ValueError(f"box {np.asarray(bbox).tolist()} leaves {len(A)} constraints; "
                         f"3 are needed")
    up = np.asarray(box_up, dtype=float) if box_up is not None else None if plane is None else _up(plane)
    return _Outline(P, image_size, np.array([x1, y1, x2, y2]), up,
                    np.array(rows).reshape(-1, 4), np.array(on_feet, dtype=bool),
                    np.linalg.pinv(np.array(A)), plane_rhs,
                    _grid(tuple(tuple(c.tolist()) for c in choices)), bottom_col, ground)


def _place(o: _Outline, dims: np.ndarray, rotation_y: float,
           contact: tuple[float, float]) -> MonoSolution:
    """The translation of the box (dims, yaw) whose projection best fits the outline."""
    h, w, l = (float(v) for v in dims)
    offs = standing_corners(h, w, l, rotation_y, o.up)  # (8, 3) from the bottom centre
    feet = standing_corners(h, w * contact[1], l * contact[0], rotation_y, o.up)
    T, err = _best_assignment(o.rows, o.on_feet, o.A_pinv, o.plane_rhs, o.combos, o.bottom_col,
                              o.ground, offs, feet, o.P, o.image_size[0], o.image_size[1], o.bbox)
    return MonoSolution(T, float(rotation_y), err)


@numba.njit(cache=True, nogil=True)
def _project_point(T: np.ndarray, o: np.ndarray, P: np.ndarray) -> tuple[float, float, float]:
    """Pixel (u, v) and depth of the point T + o (both (3,))."""
    x, y, z = T[0] + o[0], T[1] + o[1], T[2] + o[2]
    u = x * P[0, 0] + y * P[0, 1] + z * P[0, 2] + P[0, 3]
    v = x * P[1, 0] + y * P[1, 1] + z * P[1, 2] + P[1, 3]
    d = x * P[2, 0] + y * P[2, 1] + z * P[2, 2] + P[2, 3]
    return u / d, v / d, d


@numba.njit(cache=True, nogil=True)
def _best_assignment(rows: np.ndarray, on_feet: np.ndarray, A_pinv: np.ndarray,
                     plane_rhs: np.ndarray, combos: np.ndarray, bottom_col: int,
                     ground: np.ndarray, offs: np.ndarray, feet: np.ndarray, P: np.ndarray,
                     W: int, H: int, bbox: np.ndarray) -> tuple[np.ndarray, float]:
    """`_place`'s search: every corner assignment's translation through the pseudo-inverse, and
    the mean distance of its projected box (the contact's row at the bottom) to the 2D box; the
    best one. A kernel: numpy spent it in call overhead, several yaws per box."""
    k = A_pinv.shape[1]
    rhs = np.empty((k, 8))  # per row, the right-hand side of each corner touching its side
    for i in range(len(rows)):
        pts = feet if on_feet[i] else offs
        for c in range(8):
            rhs[i, c] = -(pts[c, 0] * rows[i, 0] + pts[c, 1] * rows[i, 1] + pts[c, 2] * rows[i, 2]
                          + rows[i, 3])
    if len(plane_rhs):
        rhs[k - 1] = plane_rhs
    lowest = -1  # which ground contact projects lowest depends on the yaw, hardly on the position:
    if bottom_col >= 0:  # the feet placed around the road point under the bottom edge decide it
        v_max = -np.inf
        for c in range(4):
            v = _project_point(ground, feet[c], P)[1]
            if v > v_max:
                v_max, lowest = v, c
    best_T, best_err = np.zeros(3), np.inf
    b, T = np.empty(k), np.empty(3)
    for m in range(len(combos)):
        for i in range(k):
            b[i] = rhs[i, lowest if i == bottom_col else combos[m, i]]
        for a in range(3):
            T[a] = 0.0
            for i in range(k):
                T[a] += A_pinv[a, i] * b[i]
        u_lo, v_lo, u_hi, foot_v = np.inf, np.inf, -np.inf, -np.inf
        ahead = True
        for c in range(8):
            u, v, z = _project_point(T, offs[c], P)
            u_lo, v_lo, u_hi = min(u_lo, u), min(v_lo, v), max(u_hi, u)
            ahead &= z > 0.1
            if c < 4:
                foot_v = max(foot_v, _project_point(T, feet[c], P)[1])
        err = (abs(min(max(u_lo, 0), W - 1) - bbox[0]) + abs(min(max(v_lo, 0), H - 1) - bbox[1])
               + abs(min(max(u_hi, 0), W - 1) - bbox[2])
               + abs(min(max(foot_v, 0), H - 1) - bbox[3])) / 4
        if m == 0 or (ahead and err < best_err):
            best_T[:] = T
            best_err = err if ahead else np.inf
    return best_T, best_err


def solve_translation(dims: np.ndarray, rotation_y: float, bbox: np.ndarray, calib: Calibration,
                      image_size: tuple[int, int], plane: np.ndarray | None = None,
                      cam: int = 2, cut_ok: bool = False,
                      contact: tuple[float, float] = (1.0, 1.0),
                      box_up: np.ndarray | None = None) -> MonoSolution:
    """Bottom-centre translation for a box of size `dims` (h, w, l) and yaw `rotation_y` whose
    projection fits `bbox` [x1, y1, x2, y2]. `plane` (a, b, c, d; rect frame) adds the constraint
    that the bottom centre lies on the road: with the bottom edge (the ground contact nearest the
    camera, at `contact` = (share of l, share of w) of the footprint) it fixes the depth (the top
    edge is then not used), and it still fixes it when the box is cut by the border.
    With `cut_ok`, a box cut on so many sides that fewer than 3 constraints remain uses its border
    sides too; without it, that is an error. `box_up` (rect frame; `box_up_of`) is the up axis of
    the box the 2D box projects, when that is not the road's normal; the box returned is the
    label's, upright in the camera frame about the same bottom centre.
    """
    return _place(_outline(bbox, calib, image_size, plane, cam, cut_ok, box_up), dims, rotation_y,
                  contact)


def solve_from_alpha(dims: np.ndarray, alpha: float, bbox: np.ndarray, calib: Calibration,
                     image_size: tuple[int, int], plane: np.ndarray | None = None, cam: int = 2,
                     iters: int = 8, tol: float = 1e-5, cut_ok: bool = False,
                     contact: tuple[float, float] = (1.0, 1.0),
                     box_up: np.ndarray | None = None) -> MonoSolution:
    """As `solve_translation`, for a local orientation alpha: rotation_y = alpha + atan2(x, z)
    depends on the translation, so start from the ray through the 2D box centre and iterate (the
    ray angle moves little with the translation: converges in a few steps)."""
    u = 0.5 * (bbox[0] + bbox[2])
    v = 0.5 * (bbox[1] + bbox[3])
    ray = _pixel_at_depth(calib.P(cam), u, v, 10.0)
    ry = float(wrap_angle(alpha + np.arctan2(ray[0], ray[2])))
    outline = _outline(bbox, calib, image_size, plane, cam, cut_ok, box_up)
    if outline.up is not None:  # on a road or a known up: the whole iteration in one kernel
        o = outline
        h, w, l = (float(v) for v in dims)
        T, ry, err = _alpha_iterations(o.rows, o.on_feet, o.A_pinv, o.plane_rhs, o.combos,
                                       o.bottom_col, o.ground, o.up, o.P, o.image_size[0],
                                       o.image_size[1], o.bbox, h, w, l, float(contact[0]),
                                       float(contact[1]), float(alpha), ry, iters, tol)
        return MonoSolution(T, ry, err)
    sol = _place(outline, dims, ry, contact)
    for _ in range(iters):
        ry_new = float(wrap_angle(alpha + np.arctan2(sol.location[0], sol.location[2])))
        if abs(wrap_angle(ry_new - ry)) < tol:
            break
        ry = ry_new
        sol = _place(outline, dims, ry, contact)
    return sol


@numba.njit(cache=True, nogil=True)
def wrap_one(a: float) -> float:
    """`kitti.boxes.wrap_angle` of one angle, inside the kernels (the same arithmetic)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


@numba.njit(cache=True, nogil=True)
def _alpha_iterations(rows, on_feet, A_pinv, plane_rhs, combos, bottom_col, ground, up, P, W, H,
                      bbox, h, w, l, contact_l, contact_w, alpha, ry, iters,
                      tol) -> tuple[np.ndarray, float, float]:
    """`solve_from_alpha`'s iteration on a road plane (`_place` for each yaw, the same arithmetic)
    as one kernel: each step cost more in calls than in arithmetic. Returns the translation, the
    yaw and the box error."""
    offs = _standing(h, w, l, ry, up)
    feet = _standing(h, w * contact_w, l * contact_l, ry, up)
    T, err = _best_assignment(rows, on_feet, A_pinv, plane_rhs, combos, bottom_col, ground, offs,
                              feet, P, W, H, bbox)
    for _ in range(iters):
        ry_new = wrap_one(alpha + np.arctan2(T[0], T[2]))
        if abs(wrap_one(ry_new - ry)) < tol:
            break
        ry = ry_new
        offs = _standing(h, w, l, ry, up)
        feet = _standing(h, w * contact_w, l * contact_l, ry, up)
        T, err = _best_assignment(rows, on_feet, A_pinv, plane_rhs, combos, bottom_col, ground,
                                  offs, feet, P, W, H, bbox)
    return T, ry, err


SIGMA_BOX_PX = 2.0                 # px, mean side error of the right box (a silhouette lies 1-3 px
                                   # inside the projected box on the testbed's cars)
SIGMA_ALPHA = np.deg2rad(6.5)      # the network's orientation error: 68th percentile on held-out cars of
                                   # generated worlds (median 3.5 deg; a tail beyond 30 deg)
_COARSE = np.deg2rad(np.arange(-30.0, 30.1, 10.0))
_FINE = np.deg2rad(np.array([-5.0, -2.5, 2.5, 5.0]))


def mono_quality(sol: MonoSolution, focal_px: float, camera_height: float = 1.65) -> float:
    """How far to trust an image-only box, in (0, 1]: its depth comes from where the 2D box's
    bottom meets the road, d^2 / (f H) metres per pixel (1 m at 34 m for KITTI's camera), and a
    box whose orientation fits the 2D box badly is less likely right."""
    d = float(np.hypot(sol.location[0], sol.location[2]))
    return 1.0 / (1.0 + d * d / (focal_px * camera_height)) / (1.0 + sol.cost)


def solve_weighing_alpha(dims: np.ndarray, alpha: float, bbox: np.ndarray, calib: Calibration,
                         image_size: tuple[int, int], plane: np.ndarray | None = None,
                         cam: int = 2, cut_ok: bool = False,
                         contact: tuple[float, float] = (1.0, 1.0),
                         box_up: np.ndarray | None = None) -> MonoSolution:
    """As `solve_from_alpha`, with the orientation weighed against the 2D box: a box's width and
    height in the image change with its orientation (1.6 px per degree for a car seen from behind
    at 30 m), so the local orientations within 30 degrees of `alpha` are tried (10 degrees apart,
    then 2.5 around the best) and the one whose box fits the 2D box best, against its distance
    from `alpha` (SIGMA_ALPHA), wins. The network's orientation on real crops is off by 10-35
    degrees at times; on the generator's it is within a few."""
    def cost(a: float) -> tuple[float, MonoSolution]:
        sol = solve_from_alpha(dims, alpha + a, bbox, calib, image_size, plane, cam,
                               cut_ok=cut_ok, contact=contact, box_up=box_up)
        return (sol.box_error_px / SIGMA_BOX_PX) ** 2 + (a / SIGMA_ALPHA) ** 2, sol

    tried = {float(a): cost(float(a)) for a in _COARSE}
    best = min(tried, key=lambda a: tried[a][0])
    for a in best + _FINE:
        tried[float(a)] = cost(float(a))
    c, sol = tried[min(tried, key=lambda a: tried[a][0])]
    sol.cost = c
    return sol
