"""Procedural actor meshes: every part a closed convex hull, every size drawn close to KITTI's.

A mesh is built from a recipe (class, h/w/l, colour, a seed for the proportions), so `meta/`
can rebuild it exactly. Parts are laid out in unit-ish proportions, then the whole actor is
scaled per axis so that its extent is exactly the drawn l x w x h and its origin is the
bottom-face centre: the label box is the mesh's exact extent by construction.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

# The vehicle materials at 905 nm and their sources: simgen.materials.
from .materials import (FRAME, GLASS, HEADLIGHT, PLATE, TAILLIGHT, TYRE, paint_material,
                        skin_reflectivity, textile_reflectivity)
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

# Common car paint colours (linear RGB) and their shares on the road.
_PAINTS = np.array([[0.85, 0.85, 0.85], [0.03, 0.03, 0.03], [0.45, 0.46, 0.48], [0.20, 0.21, 0.22],
                    [0.05, 0.12, 0.40], [0.55, 0.04, 0.03], [0.05, 0.20, 0.08], [0.55, 0.45, 0.30]])
_PAINT_SHARE = np.array([0.24, 0.20, 0.16, 0.14, 0.09, 0.09, 0.04, 0.04])
_CLOTHES = np.array([[0.05, 0.05, 0.08], [0.10, 0.15, 0.35], [0.45, 0.05, 0.05], [0.35, 0.35, 0.35],
                     [0.60, 0.55, 0.45], [0.08, 0.25, 0.10], [0.70, 0.70, 0.70]])
_SKIN = np.array([[0.80, 0.60, 0.48], [0.55, 0.38, 0.27], [0.30, 0.19, 0.13]])

# The emissive look of lamp materials at night (renderer): name -> linear RGB emission.
EMISSIVE = {"headlight": (4.0, 4.0, 3.6), "taillight": (2.5, 0.05, 0.05)}


def paint(color) -> Material:
    """Car paint: Lambertian, its 905 nm reflectance from the colour (simgen.materials: carbon
    black darkens the NIR too, chromatic pigments do not; black about 0.07, white about 0.73)."""
    return paint_material("paint", color)


def hull(points) -> trimesh.Trimesh:
    """Closed convex hull of a point set, faces wound outward: watertight by construction.

    qhull directly (trimesh's wrapper re-processes the mesh, 5x slower for these small hulls)."""
    pts = np.asarray(points, dtype=float)
    faces = ConvexHull(pts).simplices
    tri = pts[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    inward = np.einsum("ij,ij->i", normal, tri.mean(axis=1) - pts[np.unique(faces)].mean(axis=0)) < 0
    faces = np.where(inward[:, None], faces[:, ::-1], faces)
    used, inv = np.unique(faces, return_inverse=True)
    return trimesh.Trimesh(pts[used], inv.reshape(-1, 3), process=False)


_BOX_FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                       [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])


def box(x0, x1, y0, y1, z0, z1) -> trimesh.Trimesh:
    """Axis-aligned box from its bounds (either order), faces wound outward."""
    (x0, x1), (y0, y1), (z0, z1) = sorted((x0, x1)), sorted((y0, y1)), sorted((z0, z1))
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=float)
    return trimesh.Trimesh(v, _BOX_FACES, process=False)


def prism_xz(profile, y0, y1) -> trimesh.Trimesh:
    """A convex side profile (x, z) swept across y in [y0, y1]."""
    p = np.asarray(profile, dtype=float)
    return hull(np.concatenate([np.c_[p[:, 0], np.full(len(p), y0), p[:, 1]],
                                np.c_[p[:, 0], np.full(len(p), y1), p[:, 1]]]))


def wheel(x, y, r, width, sections=14) -> trimesh.Trimesh:
    """A closed cylinder of radius r, axis along y, standing on z = 0 at (x, y)."""
    a = 2 * np.pi * np.arange(sections) / sections
    ring = np.c_[x + r * np.cos(a), np.zeros(sections), r + r * np.sin(a)]
    return hull(np.concatenate([ring + [0, y - width / 2, 0], ring + [0, y + width / 2, 0]]))


def sample_size(cls: str, rng: np.random.Generator) -> tuple[float, float, float]:
    """(h, w, l) from a normal truncated at 2.5 sd, correlated through one shared 'scale' draw."""
    mean, sd = (np.array(v) for v in SIZE_STATS[cls])
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
        color = _PAINTS[rng.choice(len(_PAINTS), p=_PAINT_SHARE / _PAINT_SHARE.sum())]
    color = np.clip(color * rng.uniform(0.85, 1.15), 0.0, 1.0)
    return {"kind": cls.lower(), "dims": [h, w, l], "color": [round(float(c), 4) for c in color],
            "seed": int(rng.integers(2**31))}


