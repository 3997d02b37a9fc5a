"""What the scenery's sections share: the mesh helpers (strips, rectangles, walls, unit shapes
placed by plain vertex arithmetic), the cross street, the scenery built so far (_Meshes) and the
footprints actors keep off (Obstacle)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import shapely
import trimesh

from ..materials import ASPHALT, CONCRETE, FOREST_FLOOR, MARKING, SAND, SIDEWALK, VERGE
from ..meshes import Shape
from ..road import RoadLayout
from ..world import Material


FACADES = [(0.55, 0.50, 0.42), (0.40, 0.30, 0.25), (0.60, 0.58, 0.55), (0.35, 0.36, 0.40),
           (0.65, 0.55, 0.40), (0.30, 0.25, 0.22)]
# 003's scene types: the ground beside the road, whether buildings may stand, the tree density
# multiplier along the sidewalk and the density of woods (trees per 100 m in a 25 m deep band).
ENVIRONMENTS = {"city": (VERGE, True, 1.0, 0.0), "grass": (VERGE, False, 0.5, 0.0),
                "forest": (FOREST_FLOOR, False, 1.0, 40.0), "desert": (SAND, False, 0.0, 0.0)}
MARK_Z = 0.01  # markings sit 1 cm above the asphalt so no renderer z-fights them
VERGE_WIDTH = 60.0


@dataclass
class Obstacle:
    """A static footprint actors must not overlap; `base` is the lowest height it occupies."""

    polygon: shapely.Polygon
    base: float = 0.0


def strip(road: RoadLayout, s: np.ndarray, d0: float, d1: float, z0: float, z1: float | None = None):
    """A quad strip between lateral offsets d0 < d1 along s; horizontal at z0, or vertical
    from z0 to z1 (d0 == d1). Faces wound to face up (horizontal) or towards +d (vertical)."""
    n = len(s)
    v = np.empty((2 * n, 3))
    v[:n, :2], v[n:, :2] = road.xy(s, d0), road.xy(s, d0 if z1 is not None else d1)
    v[:n, 2], v[n:, 2] = (z0, z0) if z1 is None else (z1, z0)
    return Shape(v, _strip_faces(n))


@functools.cache
def _strip_faces(n: int) -> np.ndarray:
    """The faces of a strip of n samples a side (shared by every strip of that length: read-only)."""
    i = np.arange(n - 1)
    faces = np.concatenate([np.column_stack((i, i + 1, i + n)), np.column_stack((i + 1, i + n + 1, i + n))])
    faces.flags.writeable = False
    return faces


def flip(m: Shape) -> Shape:
    return Shape(m.vertices, m.faces[:, ::-1])


def oriented_box(road: RoadLayout, s: float, d: float, z: float, l: float, w: float, h: float):
    m = trimesh.creation.box(extents=[l, w, h])
    m.apply_translation([0, 0, h / 2])
    m.apply_transform(road.pose(s, d, z))
    return m


def footprint(m: Shape | trimesh.Trimesh) -> shapely.Polygon:
    return plan_hull(np.asarray(m.vertices)[:, :2])


def plan_hull(xy: np.ndarray) -> shapely.Polygon:
    """The convex hull of (n, 2) points, taken of them as a line string: GEOS hulls the same
    coordinates in the same order whatever holds them, and a multipoint first makes a point
    geometry of each."""
    return shapely.convex_hull(shapely.linestrings(xy))


def plain(m: trimesh.Trimesh) -> Shape:
    """A template mesh's arrays as plain numpy (arithmetic on trimesh's tracked arrays costs more)."""
    return Shape(np.asarray(m.vertices), np.asarray(m.faces))


QUAD = np.array([[0, 1, 2], [0, 2, 3]])  # a quad's corners in order round it, as two triangles


def _rect(x0: float, x1: float, y0: float, y1: float, z: float) -> Shape:
    """An upward-facing horizontal rectangle in world coordinates."""
    v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
    return Shape(v, QUAD)


def _wall(x: float, y0: float, y1: float, z0: float, z1: float, facing: float) -> Shape:
    """A vertical rectangle in the plane world x = const, facing +x (facing > 0) or -x."""
    v = np.array([[x, y0, z0], [x, y1, z0], [x, y1, z1], [x, y0, z1]], float)
    return Shape(v, QUAD if facing > 0 else QUAD[:, [0, 2, 1]])


def _spans(road: RoadLayout, margin: float) -> list[tuple[float, float]]:
    """[s_min, s_max] minus the cross street widened by `margin` on both sides."""
    if road.cross_s is None:
        return [(road.s_min, road.s_max)]
    a, b = road.cross_s - road.cross_half_width - margin, road.cross_s + road.cross_half_width + margin
    return [(lo, hi) for lo, hi in ((road.s_min, a), (b, road.s_max)) if hi > lo]


def cross_street(road: RoadLayout, add, far: float | None = None) -> shapely.Polygon:
    """Asphalt, curbs, sidewalks and markings of the cross street out to `far` beyond each curb
    (default: the verge's far edge); returns the band to keep free of buildings, trees and poles."""
    cx, hw, sw, ch = road.cross_s, road.cross_half_width, road.sidewalk_width, road.curb_height
    far = VERGE_WIDTH + sw if far is None else far
    for y0, y1, walk in ((road.right_curb - far, road.right_curb, road.right_curb - sw),
                         (road.left_curb, road.left_curb + far, road.left_curb + sw)):
        add(ASPHALT, _rect(cx - hw, cx + hw, y0, y1, 0.0))
        w0, w1 = (y0, walk) if y1 == road.right_curb else (walk, y1)
        add(SIDEWALK, _rect(cx - hw - sw, cx - hw, w0, w1, ch))
        add(SIDEWALK, _rect(cx + hw, cx + hw + sw, w0, w1, ch))
        add(CONCRETE, _wall(cx - hw, y0, y1, 0.0, ch, +1))
        add(CONCRETE, _wall(cx + hw, y0, y1, 0.0, ch, -1))
        for off in (-0.12, 0.12):
            add(MARKING, _rect(cx + off - 0.075, cx + off + 0.075, y0, y1, MARK_Z))
    # Stop lines before the crossing, across the lanes of each direction.
    add(MARKING, strip(road, np.array([cx - hw - 1.4, cx - hw - 1.0]), road.right_lane_edge,
                       road.divider, MARK_Z))
    add(MARKING, strip(road, np.array([cx + hw + 1.0, cx + hw + 1.4]), road.divider,
                       road.left_lane_edge, MARK_Z))
    return shapely.box(cx - hw - sw - 1.0, -1e4, cx + hw + sw + 1.0, 1e4)


class _Meshes:
    """The scenery built so far: meshes by material, footprints, and the areas to keep clear."""

    def __init__(self, clear: list[shapely.Polygon]):
        self.by_mat: dict[Material, list[Shape | trimesh.Trimesh]] = {}
        self.obstacles: list[Obstacle] = []
        self.clear = clear
        self.sight = list(clear)  # the caller's keep-clear areas: even the signals keep off them

    def add(self, mat: Material, mesh: Shape | trimesh.Trimesh) -> None:
        self.by_mat.setdefault(mat, []).append(mesh)

    def clear_of(self, footprints: np.ndarray) -> np.ndarray:
        """Which footprints keep out of every keep-clear area: one vectorised test per area, of
        the footprints whose envelopes meet its envelope (no others can meet it)."""
        keep = np.ones(len(footprints), bool)
        if not self.clear:
            return keep
        x0, y0, x1, y1 = shapely.bounds(footprints).T
        for c in self.clear:
            cx0, cy0, cx1, cy1 = c.bounds
            near = np.flatnonzero((x0 <= cx1) & (x1 >= cx0) & (y0 <= cy1) & (y1 >= cy0))
            keep[near[shapely.intersects(footprints[near], c)]] = False
        return keep

    def blocks(self, mesh: Shape | trimesh.Trimesh) -> bool:
        """Whether the mesh would stand in a keep-clear area (a sight line, the cross street)."""
        return self.blocked(footprint(mesh))

    def blocked(self, fp: shapely.Polygon) -> bool:
        """Whether a footprint reaches into a keep-clear area (one vectorised test)."""
        return bool(self.clear) and bool(shapely.intersects(fp, self.clear).any())


# Unit meshes the frontage scales and places by plain vertex arithmetic (thousands per world:
# trimesh's creation and transform calls cost ~20x more).
UNIT_BOX = plain(trimesh.creation.box(extents=[1.0, 1.0, 1.0]))
UNIT_CYLINDER = plain(trimesh.creation.cylinder(radius=1.0, height=1.0, sections=8))
UNIT_SPHERES = {k: plain(trimesh.creation.icosphere(subdivisions=k, radius=1.0)) for k in (0, 1)}
SPHERE_TOP = float(UNIT_SPHERES[0].vertices[:, 2].max())  # the coarse sphere's reach up (and down)


def _placed(unit: Shape, scale, at) -> Shape:
    return Shape(unit.vertices * np.asarray(scale) + np.asarray(at), unit.faces)


def uniform(bounds: tuple[float, float], u: np.ndarray) -> np.ndarray:
    """rng.uniform(*bounds) from the stream's next doubles u (rng.random): numpy's own lo + (hi -
    lo) u, so draws taken at once have the bits and the order of draws taken one at a time."""
    lo, hi = bounds
    return lo + (hi - lo) * u


def placed_many(unit: Shape, scale: np.ndarray, at: np.ndarray) -> Shape:
    """_placed for (n, 3) scales and places at once, as one Shape (the same products and sums,
    faces offset as merging the n Shapes offsets them): one numpy call for hundreds of shrubs."""
    n, nv = len(at), len(unit.vertices)
    v = unit.vertices * scale[:, None, :] + at[:, None, :]
    f = unit.faces + nv * np.arange(n)[:, None, None]
    return Shape(v.reshape(-1, 3), f.reshape(-1, 3))


@functools.cache
def _unit_ring(quad_segs: int) -> np.ndarray:
    """GEOS's ring of a point buffered by 1 at the origin: the cosines and sines it uses (snapped
    to 0 next to the axes), its start (1, 0) first and last."""
    return shapely.get_coordinates(shapely.Point(0.0, 0.0).buffer(1.0, quad_segs))


def discs(x: np.ndarray, y: np.ndarray, r: np.ndarray, quad_segs: int) -> np.ndarray:
    """shapely.Point(x, y).buffer(r, quad_segs) for arrays of centres and radii: GEOS's own ring
    (centre plus radius times its cosine and sine) in one vectorised call instead of a buffer
    each, which cost most of a frame's frontage."""
    ring = _unit_ring(quad_segs)
    x, y = np.asarray(x, dtype=float)[:, None], np.asarray(y, dtype=float)[:, None]
    r = np.asarray(r, dtype=float)[..., None]
    coords = np.empty((len(x), len(ring), 2))
    coords[..., 0] = x + r * ring[:, 0]
    coords[..., 1] = y + r * ring[:, 1]
    coords[:, [0, -1], 1] = y  # GEOS starts (and closes) the ring at (x + r, y) itself
    return shapely.polygons(coords)


def moved(m: Shape, at) -> Shape:
    """m moved by `at` as trimesh's apply_translation moves it (the same homogeneous product, so
    the same bits)."""
    move = np.eye(4)
    move[:3, 3] = at
    return Shape(trimesh.transformations.transform_points(m.vertices, move), m.faces)
