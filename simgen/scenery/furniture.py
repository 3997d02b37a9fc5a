"""Street furniture (clutter.furniture): signs, signals, bins, bollards, cycle stands and the
bicycles parked at them, placed on the sidewalks of both street models after everything else."""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import shapely
import trimesh

from ..materials import METAL, SIGN_BLUE, SIGN_RED, SIGN_WHITE, SIGN_YELLOW, TRIM, paint_material, signal_lens
from ..meshes import Shape, _box, _extrude, bicycle
from ..road import RoadLayout
from ..world import Material, Part, fit_parts
from .parts import Obstacle, UNIT_CYLINDER, _Meshes, _placed, footprint, plan_hull


# --- Street furniture (clutter.furniture) -----------------------------------------------------
# On the sidewalks of both street models, after everything else, from its own random stream; each
# piece keeps off the keep-clear areas, the obstacles lower than its top and the pieces before it.
# `clutter.furniture` scales the densities below. German rules again, KITTI being Karlsruhe's.
#
# Traffic signs. More than 20 million in Germany, on average one every 28 m of road, motorways
# included (press figures): 3.6 per 100 m of road, 1.8 per side. VwV-StVO: lower edge 2.0 m above
# footways; the edge nearest the carriageway 0.5 m from it in town (never less than 0.3 m); posts
# and backs grey (METAL), the common post a 60.3 mm steel tube. Sizes: VwV-StVO size 2, the one
# for 50-100 km/h: circle 600 mm, triangle 900 mm a side, square 600 mm; the stop octagon and the
# priority diamond taken as 600 mm (no table at hand). Kinds equally often (no survey found).
SIGNS_PER_100M = 1.8
SIGN_LOWER_EDGE, SIDE_CLEARANCE, SIGN_POST_R = 2.0, 0.5, 0.03
# kind: outer (corners, circumradius m, phase deg) and sheeting, inner field (or None) and sheeting;
# the fields' proportions read off the StVO's drawings.
SIGNS = {
    "prohibition": ((12, 0.30, 0.0), SIGN_RED, (12, 0.24, 0.0), SIGN_WHITE),
    "mandatory": ((12, 0.30, 0.0), SIGN_BLUE, None, None),
    "no_stopping": ((12, 0.30, 0.0), SIGN_RED, (12, 0.24, 0.0), SIGN_BLUE),
    "warning": ((3, 0.52, 90.0), SIGN_RED, (3, 0.37, 90.0), SIGN_WHITE),
    "yield": ((3, 0.52, -90.0), SIGN_RED, (3, 0.37, -90.0), SIGN_WHITE),
    "stop": ((8, 0.325, 22.5), SIGN_RED, None, None),
    "priority": ((4, 0.42, 0.0), SIGN_WHITE, (4, 0.30, 0.0), SIGN_YELLOW),
    "crossing": ((4, 0.42, 45.0), SIGN_BLUE, (3, 0.25, 90.0), SIGN_WHITE),
}
# Traffic signals at every corner of the intersection, each facing the traffic that arrives there
# (the generated intersection joins multi-lane urban streets: signalised; no survey of the share).
# Lower edge of the head 2.10 m above the footway, 0.3 m at least from the carriageway (RSA/RiLSA);
# a three-lamp head of 200 mm lenses, about 0.30 x 0.85 x 0.25 m in a 0.55 x 1.05 m black board
# (makers' drawings; no standard found), on a mast of about 140 mm.
SIGNAL_LOWER_EDGE, SIGNAL_MAST_R = 2.10, 0.07
# Which lamp is lit: RiLSA's amber lasts 3 s at 50 km/h in cycles of typically 60-90 s, so about
# 5 % of the time; red and green share the rest (no survey). The cross street shows red unless the
# main road does. Lens colours (linear RGB) lit and dark.
SIGNAL_PHASES, SIGNAL_SHARES = ("red", "amber", "green"), (0.475, 0.05, 0.475)
LENSES = {"red": ((1.0, 0.06, 0.03), (0.10, 0.02, 0.02)), "amber": ((1.0, 0.50, 0.02), (0.10, 0.07, 0.01)),
          "green": ((0.08, 1.0, 0.45), (0.02, 0.09, 0.06))}
