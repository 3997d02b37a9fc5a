"""Procedural actor meshes: every part a closed convex hull, every size drawn close to KITTI's.

A mesh is built from a recipe (class, h/w/l, colour, a seed for the proportions), so `meta/`
can rebuild it exactly. Parts are laid out in metres (cars) or unit-ish proportions, then the
whole actor is scaled per axis so that its extent is exactly the drawn l x w x h and its origin
is the bottom-face centre: the label box is the mesh's exact extent by construction.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np
import trimesh
from scipy.spatial import ConvexHull

# The vehicle materials at 905 nm and their sources: simgen.materials.
from .materials import (FRAME, GLASS, HEADLIGHT, PLATE, RIM, TAIL_LENS, TAILLIGHT, TRIM, TYRE, paint_material,
                        skin_reflectivity, textile_reflectivity)
from .facets import cross
from .usermesh import build_user_parts
from .world import Material, Part, fit_parts

# KITTI training-set label statistics (mean, sd) of h, w, l in metres; Bus (absent from KITTI)
# from common city-bus dimensions.
SIZE_STATS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "Car": ((1.53, 1.63, 3.88), (0.14, 0.10, 0.43)),
    "Van": ((2.21, 1.90, 5.08), (0.32, 0.14, 0.56)),
    "Truck": ((3.25, 2.59, 10.11), (0.44, 0.21, 2.60)),
    "Bus": ((3.20, 2.55, 12.0), (0.15, 0.05, 1.00)),
    "Pedestrian": ((1.76, 0.66, 0.84), (0.11, 0.14, 0.23)),
    "Cyclist": ((1.74, 0.60, 1.76), (0.09, 0.12, 0.18)),
}
# Lower bounds keep every drawn size physically buildable (a 2.5-sd draw can go below them).
_SIZE_MIN = {"Pedestrian": (1.2, 0.35, 0.3), "Cyclist": (1.3, 0.35, 1.2)}

# Vehicle paint colours (linear RGB): white, black, silver, dark grey, blue, red, green, beige.
_PAINTS = np.array([[0.85, 0.85, 0.85], [0.03, 0.03, 0.03], [0.45, 0.46, 0.48], [0.20, 0.21, 0.22],
                    [0.05, 0.12, 0.40], [0.55, 0.04, 0.03], [0.05, 0.20, 0.08], [0.55, 0.45, 0.30]])
# Vans and trucks: shares on today's roads (no survey at hand for commercial vehicles).
_PAINT_SHARE = np.array([0.24, 0.20, 0.16, 0.14, 0.09, 0.09, 0.04, 0.04])
# Cars: the German passenger-car mix KITTI drove among in Karlsruhe in 2011, when white was still
# rare. The Kraftfahrt-Bundesamt's annual report for 2006 (new registrations, as reported by dpa):
# grey and silver 42.2 %, black 27.8 %, blue 16.3 %, white 1.6 %, the other colours 12.1 %; 2006
# lies near the median registration year of a fleet about 8 years old in 2011 (KBA: a passenger
# car's mean age 8.1 years at the start of 2010, 8.5 at the start of 2012), and white reached only
# one new car in ten by 2010 (KBA, via SP-X). Grey and silver split as silver 16 : dark grey
# 14, and the other colours as red 9 : green 4 : beige 4, both as in the vans' shares above.
_CAR_PAINT_SHARE = np.array([0.016, 0.278, 0.422 * 16 / 30, 0.422 * 14 / 30, 0.163,
                             0.121 * 9 / 17, 0.121 * 4 / 17, 0.121 * 4 / 17])
_CLOTHES = np.array([[0.05, 0.05, 0.08], [0.10, 0.15, 0.35], [0.45, 0.05, 0.05], [0.35, 0.35, 0.35],
                     [0.60, 0.55, 0.45], [0.08, 0.25, 0.10], [0.70, 0.70, 0.70]])
_SKIN = np.array([[0.80, 0.60, 0.48], [0.55, 0.38, 0.27], [0.30, 0.19, 0.13]])
# Hair, natural colours from black through brown and blond to grey (linear RGB; no survey of the
# shares: drawn evenly), over the back and the top of the head; the face stays bare. Shoes black,
# brown or white. Before them a person was the same seen from in front and from behind, and a
# network could not learn which way a pedestrian faces from generated images.
_HAIR = np.array([[0.02, 0.018, 0.015], [0.06, 0.04, 0.03], [0.15, 0.10, 0.06], [0.35, 0.27, 0.17],
                  [0.40, 0.40, 0.40]])
_SHOES = np.array([[0.03, 0.03, 0.03], [0.12, 0.07, 0.04], [0.70, 0.70, 0.70]])
# A foot is 0.152 of the stature long and 0.055 broad, the ankle 0.039 high (Drillis and Contini's
# segment lengths, as tabulated in D. A. Winter, "Biomechanics and Motor Control of Human
# Movement"); the ankle stands a quarter of the foot's length in front of the heel.
FOOT = (0.152, 0.055, 0.039)
# The hairline: the hair covers the head where it lies behind HAIRLINE[0] of the head's depth in
# front of its centre, or above HAIRLINE[1] of its height over the centre (the forehead).
HAIRLINE = (0.25, 0.45)

# Car bodies. KITTI's Car class holds cars, SUVs and MPVs: the tall SUV/MPV profile from
# SUV_HEIGHT up (makers' heights: VW Tiguan 1.69 m, BMW X3 F25 1.68, VW Touran 1.63, Nissan Qashqai
# 1.61), below it a sedan, hatchback or estate (VW Golf VI 1.48, Passat B7 1.47, BMW 3 series E90
# 1.42, Opel Astra J 1.51) equally often (no survey of the shares found). Sedans and estates are
# 4.2 m and longer (Skoda Fabia Combi, about 4.25 m, the shortest estate found) and KITTI's boxes are
# shorter than makers' lengths (Car mean 3.88 m): below HATCH_ONLY_LENGTH only hatchbacks.
SUV_HEIGHT, HATCH_ONLY_LENGTH = 1.60, 3.6
CAR_STYLES = ("sedan", "hatchback", "estate")
# Proportions per style, drawn uniformly: overhangs, the windscreen's foot (cowl), the roof's and
# the glass's rear ends (shares of the length from their end); belt line and bonnet front (shares
# of the height); windscreen rake (degrees from vertical); sill height (m). Read off makers' side
# views (Golf VI, Passat B7 sedan and estate, Tiguan); no survey.
_STYLES = {
    "sedan": {"front": (0.19, 0.22), "rear": (0.21, 0.25), "cowl": (0.29, 0.33),
              "roof_end": (0.29, 0.34), "glass_end": (0.17, 0.21), "belt": (0.58, 0.63),
              "nose": (0.46, 0.52), "rake": (58.0, 63.0), "sill": (0.14, 0.18)},
    "hatchback": {"front": (0.19, 0.23), "rear": (0.15, 0.19), "cowl": (0.28, 0.32),
                  "roof_end": (0.09, 0.13), "glass_end": (0.03, 0.05), "belt": (0.58, 0.63),
                  "nose": (0.47, 0.53), "rake": (57.0, 62.0), "sill": (0.14, 0.18)},
    "estate": {"front": (0.19, 0.22), "rear": (0.19, 0.23), "cowl": (0.29, 0.33),
               "roof_end": (0.04, 0.07), "glass_end": (0.02, 0.04), "belt": (0.57, 0.62),
               "nose": (0.46, 0.52), "rake": (58.0, 63.0), "sill": (0.14, 0.18)},
    "suv": {"front": (0.18, 0.22), "rear": (0.17, 0.21), "cowl": (0.25, 0.30),
            "roof_end": (0.05, 0.08), "glass_end": (0.02, 0.04), "belt": (0.60, 0.65),
            "nose": (0.55, 0.60), "rake": (52.0, 57.0), "sill": (0.19, 0.23)},
}
# The rear overhang's floor: nothing behind a car's rear axle may reach below its departure plane
# (the plane tangent to the rear tyres at the departure angle), and a car's floor rises from the
# rear axle (over the rear suspension, the spare-wheel well, the silencer) to the back end, where
# it stands at the plane's height. Before, the underside was flat at sill height (0.14-0.23 m) from
# bumper to bumper, with the rear bumper 3 cm above it. The real car ahead in the dev frames'
# traffic jam (001206, 001497, 001966, 004587) returns no LiDAR point between 0.05 and 0.25 m on
# its rear face; the generated cars ahead did, down to 0.17 m. Makers
# rarely publish the angle for cars; EU type approval asks of an off-road M1 vehicle (M1G),
# among five of six criteria, a departure angle of at least 20 deg (87/403/EEC, carried into
# 2007/46/EC Annex II), so cars stay below it: 14-20 deg, and 18-24 deg for SUVs and MPVs, which
# stand higher (a judgement: no survey found). The bumper's top stays under the lamps (bonnet
# front less 0.17 m), so on the lowest cars with the highest rears (0.3 % of drawn cars) the rear
# cover is as little as 3 cm tall.
DEPARTURE_DEG = {"car": (14.0, 20.0), "suv": (18.0, 24.0)}
# Body width against the mirrors' span, which is the box's width: VW Golf VII 1.799 m against
# 2.027 m (maker's data).
BODY_SHARE = 1.799 / 2.027
# Tyre radii (m): 195/65 R15 and 205/55 R16 0.32 (cars), 215/65 R16 0.34 and 235/55 R18 0.36
# (SUVs); a 205 mm tread.
TYRE_RADIUS = {"car": (0.30, 0.33), "suv": (0.33, 0.37)}
TYRE_WIDTH = 0.205
# A 16-inch rim (406 mm) in a 205/55 R16 tyre (632 mm across).
RIM_SHARE = 406.0 / 632.0
# Rims stand 8 mm proud of the tyre (in unit frames 0.008 of the width): 24-bit depth over the
# camera's 0.3-400 m resolves about 1.3 mm at 80 m, so the rim never z-fights the tyre.
RIM_PROUD = 0.008
# Bumper covers: painted in the body's colour on the passenger cars of KITTI's years (VW Golf
# IV-VI, Passat B5-B7, Opel Astra G-J, BMW 3 series E46/E90, Mercedes A/B/C classes of 1997-2011;
# read off makers' photographs, no survey), the unpainted black plastic kept to a strip along
# the bottom: a valance or diffuser, its height (m) drawn per bumper.
VALANCE = (0.02, 0.08)
# EU number plates: 520 x 110 mm (DIN 74069).
PLATE_W, PLATE_H = 0.52, 0.11
ROOF = 0.05  # m: roof panel over the glass
# The rear window's sides: body-coloured C pillars seen from behind, each REAR_PILLAR of the
# glass face's width (read off makers' rear views, Golf VI and Passat B7; no survey). Without
# them the whole back of the cabin is glass, which no real car shows.
REAR_PILLAR = 0.10
# A van's rear glass, in its unit frame: bottom and top (share of the height) and half width
# (share of the body's), drawn per van. The vans of KITTI's streets (VW T4/T5 Transporter,
# Caravelle and Multivan, Mercedes Vito/Viano and Sprinter, Ford Transit; read off makers' rear
# views, no survey) show a glazed tailgate or glazed rear doors from the waist to just under the
# roof, the width of the body less its D pillars. Without it the front was a van's only glass,
# and the size/orientation network read real vans seen from behind as seen from in front.
VAN_REAR_GLASS = ((0.56, 0.62), (0.84, 0.90), (0.72, 0.86))

# A car's rear lamp cluster (stop, rear position and direction-indicator lamps and the red reflex
# reflector behind one lens): UN ECE R48 asks the rear position lamps to be seen from 80 deg
# outboard of straight behind, which a lens on the back face alone cannot give, so the clusters
# wrap round the body's corner onto its side; their outer edges lie within 400 mm of the body's
# (R48). The lens reaches 0.40 m in from the body's edge, or less on a narrow body: the inner
# edges of the two stop lamps stand at least 600 mm apart (R48, STOP_LAMP_GAP). It wraps 0.10 m
# along the side and stands 0.06-0.26 m below the deck (a lens 0.20 m high; shapes read off makers'
# rear views, no survey).
TAIL_LAMP_INNER, TAIL_LAMP_WRAP, TAIL_LAMP_Z, STOP_LAMP_GAP = 0.40, 0.10, (0.26, 0.06), 0.60
# A car body's four vertical corners are cut at 45 degrees by this much in plan (_chamfered).
PLAN_CHAMFER = 0.12

# The emissive look of lamp materials at night (renderer): name -> linear RGB emission.
EMISSIVE = {"headlight": (4.0, 4.0, 3.6), "taillight": (2.5, 0.05, 0.05)}


def paint(color) -> Material:
    """Car paint: Lambertian, its 905 nm reflectance from the colour (simgen.materials: carbon
    black darkens the NIR too, chromatic pigments do not; black about 0.07, white about 0.73)."""
    return paint_material("paint", color)


class Shape(NamedTuple):
    """A part's vertices and faces before fit_parts: the builders pass plain arrays, and only
    fit_parts makes the trimesh (whose constructor costs more than most of these shapes)."""

    vertices: np.ndarray
    faces: np.ndarray


def _trimesh(shape: Shape) -> trimesh.Trimesh:
    return trimesh.Trimesh(shape.vertices, shape.faces, process=False)


def hull(points) -> Shape:
    """Closed convex hull of a point set, faces wound outward: watertight by construction.

    qhull directly (trimesh's wrapper re-processes the mesh, 5x slower for these small hulls),
    its faces turned and renumbered by a compiled loop (_outward)."""
    pts = np.asarray(points, dtype=float)
    return Shape(*_outward(pts, ConvexHull(pts).simplices))


@numba.njit(cache=True, nogil=True)
def _outward(pts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The hull's points and its faces turned outward, renumbered onto those points: a face
    turns where its normal (np.cross's products and differences) points away from the way from
    the points' mean to the face's centre. The means add in numpy's order (0, then each in turn)
    and the dot product in np.einsum's ((x z) then y), so every face turns as numpy turned it."""
    n = pts.shape[0]
    used = np.zeros(n, np.bool_)
    for f in faces.ravel():
        used[f] = True
    rank = np.cumsum(used) - 1
    mean = np.zeros(3)
    for i in range(n):
        if used[i]:
            for k in range(3):
                mean[k] += pts[i, k]
    mean /= rank[-1] + 1
    out = np.empty((faces.shape[0], 3), np.int64)
    for t in range(faces.shape[0]):
        a, b, c = pts[faces[t, 0]], pts[faces[t, 1]], pts[faces[t, 2]]
        u0, u1, u2, w0, w1, w2 = b[0] - a[0], b[1] - a[1], b[2] - a[2], c[0] - a[0], c[1] - a[1], c[2] - a[2]
        d0 = (0.0 + a[0] + b[0] + c[0]) / 3 - mean[0]
        d1 = (0.0 + a[1] + b[1] + c[1]) / 3 - mean[1]
        d2 = (0.0 + a[2] + b[2] + c[2]) / 3 - mean[2]
        dot = (u1 * w2 - u2 * w1) * d0 + (u0 * w1 - u1 * w0) * d2 + (u2 * w0 - u0 * w2) * d1
        for j in range(3):
            out[t, j] = rank[faces[t, 2 - j] if dot < 0 else faces[t, j]]
    return pts[used], out


_BOX_FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                       [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])