def _car(rng, c: Material) -> list[Part]:
    hood = rng.uniform(0.14, 0.22)  # where the windshield starts (x, share of length from centre)
    belt = rng.uniform(0.50, 0.56)
    rear = rng.uniform(-0.40, -0.34)
    body = prism_xz([[0.5, 0.16], [0.49, 0.42], [hood, belt], [-0.47, belt], [-0.5, 0.42],
                     [-0.5, 0.18]], -0.5, 0.5)
    cabin = hull([[hood, -0.44, belt], [hood, 0.44, belt], [rear, -0.44, belt], [rear, 0.44, belt],
                  [-0.03, -0.37, 0.94], [-0.03, 0.37, 0.94], [rear + 0.10, -0.37, 0.94],
                  [rear + 0.10, 0.37, 0.94]])
    roof = box(rear + 0.10, -0.03, -0.37, 0.37, 0.93, 1.0)
    r = 0.21
    wheels = [wheel(x, y, r, 0.14) for x in (0.33, -0.31) for y in (-0.40, 0.40)]
    return [Part(body, c), Part(cabin, GLASS), Part(roof, c),
            *[Part(wm, TYRE) for wm in wheels],
            Part(box(0.488, 0.502, -0.12, 0.12, 0.25, 0.33), PLATE),
            Part(box(-0.502, -0.495, -0.12, 0.12, 0.28, 0.36), PLATE),
            *[Part(box(0.475, 0.496, s * 0.30, s * 0.44, 0.40, 0.46), HEADLIGHT) for s in (-1, 1)],
            *[Part(box(-0.501, -0.49, s * 0.32, s * 0.46, 0.40, 0.48), TAILLIGHT)
              for s in (-1, 1)]]


def _van(rng, c: Material) -> list[Part]:
    nose = rng.uniform(0.28, 0.36)
    body = prism_xz([[0.5, 0.14], [0.5, 0.45], [nose, 0.52], [-0.5, 0.52], [-0.5, 0.14]], -0.5, 0.5)
    upper = box(-0.5, nose - 0.10, -0.5, 0.5, 0.50, 1.0)
    shield = hull([[nose, -0.46, 0.52], [nose, 0.46, 0.52], [nose - 0.10, -0.46, 0.50],
                   [nose - 0.10, 0.46, 0.50], [nose - 0.10, -0.44, 0.86], [nose - 0.10, 0.44, 0.86]])
    side_windows = [box(-0.15, nose - 0.11, s * 0.5 - 0.005, s * 0.5 + 0.005, 0.60, 0.82)
                    for s in (-1, 1)]
    r = 0.16
    wheels = [wheel(x, y, r, 0.12) for x in (0.32, -0.32) for y in (-0.42, 0.42)]
    return [Part(body, c), Part(upper, c), Part(shield, GLASS),
            *[Part(m, GLASS) for m in side_windows], *[Part(m, TYRE) for m in wheels],
            Part(box(0.495, 0.502, -0.11, 0.11, 0.22, 0.29), PLATE),
            Part(box(-0.502, -0.495, -0.11, 0.11, 0.25, 0.32), PLATE),
            *[Part(box(0.49, 0.503, s * 0.30, s * 0.45, 0.38, 0.44), HEADLIGHT) for s in (-1, 1)],
            *[Part(box(-0.503, -0.49, s * 0.36, s * 0.48, 0.30, 0.45), TAILLIGHT)
              for s in (-1, 1)]]


def _truck(rng, c: Material) -> list[Part]:
    cab_len = rng.uniform(0.17, 0.24)
    front = 0.5
    cab = box(front - cab_len, front, -0.5, 0.5, 0.12, 0.92)
    shield = box(front - 0.004, front + 0.004, -0.44, 0.44, 0.60, 0.86)
    cargo_color = paint(rng.uniform(0.5, 0.95, 3))
    cargo = box(-0.5, front - cab_len - 0.02, -0.5, 0.5, 0.14, 1.0)
    chassis = box(-0.48, front - 0.02, -0.35, 0.35, 0.08, 0.16)
    r = 0.11
    xs = (front - cab_len * 0.5, -0.28, -0.38)
    wheels = [wheel(x, y, r, 0.10) for x in xs for y in (-0.40, 0.40)]
    return [Part(cab, c), Part(shield, GLASS), Part(cargo, cargo_color), Part(chassis, FRAME),
            *[Part(m, TYRE) for m in wheels],
            Part(box(0.5, 0.503, -0.08, 0.08, 0.15, 0.20), PLATE),
            *[Part(box(0.5, 0.503, s * 0.30, s * 0.45, 0.22, 0.28), HEADLIGHT) for s in (-1, 1)],
            *[Part(box(-0.503, -0.5, s * 0.30, s * 0.45, 0.16, 0.22), TAILLIGHT)
              for s in (-1, 1)]]