# Litter bins: Hamburg has 8,850 public bins, most of 42 l, hung on posts (Hamburger Abendblatt),
# along about 4,000 km of streets: 0.22 per 100 m of street, 0.11 per side. A 42 l drum is 0.36 m
# across and 0.45 m high; its top at 1.0 m (no figure found). Colours: Berlin's orange, Hamburg's
# red, moss green and anthracite (RAL 2000, 3000, 6005, 7016), equally often (no survey found).
BINS_PER_100M = 0.11
BIN_R, BIN_H, BIN_TOP = 0.18, 0.45, 1.0
BIN_COLOURS = ((0.70, 0.16, 0.0), (0.45, 0.01, 0.01), (0.03, 0.06, 0.04), (0.02, 0.03, 0.03))
# Bollards keeping cars off the sidewalk: steel tubes of 76-108 mm, 0.9-1.0 m high, most with a
# white retro-reflective band (makers' catalogues; no standard found), in rows of 3-6 with gaps a
# car cannot pass (1.4 m between centres). Rows per side: no survey found, 0.5 per 100 m.
BOLLARD_ROWS_PER_100M = 0.5
BOLLARD_R, BOLLARD_H, BOLLARD_PITCH, BOLLARD_ROW = 0.045, 0.95, 1.4, (3, 7)
# Cycle stands (Anlehnbuegel): 48 mm tube, about 0.8 m high and 1.0 m long, 1.2 m apart for two
# bikes each (ADFC's recommendation), across the sidewalk, in groups of 2-6; only on sidewalks of
# at least 2.5 m, RASt 06's standard width. Groups per side: no survey found, 0.3 per 100 m.
STAND_GROUPS_PER_100M = 0.3
STAND_R, STAND_H, STAND_L, STAND_PITCH, STAND_GROUP, STAND_SIDEWALK = 0.024, 0.8, 1.0, 1.2, (2, 7), 2.5
# Parked bicycles: each side of a stand holds one with this probability (a judgement: no survey of
# how full KITTI's stands were), alongside the bar (its frame BIKE_GAP from the bar's axis), front
# wheel either way: the cyclist's bicycle (simgen.meshes.bicycle) scaled evenly to the length of
# KITTI's Cyclist labels (1.76 m, simgen.meshes.SIZE_STATS). KITTI's Cyclist is a rider on a
# bicycle; it labels no parked one, and neither does the generator: they are scenery, for the
# camera and the LiDAR alike.
STAND_OCCUPANCY = 0.5
BIKE_L, BIKE_GAP = 1.76, 0.12


def _posed(m: Shape | trimesh.Trimesh, T: np.ndarray) -> Shape:
    return Shape(m.vertices @ T[:3, :3].T + T[:3, 3], m.faces)


def _regular(n: int, r: float, phase_deg: float) -> np.ndarray:
    """A regular polygon's corners (y, z) about the origin."""
    a = np.radians(phase_deg) + 2 * np.pi * np.arange(n) / n
    return np.c_[r * np.cos(a), r * np.sin(a)]


def _plate(poly: np.ndarray, x0: float, x1: float, z: float) -> Shape:
    """A flat plate of a convex outline (y, z about height z), facing +x from x0 to x1."""
    return _extrude(poly + [0.0, z], 0, x0, x1)


def _column(x: float, y: float, r: float, z0: float, z1: float) -> Shape:
    return _placed(UNIT_CYLINDER, [r, r, z1 - z0], [x, y, (z0 + z1) / 2])


