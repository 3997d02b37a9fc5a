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
    their sides lie within 0.5-1.7 px of the labelled box's projection on the dev frames) is
    bounded below by a bottom corner of that box."""
    return CONTACT.get(cls, (1.0, 1.0)) if outline == "silhouette" else (1.0, 1.0)


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
    o, p1 = calib.image_to_rect(np.array([[u, v], [u, v]]), np.array([0.0, 1.0]), cam)
    d = p1 - o
    denom = d @ plane[:3]
    if abs(denom) < 1e-12:
        raise ValueError(f"pixel ({u:.1f}, {v:.1f}) looks along the road plane")
    return o - (o @ plane[:3] + plane[3]) / denom * d


def _grid(choices: list[np.ndarray]) -> np.ndarray:
    """(K, len(choices)) every combination of one corner per constrained side."""
    mesh = np.meshgrid(*choices, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def _project(pts: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    hom = np.einsum("...j,ij->...i", pts, P[:, :3]) + P[:, 3]
    return hom[..., :2] / hom[..., 2:3], hom[..., 2]


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
    c, s = np.cos(rotation_y), np.sin(rotation_y)
    head = np.array([c, (up[2] * -s + up[0] * c) / -up[1], -s])  # in the surface: up . head = 0
    head /= np.linalg.norm(head)
    side = np.cross(up, head)
    u = UNIT_CORNERS  # its y runs down (0 to -1): the height goes along -y, here along `up`
    return np.outer(u[:, 0] * l, head) - np.outer(u[:, 1] * h, up) + np.outer(u[:, 2] * w, side)


@dataclass
class _Outline:
    """What a 2D box asks of any 3D box, whatever its size and yaw: the constrained sides (image
    rows, linear in the translation) with their pseudo-inverse, and the road point under the
    bottom edge. Built once per 2D box: `solve_from_alpha` re-solves it for several yaws."""

    P: np.ndarray
    image_size: tuple[int, int]
    bbox: np.ndarray           # [x1, y1, x2, y2] as floats
    up: np.ndarray | None      # the road's normal (None: no road plane)
    rows: list[np.ndarray]     # per constrained side, its (4,) row P[axis] - s P[2] (scaled)
    on_feet: list[bool]        # the side is the bottom edge: touched by a ground contact
    A_pinv: np.ndarray         # (3, k) pseudo-inverse of the sides' rows and the road's (last)
    plane_rhs: np.ndarray | None  # (8,) the road row's right-hand side
    combos: np.ndarray         # (K, k) every corner assignment (bottom column: set per yaw)
    bottom_col: int | None     # column of combos that is the lowest ground contact
    ground: np.ndarray | None  # road point under the bottom edge's middle


def _outline(bbox: np.ndarray, calib: Calibration, image_size: tuple[int, int],
             plane: np.ndarray | None, cam: int, cut_ok: bool) -> _Outline:
    """The yaw-independent half of `solve_translation` (its arguments are documented there)."""
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
    plane_rhs = ground = bottom_col = None
    if plane is not None:
        n = np.asarray(plane, dtype=float)
        scale = PLANE_WEIGHT * P[0, 0]  # a metre of plane error ~ f pixels at 1 m
        A.append(n[:3] * scale)
        plane_rhs = np.full(8, -n[3] * scale)
        choices.append(np.zeros(1, dtype=int))
        ground = ground_point(0.5 * (x1 + x2), y2, calib, plane, cam)
        bottom_col = next((i for i, b in enumerate(on_feet) if b), None)
    if len(A) < 3:
        raise ValueError(f"box {np.asarray(bbox).tolist()} leaves {len(A)} constraints; "
                         f"3 are needed")
    return _Outline(P, image_size, np.array([x1, y1, x2, y2]), None if plane is None else _up(plane),
                    rows, on_feet, np.linalg.pinv(np.array(A)), plane_rhs,
                    _grid(choices), bottom_col, ground)


def _place(o: _Outline, dims: np.ndarray, rotation_y: float,
           contact: tuple[float, float]) -> MonoSolution:
    """The translation of the box (dims, yaw) whose projection best fits the outline."""
    h, w, l = (float(v) for v in dims)
    P = o.P
    W, H = o.image_size
    offs = standing_corners(h, w, l, rotation_y, o.up)  # (8, 3) from the bottom centre
    feet = standing_corners(h, w * contact[1], l * contact[0], rotation_y, o.up)
    rhs_sets = [-((feet if bottom else offs) @ r[:3] + r[3]) for r, bottom in zip(o.rows, o.on_feet)]
    if o.plane_rhs is not None:
        rhs_sets.append(o.plane_rhs)
    combos = o.combos
    if o.bottom_col is not None:
        # which ground contact projects lowest depends on the yaw, hardly on the position: the feet
        # placed around the road point under the bottom edge decide it
        v = _project(o.ground + feet[_BOTTOM], P)[0][:, 1]
        combos = combos.copy()
        combos[:, o.bottom_col] = _BOTTOM[int(np.argmax(v))]
    B = np.stack([rhs_sets[i][combos[:, i]] for i in range(len(rhs_sets))], axis=0)  # (k, K)
    T = np.einsum("ij,jk->ki", o.A_pinv, B)  # (K, 3); einsum: no BLAS threads
    uv, z = _project(T[:, None, :] + offs[None], P)  # (K, 8, 2) box corners
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    foot_v = _project(T[:, None, :] + feet[None, _BOTTOM], P)[0][..., 1].max(axis=1)  # contact row
    proj = np.stack([np.clip(lo[:, 0], 0, W - 1), np.clip(lo[:, 1], 0, H - 1),
                     np.clip(hi[:, 0], 0, W - 1), np.clip(foot_v, 0, H - 1)], axis=1)
    err = np.abs(proj - o.bbox).mean(axis=1)
    err = np.where((z > 0.1).all(axis=1), err, np.inf)
    best = int(np.argmin(err))
    return MonoSolution(T[best], float(rotation_y), float(err[best]))


def solve_translation(dims: np.ndarray, rotation_y: float, bbox: np.ndarray, calib: Calibration,
                      image_size: tuple[int, int], plane: np.ndarray | None = None,
                      cam: int = 2, cut_ok: bool = False,
                      contact: tuple[float, float] = (1.0, 1.0)) -> MonoSolution:
    """Bottom-centre translation for a box of size `dims` (h, w, l) and yaw `rotation_y` whose
    projection fits `bbox` [x1, y1, x2, y2]. `plane` (a, b, c, d; rect frame) adds the constraint
    that the bottom centre lies on the road: with the bottom edge (the ground contact nearest the
    camera, at `contact` = (share of l, share of w) of the footprint) it fixes the depth (the top
    edge is then not used), and it still fixes it when the box is cut by the border.
    With `cut_ok`, a box cut on so many sides that fewer than 3 constraints remain uses its border
    sides too; without it, that is an error.
    """
    return _place(_outline(bbox, calib, image_size, plane, cam, cut_ok), dims, rotation_y, contact)


def solve_from_alpha(dims: np.ndarray, alpha: float, bbox: np.ndarray, calib: Calibration,
                     image_size: tuple[int, int], plane: np.ndarray | None = None, cam: int = 2,
                     iters: int = 8, tol: float = 1e-5, cut_ok: bool = False,
                     contact: tuple[float, float] = (1.0, 1.0)) -> MonoSolution:
    """As `solve_translation`, for a local orientation alpha: rotation_y = alpha + atan2(x, z)
    depends on the translation, so start from the ray through the 2D box centre and iterate (the
    ray angle moves little with the translation: converges in a few steps)."""
    u = 0.5 * (bbox[0] + bbox[2])
    v = 0.5 * (bbox[1] + bbox[3])
    ray = calib.image_to_rect(np.array([[u, v]]), np.array([10.0]), cam)[0]
    ry = float(wrap_angle(alpha + np.arctan2(ray[0], ray[2])))
    outline = _outline(bbox, calib, image_size, plane, cam, cut_ok)
    sol = _place(outline, dims, ry, contact)
    for _ in range(iters):
        ry_new = float(wrap_angle(alpha + np.arctan2(sol.location[0], sol.location[2])))
        if abs(wrap_angle(ry_new - ry)) < tol:
            break
        ry = ry_new
        sol = _place(outline, dims, ry, contact)
    return sol


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
                         contact: tuple[float, float] = (1.0, 1.0)) -> MonoSolution:
    """As `solve_from_alpha`, with the orientation weighed against the 2D box: a box's width and
    height in the image change with its orientation (1.6 px per degree for a car seen from behind
    at 30 m), so the local orientations within 30 degrees of `alpha` are tried (10 degrees apart,
    then 2.5 around the best) and the one whose box fits the 2D box best, against its distance
    from `alpha` (SIGMA_ALPHA), wins. The network's orientation on real crops is off by 10-35
    degrees at times; on the generator's it is within a few."""
    def cost(a: float) -> tuple[float, MonoSolution]:
        sol = solve_from_alpha(dims, alpha + a, bbox, calib, image_size, plane, cam,
                               cut_ok=cut_ok, contact=contact)
        return (sol.box_error_px / SIGMA_BOX_PX) ** 2 + (a / SIGMA_ALPHA) ** 2, sol

    tried = {float(a): cost(float(a)) for a in _COARSE}
    best = min(tried, key=lambda a: tried[a][0])
    for a in best + _FINE:
        tried[float(a)] = cost(float(a))
    c, sol = tried[min(tried, key=lambda a: tried[a][0])]
    sol.cost = c
    return sol
