"""The frontage plan (clutter.frontage): the figures its lots are built to, the lots of both sides,
the side streets and the car parks' stalls (plan_frontage). simgen.scenery.lots builds them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..road import RoadLayout
from .parts import ENVIRONMENTS


# --- Frontage (clutter.frontage): lots of several kinds behind each sidewalk --------------------
# The first street model stands one row of buildings `building_setback` behind each sidewalk: a
# closed box to the LiDAR (urban range p90 19 m against 24.5 m in real KITTI, 0.9 % of returns
# beyond 40 m against 2.7 %). With `clutter.frontage` each side is a sequence of lots, cut by side
# streets. The figures are German rules, guidelines and plans (KITTI was recorded in Karlsruhe,
# Baden-Wuerttemberg); where no published figure was found the comment says so.
#
# A lot is part of one block side. Block sides of gridded cities are 60-200 m and blocks 60-100 m
# deep, measured between street centre lines (Portland 80 x 80 m, Houston 100 x 100, Sacramento
# 120 x 120, Calgary 100 x 170, Edmonton 60 x 171; Wikipedia "City block"); one block side often
# holds more than one use, so a lot is 30-120 m long. Side streets: `side_streets_per_100m`.
LOT_LENGTH = (30.0, 120.0)
BLOCK_DEPTH = (60.0, 100.0)  # centre line of this street to that of the next, parallel one
LAND_DEPTH = 100.0  # m of land behind each sidewalk: a block and a half (VERGE_WIDTH without frontage)
SIDE_STREET_GAP = 20.0  # m of frontage at least between two side streets, or one and the cross street
# Detached houses. LBO BW section 5: a building keeps 0.4 x its wall height, at least 2.5 m, from
# every plot boundary. Footprints of one- and two-family houses: 8-14 m a side (no survey found;
# 100-200 m2 of floor on two storeys). Height of the box, between eaves and ridge: 6-11 m (ridge
# limits of 11 m are typical, e.g. Lalendorf B-plan No. 5).
HOUSE_LENGTH = (8.0, 14.0)
HOUSE_DEPTH = (8.0, 12.0)
HOUSE_HEIGHT = (6.0, 11.0)
BOUNDARY_MIN, BOUNDARY_SHARE = 2.5, 0.4
PLOT_SLACK = (0.0, 6.0)  # m of plot frontage beyond the LBO minimum: no survey found
# Front yards: building lines 3-5 m behind the street line (Lalendorf B-plan No. 5), 6-7 m where
# carports stand in front of the house (hausbau-forum.de on B-plans).
FRONT_YARD = (3.0, 7.0)
# Front-yard boundaries along the sidewalk: hedges planted at 1.0-1.5 m and kept at most 1.8 m
# (Hamburg B-plans; Nachbarrecht, Sennestadt design guide), fences and walls at most 1.2 m
# (Sennestadt design guide). No survey of their shares was found: hedge, fence, wall and none
# equally often. A gap of 3 m (path or drive) in each plot's boundary.
HEDGE_HEIGHT, HEDGE_DEPTH = (1.0, 1.8), (0.6, 1.0)
FENCE_HEIGHT = (0.8, 1.2)
WALL_HEIGHT = (0.5, 1.2)
BOUNDARIES = ("hedge", "fence", "wall", "none")
DRIVE_GAP = 3.0
# Side and rear plot boundaries: hedge, fence or wall, equally often (no survey found); the rear
# one 5-15 m behind the house (gardens: no survey found). LBO BW section 37: one parking space
# per dwelling; LBO BW section 6: garages up to 3 m high may stand in the boundary distance.
# Garage or open stall equally often (no survey found); a prefabricated single garage is 3 x 6 m;
# GaVO: 5 m of apron before its door.
BACK_GARDEN = (5.0, 15.0)
GARAGE, GARAGE_HEIGHT, GARAGE_APRON = (3.0, 6.0), (2.5, 3.0), 5.0
# Planting (Hamburg B-plans' requirements): at least one small-crowned tree per 150 m2 of unbuilt
# plot area, taken as the mean for gardens; one tree and three shrubs per 50 m2 of front yard,
# one plan's requirement where other front yards are lawn or paved: a lot gets a share U(0, 1).
YARD_M2_PER_TREE, YARD_SHRUBS_PER_TREE, GARDEN_M2_PER_TREE = 50.0, 3.0, 150.0
SHRUB_RADIUS = (0.5, 1.2)
# Open land: a mown lawn or a meadow, equally often (no survey found). Urban meadows are mown
# once or twice a year, the last cut from September on (Berlin Strassen- und Gruenflaechenamt;
# Bayerischer Rundfunk garden guide: end of September / October), so on KITTI's drives (26
# September - 3 October 2011) they stood near full height: 0.3-1.0 m. Park trees: at least one
# large-crowned tree per 300 m2 of unbuilt land (Hamburg B-plans' requirement), taken as the mean.
MEADOW_HEIGHT = (0.3, 1.0)
PARK_M2_PER_TREE = 300.0
# Trees (GALK street tree list: the common street trees grow 8-20 m tall with crowns 4-12 m
# wide; small-crowned garden trees 4-10 m tall, 3-6 m wide). Clearance under crowns: 2.5 m over
# footways, 4.5 m over the carriageway (Lichtraumprofil, RASt 06).
TREE_HEIGHT, CROWN_RADIUS = (8.0, 18.0), (2.0, 5.0)
SMALL_TREE_HEIGHT, SMALL_CROWN_RADIUS = (4.0, 10.0), (1.5, 3.0)
CLEAR_FOOTWAY, CLEAR_ROAD = 2.5, 4.5
# Garden trees branch lower: nursery grades of fruit and garden trees have clear stems of 1.0-1.6 m
# (half-standard) to 1.8-2.0 m (standard).
GARDEN_CROWN_BASE = (1.0, 2.0)
# Belts of trees and shrubs along the street (German "Gehoelzstreifen", "Strassenbegleitgruen"):
# a grass margin behind the sidewalk, then a closed mass of shrubs 2-5 m tall with small trees
# standing in it, 3-10 m deep, branched to the ground (hedgerows and roadside plantings are not
# pruned from 1 March to 30 September, BNatSchG section 39(5), so on KITTI's drives they stood
# in full leaf and growth). The sizes are typical of such plantings, not a survey. The LiDAR
# sees the shrubs as one closed leaf mass (simgen.materials.SHRUB_MASS).
GREEN_MARGIN, GREEN_DEPTH = (0.5, 2.0), (3.0, 10.0)
SHRUB_BELT_RADIUS, SHRUB_BELT_HEIGHT = (1.0, 2.5), (2.0, 5.0)
GREEN_M2_PER_TREE = 60.0  # one small tree among the shrubs per 60 m2 of belt: a judgement
# Car parks (EAR 05): perpendicular stalls 2.50 x 5.00 m, aisles 6.00 m; a module is two stall
# rows about an aisle, 1-2 modules deep, a 1.5 m planting strip before, between and after them
# with one small- to medium-crowned tree per 4-5 stalls (Hamburg and Reinbek B-plans); a store
# behind, one storey of 5-8 m (no survey found).
STALL_W, STALL_L, AISLE, PLANTING = 2.5, 5.0, 6.0, 1.5
STALLS_PER_TREE = 4.5
STORE_HEIGHT, STORE_DEPTH = (5.0, 8.0), (20.0, 40.0)
# Closed rows keep the first street model's buildings: 8-30 m long, 8-16 m deep, 5-20 m high.
ROW_LENGTH, ROW_DEPTH, ROW_HEIGHT = (8.0, 30.0), (8.0, 16.0), (5.0, 20.0)


@dataclass(frozen=True)
class Lot:
    """One stretch [s0, s1] of one side (-1 right, +1 left) given to one kind of lot; a car
    park's paved depth behind the sidewalk in `depth`."""

    side: int
    s0: float
    s1: float
    kind: str
    depth: float = 0.0