class _Furnisher:
    """Places pieces of furniture (parts in the world frame and their obstacles) where they fit."""

    def __init__(self, road: RoadLayout, out: _Meshes):
        self.road, self.out = road, out
        self.bases = np.array([o.base for o in out.obstacles])
        self.tree = shapely.STRtree([o.polygon for o in out.obstacles])
        self.placed: list[shapely.Polygon] = []

    def pose(self, side: int, s: float, inset: float, yaw: float = 0.0) -> np.ndarray:
        """World pose `inset` metres behind the curb of `side`, on the sidewalk, x turned by yaw
        from the road's heading."""
        curb = self.road.right_curb if side < 0 else self.road.left_curb
        return self.road.pose(s, curb + side * inset, 0.0, yaw)

    def add(self, parts: list[tuple[Material, Shape]], obstacles: Callable[[], list[Obstacle]],
            corner: bool = False) -> bool:
        """Adds the piece unless it stands in a keep-clear area (at a corner: a sight line only),
        on an obstacle lower than its top, or on a piece placed before; its obstacles are made
        only for a piece placed."""
        fp, top = _extent(parts)
        if not self._free(fp, top, self.out.sight if corner else self.out.clear, self.placed):
            return False
        self._put(parts, obstacles())
        self.placed.append(fp)
        return True

    def add_beside(self, parts: list[tuple[Material, Shape]], margin: float) -> bool:
        """Adds a piece that belongs to the one placed last (a bicycle at its stand): tested as
        `add` does, but not against that piece; its footprint, grown by `margin`, becomes an
        obstacle and joins that piece's."""
        fp, top = _extent(parts)
        if not self._free(fp, top, self.out.clear, self.placed[:-1]):
            return False
        self._put(parts, [Obstacle(fp.buffer(margin))])
        self.placed[-1] = self.placed[-1].union(fp)
        return True

    def _free(self, fp: shapely.Polygon, top: float, keep_clear: list, placed: list) -> bool:
        if keep_clear and shapely.intersects(fp, keep_clear).any():
            return False
        hits = self.tree.query(fp, predicate="intersects")
        return not (np.any(self.bases[hits] < top) or (placed and shapely.intersects(fp, placed).any()))

    def _put(self, parts: list[tuple[Material, Shape]], obstacles: list[Obstacle]) -> None:
        for mat, m in parts:
            self.out.add(mat, m)
        self.out.obstacles += obstacles


def _grown(meshes: list[Shape], margin: float) -> list[Obstacle]:
    """Obstacles: the meshes' footprints grown by `margin` (one vectorised buffer, with
    Polygon.buffer's 16 segments a quadrant)."""
    return [Obstacle(p) for p in shapely.buffer([footprint(m) for m in meshes], margin, quad_segs=16)]


def _extent(parts: list[tuple[Material, Shape]]) -> tuple[shapely.Polygon, float]:
    """A piece's footprint (the convex hull of its vertices seen from above) and its top."""
    v = np.concatenate([m.vertices for _, m in parts])
    return plan_hull(v[:, :2]), float(v[:, 2].max())


def _sign(f: _Furnisher, side: int, s: float, kind: str) -> None:
    """A sign on its post behind the curb, facing the traffic on its side (the right side's
    faces look back along -s)."""
    ch = f.road.curb_height
    reach, local = _sign_local(kind, ch)
    T = f.pose(side, s, reach, np.pi if side < 0 else 0.0)
    parts = [(mat, _posed(m, T)) for mat, m in local]
    f.add(parts, lambda: _grown([parts[0][1]], 0.1) + [
        Obstacle(plan_hull(np.concatenate([m.vertices[:, :2] for _, m in parts[1:]])), base=ch + SIGN_LOWER_EDGE)])


@functools.lru_cache(maxsize=64)
def _sign_local(kind: str, ch: float) -> tuple[float, tuple[tuple[Material, Shape], ...]]:
    """A sign's inset behind the curb (its plate's reach) and its post and plates in its own
    frame: the same for every sign of a kind on curbs ch high, so made once."""
    (n, r, ph), outer_mat, inner, inner_mat = SIGNS[kind]
    outer = _regular(n, r, ph)
    z = ch + SIGN_LOWER_EDGE - outer[:, 1].min()
    post = _column(-0.02 - SIGN_POST_R, 0.0, SIGN_POST_R, ch, z + outer[:, 1].max())
    local = [(METAL, post), (METAL, _plate(outer, -0.02, 0.0, z)), (outer_mat, _plate(outer, 0.0, 0.003, z))]
    if inner is not None:
        local.append((inner_mat, _plate(_regular(*inner), 0.003, 0.006, z)))
    return SIDE_CLEARANCE + outer[:, 0].max(), _frozen(local)


def _frozen(local: list[tuple[Material, Shape]]) -> tuple[tuple[Material, Shape], ...]:
    """Parts kept for every piece of furniture of a kind, their vertices made read-only."""
    for _, m in local:
        m.vertices.flags.writeable = False
    return tuple(local)