def box(x0, x1, y0, y1, z0, z1) -> trimesh.Trimesh:
    """Axis-aligned box from its bounds (either order), faces wound outward."""
    return _trimesh(_box(x0, x1, y0, y1, z0, z1))


# Each corner of box() as indices into its sorted bounds (x0, x1, y0, y1, z0, z1).
_BOX_CORNERS = np.array([[0, 2, 4], [1, 2, 4], [1, 3, 4], [0, 3, 4], [0, 2, 5], [1, 2, 5], [1, 3, 5], [0, 3, 5]])


def _box(x0, x1, y0, y1, z0, z1) -> Shape:
    """box() as a Shape: its corners gathered from the bounds in one call (a nested list of 24
    floats costs numpy several times more)."""
    bounds = np.array([*sorted((x0, x1)), *sorted((y0, y1)), *sorted((z0, z1))], dtype=float)
    return Shape(bounds[_BOX_CORNERS], _BOX_FACES)


def prism_xz(profile, y0, y1) -> Shape:
    """A convex side profile (x, z) swept across y in [y0, y1]."""
    p = np.asarray(profile, dtype=float)
    return hull(np.concatenate([np.c_[p[:, 0], np.full(len(p), y0), p[:, 1]],
                                np.c_[p[:, 0], np.full(len(p), y1), p[:, 1]]]))


