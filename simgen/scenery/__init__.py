"""Static scenery: road surface, lane markings, curbs, sidewalks, verges, buildings, trees, poles,
fences, street furniture (signs, signals, bins, bollards, cycle stands). A pure function of its
parameters (kept in `World.scenery` and in meta/), merged into one part per material so the
renderer and the LiDAR see few large meshes. The pieces are mostly plain vertices and faces
(simgen.meshes.Shape): a trimesh for each of the hundreds a frame cost ~30 ms.

How the pieces fit: `build_scenery` (here) builds one of two street models into a `_Meshes`
(simgen.scenery.parts: the shared mesh helpers, the cross street, `Obstacle`), then drapes the
merged parts onto the road's vertical profile.
- The first street model (simgen.scenery.street): carriageway, ground, markings and along each
  side a closed row of buildings (or a fence), trees and poles, from one random stream.
- With `clutter.frontage`, the frontage plan (simgen.scenery.frontage: the figures, the lots, side
  streets and car-park stalls, `plan_frontage`, which simgen.sample also reads to place actors)
  and the frontage world built on it (simgen.scenery.lots: each lot's buildings, planting and
  boundaries, side streets, ground, street trees and poles).
- Then, in both, the street furniture on the sidewalks (simgen.scenery.furniture), from its own
  random streams.
"""

from __future__ import annotations

import numpy as np
import shapely
import trimesh

# The scenery's materials at 905 nm and their sources: simgen.materials.
from ..materials import (ASPHALT, BARK, CONCRETE, FACADE_REFLECTIVITY, FENCE, FOLIAGE,  # noqa: F401
                         FOREST_FLOOR, MARKING, METAL, SAND, SHRUB_MASS, SIDEWALK, SIGN_BLUE, SIGN_RED,
                         SIGN_WHITE, SIGN_YELLOW, TRIM, VERGE, paint_material, signal_lens)
from ..meshes import Shape
from ..relief import drape_parts
from ..road import RoadLayout
from ..world import Part
from .frontage import plan_frontage
from .furniture import _furniture
from .lots import build_frontage
from .parts import ENVIRONMENTS, Obstacle, _Meshes
from .street import _buildings, _ground, fences, markings, poles, trees

# What other modules and the tests read from simgen.scenery.
from .frontage import (CLEAR_FOOTWAY, FRONT_YARD, GREEN_MARGIN, LAND_DEPTH, SHRUB_BELT_HEIGHT,  # noqa: F401
                       SHRUB_BELT_RADIUS, STALL_W, Frontage, Lot, _outer)
from .furniture import (BIKE_GAP, BIKE_L, SIDE_CLEARANCE, SIGN_LOWER_EDGE, SIGNS_PER_100M,  # noqa: F401
                        STAND_OCCUPANCY, STAND_PITCH, _Furnisher, _stands)
from .lots import POST_PITCH, POST_W, RAIL_DEPTH, RAIL_TOP  # noqa: F401
from .parts import MARK_Z, VERGE_WIDTH  # noqa: F401


def _merged(meshes: list[Shape | trimesh.Trimesh]) -> Shape:
    """One mesh of many: trimesh.util.concatenate's vertices and faces (stacked, faces offset)
    without its per-mesh type checks, visuals and metadata, which cost ~50 ms a frame."""
    starts = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    faces = np.concatenate([m.faces + start for m, start in zip(meshes, starts)])
    return Shape(np.concatenate([m.vertices for m in meshes]), faces)


def _static(out: _Meshes, road: RoadLayout) -> list[Part]:
    """The scenery's parts, one trimesh per material, laid onto the road (drape_parts makes the
    trimeshes of a road that is not flat, so none is made for the flat mesh before)."""
    parts = [Part(_merged(ms), mat) for mat, ms in out.by_mat.items()]
    if road.flat:
        return [Part(trimesh.Trimesh(*p.mesh, process=False), p.material) for p in parts]
    return drape_parts(parts, road)


def build_scenery(params: dict, plan: Frontage | None = None) -> tuple[list[Part], list[Obstacle]]:
    """Static parts (world frame) and their footprints, from the scenery parameters.

    Everything is planned on a flat road and then laid onto the road's vertical profile
    (`simgen.relief`); the footprints stay in plan view, their bases relative to the road.

    `params["keep_clear"]` (optional): a list of (x, y) polygon vertices where no building, tree
    or pole may stand, e.g. the line of sight of an orbit camera to its target. With
    `clutter.frontage` the sides are lots and side streets (plan_frontage, or `plan` where the
    caller has it already), else one closed row.
    """
    road = RoadLayout(**params["road"])
    clutter = params["clutter"]
    ground, buildings, tree_factor, woods = ENVIRONMENTS[clutter.get("environment", "city")]
    out = _Meshes([shapely.Polygon(params["keep_clear"])] if params.get("keep_clear") else [])
    plan = plan_frontage(params) if plan is None else plan
    if plan is not None:
        build_frontage(road, plan, clutter, ground, int(params["seed"]), out)
        _furniture(road, clutter, int(params["seed"]), out)
        return _static(out, road), out.obstacles
    rng = np.random.default_rng(params["seed"])
    _ground(road, ground, out)
    markings(road, out)
    # Buildings, trees, poles and fences along both sides: one side's draws, then the other's.
    for side in (-1, 1):
        curb = road.right_curb if side < 0 else road.left_curb
        outer = curb + side * road.sidewalk_width
        if clutter["buildings"] and buildings:
            _buildings(road, side, outer, clutter["building_setback"], rng, out)
        elif clutter["fences"]:  # where no buildings line the sidewalk
            fences(road, side, outer, out)
        trees(road, side, outer, tree_factor * clutter["trees_per_100m"], woods, rng, out)
        if clutter["pole_spacing"] > 0:
            poles(road, side, curb, clutter["pole_spacing"], rng, out)
    _furniture(road, clutter, int(params["seed"]), out)
    return _static(out, road), out.obstacles