def _signal(f: _Furnisher, T: np.ndarray, lit: str) -> None:
    """A signal head on its mast at pose T (x: where the lamps face), `lit` the lamp that is on."""
    parts = [(mat, _posed(mesh, T)) for mat, mesh in _signal_local(f.road.curb_height, lit)]
    f.add(parts, lambda: _grown([parts[0][1]], 0.1) + [
        Obstacle(plan_hull(np.concatenate([x.vertices[:, :2] for _, x in parts[1:]])),
                 base=f.road.curb_height + SIGNAL_LOWER_EDGE)], corner=True)


@functools.lru_cache(maxsize=64)
def _signal_local(ch: float, lit: str) -> tuple[tuple[Material, Shape], ...]:
    """A signal's mast, board, head and lenses in its own frame (made once per curb height and
    lamp lit)."""
    m = SIGNAL_MAST_R
    z0 = ch + SIGNAL_LOWER_EDGE
    local = [(METAL, _column(0.0, 0.0, m, ch, z0 + 1.05)),
             (TRIM, _box(m + 0.20, m + 0.215, -0.275, 0.275, z0, z0 + 1.05)),
             (TRIM, _box(m, m + 0.25, -0.15, 0.15, z0 + 0.10, z0 + 0.95))]
    for k, phase in enumerate(SIGNAL_PHASES):  # red on top
        colour = LENSES[phase][0 if phase == lit else 1]
        local.append((signal_lens(colour), _plate(_regular(8, 0.10, 22.5), m + 0.25, m + 0.265,
                                                   z0 + 0.795 - 0.27 * k)))
    return _frozen(local)


def _signals(f: _Furnisher, rng: np.random.Generator) -> None:
    """One signal at each corner of the intersection, SIGNAL clearance from both curbs, facing
    the traffic that arrives at that corner (right-hand traffic)."""
    road = f.road
    main = SIGNAL_PHASES[int(rng.choice(3, p=SIGNAL_SHARES))]
    cross = "green" if main == "red" else "red"
    off = SIDE_CLEARANCE + 0.15  # the head's half width beyond the mast
    # (side, before the crossing, lamp lit, facing: main-road traffic along -s/+s, cross traffic -y/+y)
    for side, before, lit, yaw in ((-1, True, main, np.pi), (1, False, main, 0.0),
                                   (-1, False, cross, -np.pi / 2), (1, True, cross, np.pi / 2)):
        s = road.cross_s + (-1 if before else 1) * (road.cross_half_width + off)
        _signal(f, f.pose(side, s, off, yaw), lit)


def _bin(f: _Furnisher, side: int, s: float, colour) -> None:
    """A drum hung on the side of its post."""
    T = f.pose(side, s, SIDE_CLEARANCE + BIN_R)
    parts = [(mat, _posed(m, T)) for mat, m in _bin_local(f.road.curb_height, colour)]
    f.add(parts, lambda: _grown([m for _, m in parts], 0.05))


@functools.lru_cache(maxsize=64)
def _bin_local(ch: float, colour: tuple) -> tuple[tuple[Material, Shape], ...]:
    """A bin's post and drum in its own frame (made once per curb height and colour)."""
    return _frozen([(METAL, _column(0.0, 0.0, SIGN_POST_R, ch, ch + BIN_TOP + 0.1)),
                    (paint_material("bin", colour), _column(SIGN_POST_R + BIN_R, 0.0, BIN_R, ch + BIN_TOP - BIN_H,
                                                            ch + BIN_TOP))])


def _bollards(f: _Furnisher, side: int, s: float, n: int) -> None:
    """A row of n bollards along the curb from s, each with a white band below its top."""
    (post_mat, post), (band_mat, band) = _bollard_local(f.road.curb_height)
    parts = []
    for k in range(n):
        T = f.pose(side, s + k * BOLLARD_PITCH, SIDE_CLEARANCE + BOLLARD_R)
        parts += [(post_mat, _posed(post, T)), (band_mat, _posed(band, T))]
    f.add(parts, lambda: _grown([m for _, m in parts[::2]], 0.1))


@functools.lru_cache(maxsize=64)
def _bollard_local(ch: float) -> tuple[tuple[Material, Shape], ...]:
    """A bollard and its white band in its own frame (made once per curb height)."""
    return _frozen([(METAL, _column(0.0, 0.0, BOLLARD_R, ch, ch + BOLLARD_H)),
                    (SIGN_WHITE, _column(0.0, 0.0, BOLLARD_R + 0.003, ch + BOLLARD_H - 0.15, ch + BOLLARD_H - 0.08))])