def _solid(v, faces) -> Shape:
    """A closed convex solid from known faces, turned outward: qhull (hull) costs 20x more, and
    cylinders and hexahedra with planar faces need none."""
    v, faces = np.asarray(v, dtype=float), np.asarray(faces)
    if _looks_inward(v, faces[0]):
        faces = faces[:, ::-1]
    return Shape(v, faces)


def _looks_inward(v: np.ndarray, face: np.ndarray) -> bool:
    """Whether `face` turns towards the solid's vertex mean: the sign of det [b - a, c - a,
    a - mean]. The triple product (compiled, _triple) decides; only where it is too close to 0
    for its sign to be sure does np.linalg.det, as before, decide."""
    det, size, *rows = _triple(v, face[0], face[1], face[2])
    if abs(det) > 1e-9 * size:
        return det < 0
    return bool(np.linalg.det(np.reshape(rows, (3, 3))) < 0)


@numba.njit(cache=True, nogil=True)
def _triple(v: np.ndarray, i: int, j: int, k: int) -> tuple[float, ...]:
    """det [b - a, c - a, a - mean] of the face (i, j, k) in plain floats, the size its error
    scales with, and the three rows' nine entries (floats only: an array made here costs more
    than the rest). The mean adds the vertices in turn to 0, as numpy's v.mean(axis=0) does."""
    m0 = m1 = m2 = 0.0
    for r in range(v.shape[0]):
        m0, m1, m2 = m0 + v[r, 0], m1 + v[r, 1], m2 + v[r, 2]
    n = v.shape[0]
    m0, m1, m2 = m0 / n, m1 / n, m2 / n
    a0, a1, a2 = v[i, 0], v[i, 1], v[i, 2]
    u0, u1, u2 = v[j, 0] - a0, v[j, 1] - a1, v[j, 2] - a2
    w0, w1, w2 = v[k, 0] - a0, v[k, 1] - a1, v[k, 2] - a2
    z0, z1, z2 = a0 - m0, a1 - m1, a2 - m2
    det = u0 * (w1 * z2 - w2 * z1) - u1 * (w0 * z2 - w2 * z0) + u2 * (w0 * z1 - w1 * z0)
    size = (abs(u0) + abs(u1) + abs(u2)) * (abs(w0) + abs(w1) + abs(w2)) * (abs(z0) + abs(z1) + abs(z2))
    return det, size, u0, u1, u2, w0, w1, w2, z0, z1, z2


def hexahedron(v) -> Shape:
    """Eight corners in box() order (bottom x0y0, x1y0, x1y1, x0y1, then the top) of a solid whose
    faces are planar, e.g. a box sheared or tapered: convex by construction."""
    return _solid(v, _BOX_FACES)


@functools.cache
def _prism_faces(n: int) -> np.ndarray:
    """Faces of a prism over an n-gon: vertices 0..n-1 one end, n..2n-1 the other."""
    i = np.arange(n)
    j = (i + 1) % n
    return np.concatenate([np.c_[i, j, n + j], np.c_[i, n + j, n + i],
                           np.c_[np.zeros(n - 2, int), i[2:], i[1:-1]],
                           np.c_[np.full(n - 2, n), n + i[1:-1], n + i[2:]]])


