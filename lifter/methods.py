"""The lifting methods, declared once: name, what each needs and where its road comes from.

The command line, sweep axes, `testbed run`, the golden runner and the scan loading all read
`METHODS`. Listing them imports nothing (not even numpy); a method's code is imported when it runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy as np

    from kitti.calib import Calibration

    from .types import Box2D, Lifted, Prior

FLAT_ROAD = (0.0, -1.0, 0.0, 1.65)  # without planes/ or a scan: the road 1.65 m below the camera,
                                   # level (KITTI's rig, Geiger et al. 2013, and the testbed's)
# How a 2D box outlines its object: "silhouette" (the generator's labels until it took up KITTI's
# convention, and a detector trained on them: the lowest point is where the nearest tyre meets the
# road) or "box" (KITTI's labels: the projection of the labelled 3D box stood upright in the LiDAR's
# frame, whose lowest point is a bottom corner; `mono.box_up_of`). `lifter.pipeline.box_outline`
# reads it from the labels.
OUTLINES = ("silhouette", "box")


@dataclass(frozen=True)
class Frame:
    """What a method sees of one frame."""

    boxes: list[Box2D]
    priors: list[Prior]
    calib: Calibration
    image_size: tuple[int, int]
    velodyne: np.ndarray | None  # loaded only when the method reads it
    planes: np.ndarray | None  # planes/ (the road in rect coordinates) when the dataset has it
    outline: str = "silhouette"  # one of OUTLINES


@dataclass(frozen=True)
class LiftMethod:
    name: str
    summary: str
    needs_scan: bool  # cannot run without velodyne/
    # where the road plane comes from: "scan": fitted to the scan (the frame's plane, then the
    # road near each object); "planes-or-scan": planes/ when present, else the scan's, else the
    # FLAT_ROAD prior
    road: Literal["scan", "planes-or-scan"]
    rig: Literal["any", "roadside"]  # the camera rigs it is meant for
    run: Callable[[Frame], list[Lifted]]

    def loads_scan(self, has_planes: bool) -> bool:
        return self.needs_scan or (self.road == "planes-or-scan" and not has_planes)


def _scan_road(f: Frame, pts=None):
    """The road of the scan (`road.scan_road`), from the frame's points when not given."""
    from .points import frame_points
    from .road import scan_road

    return scan_road(frame_points(f.velodyne, f.calib, None) if pts is None else pts)


def _road(f: Frame, pts=None):
    """planes/ when present, else the scan's road when there is a scan, else FLAT_ROAD."""
    import numpy as np

    from .road import FixedRoad

    if f.planes is not None:
        return FixedRoad(f.planes)
    if f.velodyne is not None:
        return _scan_road(f, pts)
    return FixedRoad(np.array(FLAT_ROAD))


def _mono_box(box: Box2D, prior: Prior, calib: Calibration, size, road, outline: str) -> Lifted:
    """Deep3DBox with the road: the 2D box's sides plus the bottom centre on the road plane found
    under the box's bottom edge; a box cut on too many sides by the border may also use its
    border sides. Where the 2D box is the 3D box's projection, its top then gives the height."""
    import numpy as np

    from .mono import box_up_of, contact_of, mono_quality, solve_weighing_alpha
    from .placement import height_from_box
    from .road import plane_under
    from .types import Lifted

    contact, up = contact_of(box.type, outline), box_up_of(outline, calib)
    plane = plane_under(road, box.centre[0], box.bbox[3], calib.P(2))
    try:
        sol = solve_weighing_alpha(prior.dims, prior.alpha, box.bbox, calib, size, plane,
                                   contact=contact, box_up=up)
        cut = 1.0
    except ValueError:  # cut by the border on too many sides
        sol = solve_weighing_alpha(prior.dims, prior.alpha, box.bbox, calib, size, plane,
                                   cut_ok=True, contact=contact, box_up=up)
        cut = 0.6
    quality = 0.5 * cut * mono_quality(sol, calib.P(2)[0, 0])
    dims = np.asarray(prior.dims, dtype=float).copy()
    dims[0] = height_from_box(sol.location, dims, sol.rotation_y, box.bbox, outline, size[1],
                              calib.P(2), up)
    return Lifted(sol.location, sol.rotation_y, dims, quality)


def _mono(f: Frame) -> list[Lifted]:
    road = _road(f)
    return [_mono_box(b, p, f.calib, f.image_size, road, f.outline)
            for b, p in zip(f.boxes, f.priors)]


def _roadside(f: Frame) -> list[Lifted]:
    from .roadside import lift_roadside

    if f.planes is None and f.velodyne is None:
        raise ValueError("method 'roadside' needs the road plane (planes/) or velodyne/")
    return lift_roadside(f.boxes, f.priors, f.calib, f.image_size, _road(f), f.outline)


def _frustum(f: Frame) -> list[Lifted]:
    """The thesis method; a box without enough returns falls back to `mono` on the road."""
    from .frustum import lift_frustum
    from .points import frame_points

    pts = frame_points(f.velodyne, f.calib, None)
    found = lift_frustum(f.boxes, f.priors, pts, f.calib)
    if all(hit is not None for hit in found):
        return found
    road = _road(f, pts)
    return [hit if hit is not None else _mono_box(b, p, f.calib, f.image_size, road, f.outline)
            for hit, b, p in zip(found, f.boxes, f.priors)]


def _fit(f: Frame) -> list[Lifted]:
    """The road from this frame's own returns, then the box fitted to the object's."""
    from .fit import lift_fit
    from .points import frame_points

    pts = frame_points(f.velodyne, f.calib, None)
    road = _scan_road(f, pts)
    return lift_fit(f.boxes, f.priors, pts, f.calib, f.image_size, road, outline=f.outline)


METHODS: dict[str, LiftMethod] = {m.name: m for m in (
    LiftMethod("frustum", "the thesis's frustum clustering (falls back to mono)", True,
               "planes-or-scan", "any", _frustum),
    LiftMethod("fit", "a box fitted to the object's returns and the 2D box", True, "scan", "any",
               _fit),
    LiftMethod("mono", "image only: the 2D box's sides and the road plane", False,
               "planes-or-scan", "any", _mono),
    LiftMethod("roadside", "mono for a fixed roadside camera", False, "planes-or-scan",
               "roadside", _roadside),
)}
SCAN_METHODS = tuple(n for n, m in METHODS.items() if m.needs_scan)


def get_method(name: str) -> LiftMethod:
    if name not in METHODS:
        raise ValueError(f"unknown lifting method '{name}' (one of {', '.join(METHODS)})")
    return METHODS[name]