def _stands(f: _Furnisher, side: int, s: float, n: int, bikes: np.random.Generator) -> None:
    """n cycle stands across the sidewalk from s: two legs and a top bar each; then, where the
    stands were placed, the bicycles parked at them (their own random stream: the furniture drawn
    after them stays where it was)."""
    ch, half = f.road.curb_height, STAND_L / 2
    parts = []
    for k in range(n):
        T = f.pose(side, s + k * STAND_PITCH, SIDE_CLEARANCE + half, np.pi / 2)
        parts += [(mat, _posed(m, T)) for mat, m in _stand_local(ch)]
    parked = []  # (stand, side of its bar, heading) of each bicycle
    for k in range(n):
        for gap in (-BIKE_GAP, BIKE_GAP):
            if bikes.uniform() < STAND_OCCUPANCY:
                parked.append((k, gap, np.pi / 2 if bikes.uniform() < 0.5 else -np.pi / 2))
    if not f.add(parts, lambda: _grown([m for _, m in parts], 0.1)):
        return
    for k, gap, yaw in parked:
        T = f.pose(side, s + k * STAND_PITCH + gap, SIDE_CLEARANCE + BIKE_L / 2, yaw)
        T[2, 3] += ch
        f.add_beside([(p.material, _posed(p.mesh, T)) for p in _parked_bicycle()], 0.05)


@functools.lru_cache(maxsize=64)
def _stand_local(ch: float) -> tuple[tuple[Material, Shape], ...]:
    """A cycle stand's two legs and top bar in its own frame (made once per curb height)."""
    r, h, half = STAND_R, STAND_H, STAND_L / 2
    return _frozen([(METAL, m) for m in (_box(-half, -half + 2 * r, -r, r, ch, ch + h),
                                         _box(half - 2 * r, half, -r, r, ch, ch + h),
                                         _box(-half, half, -r, r, ch + h - 2 * r, ch + h))])


@functools.cache
def _parked_bicycle() -> tuple[Part, ...]:
    """A bicycle BIKE_L long, scaled evenly (round wheels), origin on the ground at its middle."""
    parts = bicycle()
    v = np.concatenate([np.asarray(p.mesh.vertices) for p in parts])
    l, w, h = (v.max(axis=0) - v.min(axis=0)) * (BIKE_L / np.ptp(v[:, 0]))
    return tuple(fit_parts(parts, h, w, l))


def _furniture(road: RoadLayout, clutter: dict, seed: int, out: _Meshes) -> None:
    """Signals at the intersection, then signs, bins, bollards and cycle stands (with the bicycles
    parked at them) along both sidewalks, Poisson in number at the densities above times
    `clutter.furniture`."""
    scale = float(clutter.get("furniture", 0.0))  # scenery parameters from before it: none
    if scale <= 0:
        return
    rng = np.random.default_rng([seed, 4])
    bikes = np.random.default_rng([seed, 5])
    f = _Furnisher(road, out)
    if road.cross_s is not None:
        _signals(f, rng)
    length = (road.s_max - road.s_min) / 100.0
    for side in (-1, 1):
        for s in rng.uniform(road.s_min, road.s_max, rng.poisson(scale * SIGNS_PER_100M * length)):
            _sign(f, side, s, list(SIGNS)[int(rng.integers(len(SIGNS)))])
        for s in rng.uniform(road.s_min, road.s_max, rng.poisson(scale * BINS_PER_100M * length)):
            _bin(f, side, s, BIN_COLOURS[int(rng.integers(len(BIN_COLOURS)))])
        for s in rng.uniform(road.s_min, road.s_max, rng.poisson(scale * BOLLARD_ROWS_PER_100M * length)):
            _bollards(f, side, s, int(rng.integers(*BOLLARD_ROW)))
        groups = rng.poisson(scale * STAND_GROUPS_PER_100M * length)
        for s in rng.uniform(road.s_min, road.s_max, groups if road.sidewalk_width >= STAND_SIDEWALK else 0):
            _stands(f, side, s, int(rng.integers(*STAND_GROUP)), bikes)