def _bus(rng, c: Material) -> list[Part]:
    body = box(-0.5, 0.5, -0.5, 0.5, 0.10, 1.0)
    band = [box(-0.45, 0.42, s * 0.5 - 0.004, s * 0.5 + 0.004, 0.45, 0.85) for s in (-1, 1)]
    shield = box(0.5, 0.504, -0.45, 0.45, 0.35, 0.90)
    r = 0.16
    wheels = [wheel(x, y, r, 0.11) for x in (0.32, -0.25) for y in (-0.40, 0.40)]
    return [Part(body, c), *[Part(m, GLASS) for m in band], Part(shield, GLASS),
            *[Part(m, TYRE) for m in wheels],
            *[Part(box(0.5, 0.505, s * 0.30, s * 0.45, 0.15, 0.22), HEADLIGHT) for s in (-1, 1)],
            *[Part(box(-0.505, -0.5, s * 0.30, s * 0.45, 0.15, 0.25), TAILLIGHT)
              for s in (-1, 1)]]


def _limb(a, b, r) -> trimesh.Trimesh:
    """A box-section limb from point a to point b (closed convex hull)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    offs = np.array([[dx, dy, 0.0] for dx in (-r, r) for dy in (-r, r)])
    return hull(np.concatenate([a + offs, b + offs]))


def _person(rng, clothes: Material, skin: Material, stride: float, lean: float = 0.0,
            sitting_on_bike: bool = False) -> list[Part]:
    """A person 1.0 tall, x forward: legs, torso, arms, head."""
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
    for f, k, s in zip(feet, knees, (-1, 1)):
        h = hip + [0, s * 0.07, 0]
        parts.append(Part(_limb(f + [0, 0, 0.03], k, 0.045), clothes))
        parts.append(Part(_limb(k, h, 0.055), clothes))
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
    head = trimesh.creation.icosphere(subdivisions=1, radius=0.07)
    head.apply_scale([1.0, 0.85, 1.15])
    head.apply_translation(shoulder + [0.01, 0, 0.09])
    parts.append(Part(head, skin))
    return parts


def _pedestrian(rng, c: Material) -> list[Part]:
    tone = tuple(float(v) for v in _SKIN[rng.integers(len(_SKIN))])
    skin = Material("skin", tone, skin_reflectivity(tone))
    clothes = Material("clothes", c.color, textile_reflectivity(c.color))
    return _person(rng, clothes, skin, stride=rng.uniform(0.1, 0.5), lean=rng.uniform(0, 0.03))


def _cyclist(rng, c: Material) -> list[Part]:
    tone = tuple(float(v) for v in _SKIN[rng.integers(len(_SKIN))])
    skin = Material("skin", tone, skin_reflectivity(tone))
    clothes = Material("clothes", c.color, textile_reflectivity(c.color))
    r = 0.19  # wheel radius relative to the rider's height
    xf, xb = 0.48, -0.48
    parts = [Part(wheel(x, 0.0, r, 0.03, sections=16), TYRE) for x in (xf, xb)]
    crank = np.array([0.0, 0.0, 0.16])
    seat = np.array([-0.12, 0.0, 0.55])
    bar = np.array([0.40, 0.0, 0.62])
    for a, b in ((np.array([xb, 0, r]), crank), (crank, seat), (seat, np.array([xb, 0, r])),
                 (crank, bar), (bar, np.array([xf, 0, r])), (seat, bar)):
        parts.append(Part(_limb(a, b, 0.015), FRAME))
    parts.append(Part(box(0.38, 0.42, -0.22, 0.22, 0.60, 0.64), FRAME))
    parts += _person(rng, clothes, skin, 0.0, lean=rng.uniform(0.0, 0.08), sitting_on_bike=True)
    return parts


_BUILDERS = {"car": _car, "van": _van, "truck": _truck, "bus": _bus,
             "pedestrian": _pedestrian, "cyclist": _cyclist}


def build_actor_parts(recipe: dict) -> list[Part]:
    """The parts of a procedural (or user) actor, in its own frame; a pure function of the recipe."""
    kind = recipe["kind"]
    h, w, l = recipe["dims"]
    if kind == "user":
        return build_user_parts(recipe)
    if kind not in _BUILDERS:
        raise ValueError(f"unknown mesh kind {kind!r}")
    rng = np.random.default_rng(recipe["seed"])
    parts = _BUILDERS[kind](rng, paint(recipe["color"]))
    return fit_parts(parts, h, w, l)