@dataclass
class Frontage:
    """The plan of the lots, side streets and car-park stalls: what sample.py needs to place
    actors, and what build_scenery meshes. A pure function of the scenery parameters."""

    lots: list[Lot]
    mouths: dict[int, list[tuple[float, float]]]  # per side: side streets' carriageways [s0, s1]
    stalls: list[np.ndarray]  # (4, 4) world poses, stall centre on the paving, x away from the road

    def in_mouth(self, side: int, s: float, margin: float = 0.0) -> bool:
        """Whether arc length s lies on a side street's carriageway on that side (widened)."""
        return any(a - margin <= s <= b + margin for a, b in self.mouths[side])


def _outer(road: RoadLayout, side: int) -> float:
    return (road.right_curb if side < 0 else road.left_curb) + side * road.sidewalk_width


def cut(spans: list[tuple[float, float]], a: float, b: float) -> list[tuple[float, float]]:
    out = []
    for lo, hi in spans:
        out += [(x, y) for x, y in ((lo, min(hi, a)), (max(lo, b), hi)) if y > x]
    return out


def plan_frontage(params: dict) -> Frontage | None:
    """The lots of both sides, or None when the spec keeps the first street model."""
    clutter = params["clutter"]
    mix = {k: float(w) for k, w in sorted((clutter.get("frontage") or {}).items()) if w > 0}
    if not (mix and clutter["buildings"] and ENVIRONMENTS[clutter.get("environment", "city")][1]):
        return None
    road = RoadLayout(**params["road"])
    rng = np.random.default_rng([int(params["seed"]), 1])
    kinds, p = list(mix), np.array(list(mix.values()))
    lo, hi = road.s_min - 10.0, road.s_max + 10.0
    sw, street = road.sidewalk_width, 2.0 * road.lane_width  # side streets: a lane each way
    lots, mouths, stalls = [], {-1: [], 1: []}, []
    for side in (-1, 1):
        taken = [] if road.cross_s is None else [(road.cross_s - road.cross_half_width - sw,
                                                  road.cross_s + road.cross_half_width + sw)]
        rate = float(clutter.get("side_streets_per_100m", 0.0))
        for s in np.sort(rng.uniform(road.s_min + 10.0, road.s_max - 10.0,
                                     rng.poisson(rate * (road.s_max - road.s_min) / 100.0))):
            a, b = s - street / 2, s + street / 2
            if all(b + sw + SIDE_STREET_GAP < t0 or a - sw - SIDE_STREET_GAP > t1 for t0, t1 in taken):
                mouths[side].append((float(a), float(b)))
                taken.append((a - sw, b + sw))
        spans = [(lo, hi)]
        for a, b in taken:
            spans = cut(spans, a, b)
        for s0, s1 in spans:
            s = s0
            while s < s1:
                end = min(s + rng.uniform(*LOT_LENGTH), s1)
                if s1 - end < LOT_LENGTH[0] / 2:
                    end = s1
                kind = kinds[int(rng.choice(len(kinds), p=p / p.sum()))]
                lot = Lot(side, float(s), float(end), kind)
                if kind == "car_park":
                    lot, lot_stalls = _car_park_plan(road, lot, rng)
                    stalls += lot_stalls
                lots.append(lot)
                s = end
    return Frontage(lots, mouths, stalls)


def _car_park_plan(road: RoadLayout, lot: Lot, rng: np.random.Generator) -> tuple[Lot, list[np.ndarray]]:
    """1-2 modules of two stall rows about an aisle; the stalls' poses (x away from the road)."""
    side, outer, k = lot.side, _outer(road, lot.side), road.curvature
    modules = int(rng.integers(1, 3))
    module = 2 * STALL_L + AISLE
    stalls = []
    for m in range(modules):
        q0 = PLANTING + m * (module + PLANTING)
        for q in (q0 + STALL_L / 2, q0 + STALL_L + AISLE + STALL_L / 2):
            d = outer + side * q
            pitch = STALL_W / (1.0 - k * d)  # arc length at offset d is (1 - k d) ds
            for s in np.arange(lot.s0 + 3.0 + pitch / 2, lot.s1 - 3.0 - pitch / 2, pitch):
                stalls.append(road.pose(float(s), d, road.curb_height, side * np.pi / 2))
    depth = PLANTING + modules * (module + PLANTING)
    return Lot(lot.side, lot.s0, lot.s1, lot.kind, depth), stalls