def extrude(outline, axis: int, lo: float, hi: float) -> trimesh.Trimesh:
    """A convex outline (corners in order round it, in the other two axes in their order)
    extruded along `axis` from lo to hi."""
    return _trimesh(_extrude(outline, axis, lo, hi))


def _extrude(outline, axis: int, lo: float, hi: float) -> Shape:
    """extrude() as a Shape."""
    outline = np.asarray(outline, dtype=float)
    n = len(outline)
    v = np.empty((2, n, 3))
    v[:, :, [a for a in range(3) if a != axis]] = outline
    v[0, :, axis], v[1, :, axis] = lo, hi
    return _solid(v.reshape(-1, 3), _prism_faces(n))


@functools.cache
def _circle(sections: int) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of `sections` angles evenly round the circle (the same for every wheel)."""
    a = 2 * np.pi * np.arange(sections) / sections
    return np.cos(a), np.sin(a)


def _cylinder_y(x, y, z, rx, rz, width, sections) -> Shape:
    """A closed elliptic cylinder, axis along y, centred at (x, y, z)."""
    return _solid(_cylinder_vertices(x, y, z, rx, rz, width, *_circle(sections)), _prism_faces(sections))


@numba.njit(cache=True, nogil=True)
def _cylinder_vertices(x: float, y: float, z: float, rx: float, rz: float, width: float, cos: np.ndarray,
                       sin: np.ndarray) -> np.ndarray:
    """_cylinder_y's rings at y -+ width / 2 (x + rx cos, z + rz sin round each), compiled: a
    frame's hundreds of wheels and rims paid numpy's per call cost several times over."""
    n = len(cos)
    v = np.empty((2 * n, 3))
    for i in range(n):
        v[i, 0] = v[n + i, 0] = x + rx * cos[i]
        v[i, 1], v[n + i, 1] = y - width / 2, y + width / 2
        v[i, 2] = v[n + i, 2] = z + rz * sin[i]
    return v


def wheel(x, y, r, width, sections=14, rx=None) -> Shape:
    """A closed cylinder of radius r, axis along y, standing on z = 0 at (x, y). In a frame that
    fit_parts scales unevenly, rx = r h / l keeps it round after the scaling."""
    return _cylinder_y(x, y, r, r if rx is None else rx, r, width, sections)


def spoked_wheel(x, y, r, width, thickness, sections=16) -> list[Shape]:
    """A bicycle wheel as the camera and the LiDAR see it, standing on z = 0 at (x, y), axis along
    y: its tyre and rim, a ring `thickness` deep inside radius r, as `sections` convex segments
    (a solid disc hides what lies behind the spokes; an actor's parts must each be convex)."""
    a = 2.0 * np.pi * np.arange(sections + 1) / sections
    out = []
    for a0, a1 in zip(a[:-1], a[1:]):
        ring = [(x + rr * np.cos(t), r + rr * np.sin(t)) for rr, t in
                ((r - thickness, a0), (r, a0), (r, a1), (r - thickness, a1))]
        out.append(hexahedron([(px, yy, pz) for yy in (y - width / 2, y + width / 2) for px, pz in ring]))
    return out


def rim(x, face, r, out, sections=8, rx=None) -> Shape:
    """The rim of a tyre of radius r standing at x, on its outer face (at y = face, outward sign
    `out`): RIM_SHARE of the tyre's radius, standing RIM_PROUD proud of the face so it reads."""
    rr, rrx = RIM_SHARE * r, RIM_SHARE * (r if rx is None else rx)
    return _cylinder_y(x, face + out * RIM_PROUD / 2, r, rrx, rr, RIM_PROUD, sections)


# SIZE_STATS and the paint shares as the samplers use them, made once (per draw they cost more
# than the draws).
_SIZE_ARRAYS = {cls: (np.array(mean), np.array(sd)) for cls, (mean, sd) in SIZE_STATS.items()}
_CAR_PAINT_P, _PAINT_P = _CAR_PAINT_SHARE / _CAR_PAINT_SHARE.sum(), _PAINT_SHARE / _PAINT_SHARE.sum()


def sample_size(cls: str, rng: np.random.Generator) -> tuple[float, float, float]:
    """(h, w, l) from a normal truncated at 2.5 sd, correlated through one shared 'scale' draw."""
    mean, sd = _SIZE_ARRAYS[cls]
    common = rng.standard_normal()
    z = np.clip(0.6 * common + 0.8 * rng.standard_normal(3), -2.5, 2.5)
    hwl = mean + z * sd
    hwl = np.maximum(hwl, _SIZE_MIN.get(cls, 0.5 * mean))
    return tuple(round(float(v), 4) for v in hwl)


def sample_recipe(cls: str, rng: np.random.Generator) -> dict:
    """A mesh recipe: everything build_actor_parts needs, JSON-able."""
    h, w, l = sample_size(cls, rng)
    if cls in ("Pedestrian", "Cyclist"):
        color = _CLOTHES[rng.integers(len(_CLOTHES))]
    else:
        color = _PAINTS[rng.choice(len(_PAINTS), p=_CAR_PAINT_P if cls == "Car" else _PAINT_P)]
    color = np.clip(color * rng.uniform(0.85, 1.15), 0.0, 1.0)
    return {"kind": cls.lower(), "dims": [h, w, l], "color": [round(float(c), 4) for c in color],
            "seed": int(rng.integers(2**31))}


def _chamfered(profile, half_w: float, c: float) -> Shape:
    """A convex side profile (x, z) swept across |y| <= half_w, its four vertical edges cut by c at
    45 degrees: a body's plan view is rounded at the corners."""
    p = np.asarray(profile, dtype=float)
    x = np.clip(p[:, 0], p[:, 0].min() + c, p[:, 0].max() - c)
    n = len(p)
    pts = np.empty((4, n, 3))
    pts[:2, :, 0], pts[2:, :, 0] = x, p[:, 0]
    pts[:, :, 1] = np.array([half_w, -half_w, half_w - c, c - half_w])[:, None]
    pts[:, :, 2] = p[:, 1]
    return hull(pts.reshape(-1, 3))


def _on_side(s: int, belt: tuple, top: tuple, yb: float, yt: float, zb: float, zt: float):
    """A pillar on the cabin's side s (+1 left): the band [belt] at the belt line and [top] at the
    roof, on the side's slanted plane, standing 12 mm proud of the glass."""
    n = np.array([0.0, s * (zt - zb), yb - yt])
    n0, n1, n2 = (n / np.linalg.norm(n)).tolist()
    quad = ((belt[0], s * yb, zb), (belt[1], s * yb, zb), (top[1], s * yt, zt), (top[0], s * yt, zt))
    return hexahedron([(x - 0.005 * n0, y - 0.005 * n1, z - 0.005 * n2) for x, y, z in quad]
                      + [(x + 0.012 * n0, y + 0.012 * n1, z + 0.012 * n2) for x, y, z in quad])


def _mirror(s: int, x: float, inner: float, outer: float, z: float) -> Shape:
    """A door mirror on side s just behind x (the windscreen's foot) at the belt line z, from the
    body (inner) out to the box's side (outer), its housing larger at the outer end."""
    root = [(x - 0.16, z + 0.02), (x - 0.06, z + 0.02), (x - 0.06, z + 0.10), (x - 0.16, z + 0.10)]
    head = [(x - 0.20, z + 0.01), (x - 0.06, z + 0.01), (x - 0.06, z + 0.15), (x - 0.20, z + 0.15)]
    return hexahedron([[root[i][0], s * inner, root[i][1]] for i in (0, 1)] +
                      [[head[i][0], s * outer, head[i][1]] for i in (1, 0)] +
                      [[root[i][0], s * inner, root[i][1]] for i in (3, 2)] +
                      [[head[i][0], s * outer, head[i][1]] for i in (2, 3)])


def _car_style(rng, h: float, l: float) -> str:
    """SUV/MPV from SUV_HEIGHT up, hatchbacks only below HATCH_ONLY_LENGTH, else any of three."""
    if h >= SUV_HEIGHT:
        return "suv"
    if l < HATCH_ONLY_LENGTH:
        return "hatchback"
    return CAR_STYLES[int(rng.integers(len(CAR_STYLES)))]


@dataclass(frozen=True)
class _CarLayout:
    """A car's stations in metres: x forward from the box centre, y left, z up from the ground.
    The centimetre offsets in the car's builders only say which face stands proud of which."""

    style: str
    h: float
    body: float  # half width of the body; the mirrors reach the box's half width `wing`
    wing: float
    r: float  # tyre radius
    front: float  # body faces, behind the bumpers
    back: float
    axles: tuple[float, float]
    sill: float
    tail: float  # the floor's height at the back end: the departure plane's there, or the sill
    departure: float  # radians (DEPARTURE_DEG)
    belt: float
    nose: float  # bonnet front
    deck: float  # the body's top behind the glass (sedans: the boot lid, a little lower)
    cowl: float  # windscreen foot
    glass_end: float  # the glass's rear foot
    roof: tuple[float, float]  # roof front and rear ends


def _car_layout(rng, dims) -> _CarLayout:
    """Stations drawn from the style's proportions. Tyres at most 0.24 h (below the belt line of
    the lowest cars); each axle at least a tyre plus 0.15-0.25 m from the box's ends."""
    h, w, l = dims
    style = _car_style(rng, h, l)
    p = {k: rng.uniform(*v) for k, v in _STYLES[style].items()}
    r = min(rng.uniform(*TYRE_RADIUS["suv" if style == "suv" else "car"]), 0.24 * h)
    belt, top = p["belt"] * h, h - ROOF
    cowl, roof_r = l / 2 - p["cowl"] * l, -l / 2 + p["roof_end"] * l
    roof_f = min(max(cowl - (top - belt) * np.tan(np.radians(p["rake"])), roof_r + 0.25 * l), cowl - 0.1)
    axles = (l / 2 - max(p["front"] * l, r + 0.25), -l / 2 + max(p["rear"] * l, r + 0.15))
    back = -l / 2 + 0.02
    departure = np.radians(rng.uniform(*DEPARTURE_DEG["suv" if style == "suv" else "car"]))
    tail = max(p["sill"], _departure_height(axles[1] - back, r, departure))
    return _CarLayout(style, h, BODY_SHARE * w / 2, w / 2, r, l / 2 - 0.03, back, axles, p["sill"], tail,
                      departure, belt, p["nose"] * h, belt - 0.04 if style == "sedan" else belt, cowl,
                      -l / 2 + p["glass_end"] * l, (roof_f, roof_r))


def _departure_height(d: float, r: float, angle: float) -> float:
    """Height at d behind the axle of the plane tangent to a tyre of radius r at `angle`: it
    touches the tyre d = r sin(angle) behind the axle, r (1 - cos(angle)) up."""
    return r * (1.0 - np.cos(angle)) + (d - r * np.sin(angle)) * np.tan(angle)


def _car(rng, c: Material, dims) -> list[Part]:
    """A car built in metres (fit_parts then makes its extent exact): a body rounded at the
    corners, its floor rising behind the rear axle (DEPARTURE_DEG), a glass cabin with pillars
    under a roof, painted bumpers over black valances, black sills and grille, mirrors (the box's
    width), round tyres with rims, lamps and plates."""
    k = _car_layout(rng, dims)
    return _car_body(rng, k, c) + _car_ends(rng, k, dims[2], c) + _car_sides(k, c)


def _car_body(rng, k: _CarLayout, c: Material) -> list[Part]:
    """The lower body (chamfered in plan), the glass cabin, its pillars and the roof."""
    lower = _chamfered([[k.front - 0.04, k.sill], [k.front, k.sill + 0.08], [k.front, k.nose - 0.10],
                        [k.front - 0.12, k.nose], [k.cowl, k.belt], [k.glass_end, k.belt],
                        [k.back + 0.06, k.deck], [k.back, k.deck - 0.06], [k.back, k.tail + 0.08],
                        [k.back + 0.04, k.tail], *_underside(k)], k.body, PLAN_CHAMFER)
    (roof_f, roof_r), top = k.roof, k.h - ROOF
    yb, yt, zb = k.body - 0.03, k.body * rng.uniform(0.76, 0.82), k.belt - 0.02
    cabin = hexahedron([[k.cowl, -yb, zb], [k.glass_end, -yb, zb], [k.glass_end, yb, zb], [k.cowl, yb, zb],
                        [roof_f, -yt, top], [roof_r, -yt, top], [roof_r, yt, top], [roof_f, yt, top]])
    roof = _box(roof_r - 0.01, roof_f + 0.01, -yt - 0.01, yt + 0.01, top - 0.01, k.h)
    pillars = [_on_side(s, *band, yb, yt, zb, top) for s in (-1, 1)
               for band in _pillars(rng, k.style, k.cowl, k.glass_end, roof_f, roof_r)]
    rear = np.array([[k.glass_end, yb, zb], [k.glass_end, -yb, zb], [roof_r, -yt, top], [roof_r, yt, top]])
    return [Part(lower, c), Part(cabin, GLASS), Part(roof, c),
            *[Part(m, c) for m in pillars + _rear_pillars(rear, REAR_PILLAR)]]


def _underside(k: _CarLayout) -> list[list[float]]:
    """The side profile's corner where the floor leaves the sill's level, rising to the back end:
    at the rear axle (none where the departure plane stays under the sill)."""
    return [[k.axles[1], k.sill]] if k.tail > k.sill else []


def _rear_pillars(quad: np.ndarray, share: float) -> list[Shape]:
    """Bands up both sides of the rear glass face (its corners: bottom two, then the top two
    above them, counter-clockwise seen from behind), `share` of its width each, on the face's
    plane and standing 12 mm proud of the glass: a convex slab each, as every part is."""
    b0, b1, t1, t0 = quad
    n = cross(b1 - b0, t0 - b0)
    n /= np.linalg.norm(n)
    bands = [np.array([b0, b0 + share * (b1 - b0), t0 + share * (t1 - t0), t0]),
             np.array([b1 - share * (b1 - b0), b1, t1, t1 - share * (t1 - t0)])]
    return [hexahedron(np.concatenate([q - 0.005 * n, q + 0.012 * n])) for q in bands]


def _car_ends(rng, k: _CarLayout, l: float, paint: Material) -> list[Part]:
    """Bumpers wrapping 0.27 m round the sides, painted in the body's colour above a black
    valance (VALANCE), the plates (the front one on the bumper, the rear one above it), the
    grille, head and tail lamps."""
    bottoms = (k.sill + 0.03, k.tail + 0.03)  # front, rear: the rear on the departure plane
    tops = [min(z0 + rng.uniform(0.20, 0.28), k.nose - 0.17) for z0 in bottoms]
    valances = rng.uniform(*VALANCE, 2)
    parts = []
    hw, c = k.body + 0.005, 0.13
    for x_end, sgn, z0, z1, v in ((l / 2, 1.0, bottoms[0], tops[0], valances[0]),
                                  (-l / 2, -1.0, bottoms[1], tops[1], valances[1])):
        x = x_end - sgn * np.array([0.0, 0.0, c, 0.40 - c, 0.40, 0.40, 0.40 - c, c])
        plan = np.column_stack((x, [c - hw, hw - c, hw, hw, hw - c, c - hw, -hw, -hw]))
        pz = (z0 + z1) / 2 if sgn > 0 else z1 + 0.03 + PLATE_H / 2
        px = x_end - 0.001 if sgn > 0 else k.back
        valance = _box(x_end, x_end - sgn * 0.40, c - hw, hw - c, z0, z0 + v)  # inside the corners
        parts += [Part(valance, TRIM), Part(_extrude(plan, 2, z0 + v, z1), paint),
                  Part(_box(px - 0.005, px + 0.005, -PLATE_W / 2, PLATE_W / 2,
                            pz - PLATE_H / 2, pz + PLATE_H / 2), PLATE)]
    parts.append(Part(_box(k.front - 0.02, k.front + 0.006, 0.44 - k.body, k.body - 0.44, tops[0] - 0.01,
                          k.nose - 0.12), TRIM))
    for s in (-1, 1):
        y = sorted((s * (k.body - 0.42), s * (k.body - 0.14)))
        parts += [Part(_box(k.front - 0.02, k.front + 0.01, *y, k.nose - 0.15, k.nose - 0.05), HEADLIGHT),
                  *[Part(m, mat) for m, mat in zip(_tail_lamp(k, s), (TAILLIGHT, TAIL_LENS, TAIL_LENS))]]
    return parts


def _tail_lamp(k: _CarLayout, s: float) -> list[Shape]:
    """One rear lamp cluster, on side s: a face on the back from TAIL_LAMP_INNER of the body's edge
    (at most, STOP_LAMP_GAP apart) out to the plan chamfer, round the chamfer and TAIL_LAMP_WRAP
    along the body side, each piece 12 mm proud of the body and 20 mm into it, TAIL_LAMP_Z below
    the deck."""
    z0, z1 = (k.deck - z for z in TAIL_LAMP_Z)
    c, e = PLAN_CHAMFER, k.body
    inner = max(e - TAIL_LAMP_INNER, STOP_LAMP_GAP / 2)
    back = _box(k.back - 0.012, k.back + 0.02, *sorted((s * inner, s * (e - c))), z0, z1)
    a, b = np.array([k.back, s * (e - c)]), np.array([k.back + c, s * e])  # the chamfer's ends
    n = np.array([-1.0, s]) / np.sqrt(2.0)  # its outward normal
    ring = [a - 0.02 * n, b - 0.02 * n, b + 0.012 * n, a + 0.012 * n]
    chamfer = hexahedron([[*q, z] for z in (z0, z1) for q in ring])
    side = _box(k.back + c, k.back + c + TAIL_LAMP_WRAP, s * (e - 0.02), s * (e + 0.012), z0, z1)
    return [back, chamfer, side]


def _car_sides(k: _CarLayout, c: Material) -> list[Part]:
    """Sills between the wheels, mirrors, tyres whose outer faces stand just proud of the body
    side, rims on them."""
    (ax_f, ax_r), r = k.axles, k.r
    parts = []
    for s in (-1, 1):
        face = s * (k.body + 0.006)
        parts += [Part(_box(ax_r + r + 0.04, ax_f - r - 0.04, s * (k.body - 0.05), s * (k.body + 0.004),
                           k.sill, k.sill + 0.09), TRIM),
                  Part(_mirror(s, k.cowl, k.body - 0.04, k.wing, k.belt), c)]
        for ax in (ax_f, ax_r):
            parts += [Part(wheel(ax, face - s * TYRE_WIDTH / 2, r, TYRE_WIDTH, 12), TYRE),
                      Part(rim(ax, face, r, s), RIM)]
    return parts


def _pillars(rng, style: str, cowl: float, glass_r: float, roof_f: float, roof_r: float):
    """(belt band, roof band) of the B pillar and the rear pillars: a broad C pillar on sedans and
    hatchbacks, a C and a slim D pillar on estates and SUVs."""
    span = cowl - glass_r
    xb = cowl - rng.uniform(0.40, 0.46) * span
    tb = float(np.clip(xb + 0.05, roof_r + 0.1, roof_f - 0.1))
    bands = [((xb - 0.10, xb), (tb - 0.08, tb))]
    if style in ("sedan", "hatchback"):
        wb, wt = (rng.uniform(0.35, 0.50), rng.uniform(0.10, 0.18)) if style == "sedan" else (
            rng.uniform(0.45, 0.65), rng.uniform(0.20, 0.30))
        return bands + [((glass_r, glass_r + wb), (roof_r, roof_r + wt))]
    xc = cowl - rng.uniform(0.68, 0.74) * span
    tc = float(np.clip(xc, roof_r + 0.3, roof_f - 0.3))
    return bands + [((xc - 0.10, xc), (tc - 0.10, tc)), ((glass_r, glass_r + 0.16), (roof_r, roof_r + 0.12))]


def _wheels(xs, half: float, r: float, width: float, rx: float) -> list[Part]:
    """Tyres at x in xs whose outer faces stand just proud of the sides at +-half, rims on them
    (unit frames: rx = r h / l keeps them round)."""
    parts = []
    for s in (-1, 1):
        face = s * (half + 0.006)
        for x in xs:
            parts += [Part(wheel(x, face - s * width / 2, r, width, 12, rx), TYRE),
                      Part(rim(x, face, r, s, rx=rx), RIM)]
    return parts


def _van(rng, c: Material, dims) -> list[Part]:
    """A van in a unit frame: mirrors span the box's width, as on the car."""
    h, _, l = dims
    b = BODY_SHARE / 2
    nose = rng.uniform(0.28, 0.36)
    body = prism_xz([[0.5, 0.14], [0.5, 0.45], [nose, 0.52], [-0.5, 0.52], [-0.5, 0.14]], -b, b)
    upper = _box(-0.5, nose - 0.10, -b, b, 0.50, 1.0)
    shield = hull([[nose, 0.04 - b, 0.52], [nose, b - 0.04, 0.52], [nose - 0.10, 0.04 - b, 0.50],
                   [nose - 0.10, b - 0.04, 0.50], [nose - 0.10, 0.06 - b, 0.86],
                   [nose - 0.10, b - 0.06, 0.86]])
    side_windows = [_box(-0.15, nose - 0.11, s * b - 0.005, s * b + 0.005, 0.60, 0.82) for s in (-1, 1)]
    (z0, z1), (z2, z3), (y0, y1) = VAN_REAR_GLASS
    half = b * rng.uniform(y0, y1)
    rear_glass = _box(-0.505, -0.495, -half, half, rng.uniform(z0, z1), rng.uniform(z2, z3))
    r = 0.16
    return [Part(body, c), Part(upper, c), Part(shield, GLASS), Part(rear_glass, GLASS),
            *[Part(m, GLASS) for m in side_windows], *_wheels((0.32, -0.32), b, r, 0.11, r * h / l),
            *[Part(_box(sgn * 0.47, sgn * 0.503, -b - 0.004, b + 0.004, 0.10, 0.25), TRIM)
              for sgn in (-1, 1)],  # bumpers
            *[Part(_box(nose - 0.16, nose - 0.11, s * (b - 0.02), s * 0.5, 0.55, 0.68), TRIM)
              for s in (-1, 1)],  # mirrors
            Part(_box(0.503, 0.509, -0.11, 0.11, 0.14, 0.21), PLATE),
            Part(_box(-0.509, -0.503, -0.11, 0.11, 0.14, 0.21), PLATE),
            *[Part(_box(0.49, 0.503, s * 0.30, s * 0.42, 0.38, 0.44), HEADLIGHT) for s in (-1, 1)],
            *[Part(_box(-0.503, -0.49, s * 0.32, s * 0.42, 0.30, 0.45), TAILLIGHT)
              for s in (-1, 1)]]


def _truck(rng, c: Material, dims) -> list[Part]:
    h, _, l = dims
    cab_len = rng.uniform(0.17, 0.24)
    front = 0.5
    cab = _box(front - cab_len, front, -0.5, 0.5, 0.12, 0.92)
    shield = _box(front - 0.004, front + 0.004, -0.44, 0.44, 0.60, 0.86)
    cargo_color = paint(rng.uniform(0.5, 0.95, 3))
    cargo = _box(-0.5, front - cab_len - 0.02, -0.5, 0.5, 0.14, 1.0)
    chassis = _box(-0.48, front - 0.02, -0.35, 0.35, 0.08, 0.16)
    r = 0.15  # 315/80 R22.5 tyres: 0.54 m, 0.16 of a 3.25 m truck
    xs = (front - cab_len * 0.5, -0.28, -0.38)
    return [Part(cab, c), Part(shield, GLASS), Part(cargo, cargo_color), Part(chassis, FRAME),
            *_wheels(xs, 0.5, r, 0.10, r * h / l),
            Part(_box(0.5, 0.503, -0.08, 0.08, 0.15, 0.20), PLATE),
            *[Part(_box(0.5, 0.503, s * 0.30, s * 0.45, 0.22, 0.28), HEADLIGHT) for s in (-1, 1)],
            *[Part(_box(-0.503, -0.5, s * 0.30, s * 0.45, 0.16, 0.22), TAILLIGHT)
              for s in (-1, 1)]]


def _bus(rng, c: Material, dims) -> list[Part]:
    h, _, l = dims
    body = _box(-0.5, 0.5, -0.5, 0.5, 0.10, 1.0)
    band = [_box(-0.45, 0.42, s * 0.5 - 0.004, s * 0.5 + 0.004, 0.45, 0.85) for s in (-1, 1)]
    shield = _box(0.5, 0.504, -0.45, 0.45, 0.35, 0.90)
    r = 0.16
    return [Part(body, c), *[Part(m, GLASS) for m in band], Part(shield, GLASS),
            *_wheels((0.32, -0.25), 0.5, r, 0.11, r * h / l),
            *[Part(_box(0.5, 0.505, s * 0.30, s * 0.45, 0.15, 0.22), HEADLIGHT) for s in (-1, 1)],
            *[Part(_box(-0.505, -0.5, s * 0.30, s * 0.45, 0.15, 0.25), TAILLIGHT)
              for s in (-1, 1)]]


def _limb(a, b, r) -> Shape:
    """A box-section limb from point a to point b (closed convex hull)."""
    return _limb_at(tuple(np.asarray(a, float).tolist()), tuple(np.asarray(b, float).tolist()), float(r))


@functools.lru_cache(maxsize=256)
def _limb_at(a: tuple, b: tuple, r: float) -> Shape:
    """_limb by value: a cyclist's frame and legs are the same on every bike (qhull, 0.1 ms each)."""
    a, b = np.array(a), np.array(b)
    offs = np.array([[dx, dy, 0.0] for dx in (-r, r) for dy in (-r, r)])
    shape = hull(np.concatenate([a + offs, b + offs]))
    shape.vertices.flags.writeable = shape.faces.flags.writeable = False  # shared by every caller
    return shape


@functools.cache
def _head_template() -> trimesh.Trimesh:
    """The head before it is placed: the same for every person."""
    head = trimesh.creation.icosphere(subdivisions=1, radius=0.07)
    head.apply_scale([1.0, 0.85, 1.15])
    return head


def _head(centre) -> Shape:
    """The head at `centre`: the template moved as trimesh's apply_translation moves it (the
    same homogeneous product, so the same bits), without a trimesh per person."""
    head = _head_template()
    move = np.eye(4)
    move[:3, 3] = np.asarray(centre, dtype=np.float64)
    return Shape(trimesh.transformations.transform_points(head.vertices, move), head.faces)


@functools.cache
def _hair_template() -> Shape:
    """The hair over the head template (HAIRLINE), 4 % proud of it so that the skin under it
    stays hidden: the hull of the head's points behind the hairline or above the forehead."""
    v = _head_template().vertices
    half = np.ptp(v, axis=0) / 2
    keep = (v[:, 0] <= HAIRLINE[0] * half[0]) | (v[:, 2] >= HAIRLINE[1] * half[2])
    shape = hull(1.04 * v[keep])
    shape.vertices.flags.writeable = shape.faces.flags.writeable = False  # shared by every caller
    return shape


def _fibre(name: str, palette: np.ndarray, rng) -> Material:
    """Hair or shoes in a colour of the palette; at 905 nm read as clothes' fibres are
    (`textile_reflectivity`: no measurement of hair or shoe leather at 905 nm to hand)."""
    colour = tuple(float(v) for v in palette[rng.integers(len(palette))])
    return Material(name, colour, textile_reflectivity(colour))


def _person(rng, clothes: Material, skin: Material, stride: float, lean: float = 0.0,
            sitting_on_bike: bool = False) -> list[Part]:
    """A person 1.0 tall, x forward: legs and feet, torso, arms, head and hair."""
    hair, shoes = _fibre("hair", _HAIR, rng), _fibre("shoes", _SHOES, rng)
    hip = np.array([0.0, 0.0, 0.50])
    shoulder_z = 0.80
    parts = []
    if sitting_on_bike:
        feet = [np.array([0.10, -0.08, 0.12]), np.array([-0.05, 0.08, 0.22])]
        knees = [np.array([0.22, -0.09, 0.45]), np.array([0.18, 0.09, 0.50])]
        hip = np.array([-0.12, 0.0, 0.62])
        shoulder = np.array([0.10 + lean, 0.0, 0.90])
    else:
        feet = [np.array([stride / 2, -0.07, 0.0]), np.array([-stride / 2, 0.07, 0.0])]
        knees = [np.array([stride / 4, -0.07, 0.27]), np.array([-stride / 4, 0.07, 0.27])]
        shoulder = np.array([lean, 0.0, shoulder_z])
    length, breadth, ankle = FOOT
    for f, k, s in zip(feet, knees, (-1, 1)):
        h = hip + [0, s * 0.07, 0]
        parts.append(Part(_limb(f + [0, 0, 0.03], k, 0.045), clothes))
        parts.append(Part(_limb(k, h, 0.055), clothes))
        parts.append(Part(_box(f[0] - length / 4, f[0] + 3 * length / 4, f[1] - breadth / 2,
                               f[1] + breadth / 2, f[2], f[2] + ankle), shoes))
    torso = hull([hip + [dx, dy, 0] for dx in (-0.07, 0.07) for dy in (-0.13, 0.13)]
                 + [shoulder + [dx, dy, 0] for dx in (-0.08, 0.08) for dy in (-0.18, 0.18)])
    parts.append(Part(torso, clothes))
    for s in (-1, 1):
        top = shoulder + [0, s * 0.21, -0.02]
        if sitting_on_bike:
            hand = np.array([0.42, s * 0.20, 0.66])  # on the handlebar
        else:
            hand = top + [-s * stride * 0.3, s * 0.03, -0.33]
        parts.append(Part(_limb(top, hand, 0.035), clothes))
    head = shoulder + [0.01, 0, 0.09]
    parts.append(Part(_head(head), skin))
    hair_shape = _hair_template()
    parts.append(Part(Shape(hair_shape.vertices + head, hair_shape.faces), hair))
    return parts


def _pedestrian(rng, c: Material) -> list[Part]:
    tone = tuple(float(v) for v in _SKIN[rng.integers(len(_SKIN))])
    skin = Material("skin", tone, skin_reflectivity(tone))
    clothes = Material("clothes", c.color, textile_reflectivity(c.color))
    return _person(rng, clothes, skin, stride=rng.uniform(0.1, 0.5), lean=rng.uniform(0, 0.03))


def bicycle() -> list[Part]:
    """A bicycle in its rider's unit frame (x forward, wheels on z = 0, the rider's height 1):
    two wheels, the frame's tubes and the handlebar. Ridden (a cyclist) or parked
    (simgen.scenery's cycle stands), scaled to its owner's size by fit_parts."""
    return list(_bicycle())


@functools.cache
def _bicycle() -> tuple[Part, ...]:
    """bicycle()'s parts, the same for every bicycle: made once, read-only."""
    r = 0.19  # wheel radius relative to the rider's height
    xf, xb = 0.48, -0.48
    parts = [Part(m, TYRE) for x in (xf, xb) for m in spoked_wheel(x, 0.0, r, 0.03, 0.025)]
    crank = np.array([0.0, 0.0, 0.16])
    seat = np.array([-0.12, 0.0, 0.55])
    bar = np.array([0.40, 0.0, 0.62])
    for a, b in ((np.array([xb, 0, r]), crank), (crank, seat), (seat, np.array([xb, 0, r])),
                 (crank, bar), (bar, np.array([xf, 0, r])), (seat, bar)):
        parts.append(Part(_limb(a, b, 0.015), FRAME))
    parts.append(Part(_box(0.38, 0.42, -0.22, 0.22, 0.60, 0.64), FRAME))
    for p in parts:
        p.mesh.vertices.flags.writeable = False
    return tuple(parts)


def _cyclist(rng, c: Material) -> list[Part]:
    tone = tuple(float(v) for v in _SKIN[rng.integers(len(_SKIN))])
    skin = Material("skin", tone, skin_reflectivity(tone))
    clothes = Material("clothes", c.color, textile_reflectivity(c.color))
    parts = bicycle()
    parts += _person(rng, clothes, skin, 0.0, lean=rng.uniform(0.0, 0.08), sitting_on_bike=True)
    return parts


# Vehicles are built knowing their size (round wheels, parts in metres); people in a unit frame.
_VEHICLES = {"car": _car, "van": _van, "truck": _truck, "bus": _bus}
_PEOPLE = {"pedestrian": _pedestrian, "cyclist": _cyclist}


def build_actor_parts(recipe: dict) -> list[Part]:
    """The parts of a procedural (or user) actor, in its own frame; a pure function of the recipe."""
    kind = recipe["kind"]
    h, w, l = recipe["dims"]
    if kind == "user":
        return build_user_parts(recipe)
    if kind not in _VEHICLES and kind not in _PEOPLE:
        raise ValueError(f"unknown mesh kind {kind!r}")
    rng = np.random.default_rng(recipe["seed"])
    c = paint(recipe["color"])
    parts = _VEHICLES[kind](rng, c, (h, w, l)) if kind in _VEHICLES else _PEOPLE[kind](rng, c)
    return fit_parts(parts, h, w, l)
