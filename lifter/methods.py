"""The lifting methods, declared once: name, what each needs and where its road comes from.

The command line, sweep axes, `testbed run`, the golden runner and the scan loading all read
`METHODS`. Listing them imports nothing (not even numpy); a method's code is imported when it runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Literal

if TYPE_CHECKING:
    import numpy as np

    from kitti.calib import Calibration

    from .types import Box2D, Lifted, Prior

FLAT_ROAD = (0.0, -1.0, 0.0, 1.65)  # camera 1.65 m above a level road (KITTI rig)


@dataclass(frozen=True)
class Frame:
    """What a method sees of one frame."""

    boxes: list[Box2D]
    priors: list[Prior]
    calib: Calibration
    image_size: tuple[int, int]
    velodyne: np.ndarray | None  # loaded only when the method reads it
    planes: np.ndarray | None  # planes/ (the road in rect coordinates) when the dataset has it


@dataclass(frozen=True)
class LiftMethod:
    name: str
    summary: str
    needs_scan: bool  # cannot run without velodyne/
    # where the road plane comes from: fitted to the scan; planes/ else KITTI's flat road;
    # planes/ else fitted to the scan
    road: Literal["scan", "planes", "planes-or-scan"]
    rig: Literal["any", "roadside"]  # the camera rigs it is meant for
    run: Callable[[Frame], list[Lifted]]

    def loads_scan(self, has_planes: bool) -> bool:
        return self.needs_scan or (self.road == "planes-or-scan" and not has_planes)


def _planes_road(f: Frame) -> np.ndarray:
    import numpy as np

    from .ground import normalise_plane

    return normalise_plane(f.planes) if f.planes is not None else np.array(FLAT_ROAD)


def _mono_box(box: Box2D, prior: Prior, calib: Calibration, size, plane) -> Lifted:
    """Deep3DBox with the road: the 2D box's sides plus the bottom centre on the road plane; a
    box cut on too many sides by the border may also use its border sides."""
    import numpy as np

    from .mono import contact_of, solve_from_alpha
    from .types import Lifted

    contact = contact_of(box.type)
    try:
        sol = solve_from_alpha(prior.dims, prior.alpha, box.bbox, calib, size, plane, contact=contact)
        return Lifted(sol.location, sol.rotation_y, np.asarray(prior.dims, dtype=float), 0.5)
    except ValueError:
        sol = solve_from_alpha(prior.dims, prior.alpha, box.bbox, calib, size, plane, cut_ok=True,
                               contact=contact)
        return Lifted(sol.location, sol.rotation_y, np.asarray(prior.dims, dtype=float), 0.3)


def _mono(f: Frame) -> list[Lifted]:
    road = _planes_road(f)
    return [_mono_box(b, p, f.calib, f.image_size, road) for b, p in zip(f.boxes, f.priors)]


def _roadside(f: Frame) -> list[Lifted]:
    from .ground import fit_ground_plane
    from .points import frame_points
    from .roadside import lift_roadside

    if f.planes is None and f.velodyne is None:
        raise ValueError("method 'roadside' needs the road plane (planes/) or velodyne/")
    road = (_planes_road(f) if f.planes is not None
            else fit_ground_plane(frame_points(f.velodyne, f.calib, None).rect))
    return lift_roadside(f.boxes, f.priors, f.calib, f.image_size, road)


def _frustum(f: Frame) -> list[Lifted]:
    """The thesis method; a box without enough returns falls back to `mono`."""
    from .frustum import lift_frustum
    from .points import frame_points

    road = _planes_road(f)
    found = lift_frustum(f.boxes, f.priors, frame_points(f.velodyne, f.calib, None), f.calib)
    return [hit if hit is not None else _mono_box(b, p, f.calib, f.image_size, road)
            for hit, b, p in zip(found, f.boxes, f.priors)]


def _fit(f: Frame) -> list[Lifted]:
    """The road plane from this frame's own returns, then the box fitted to the object's."""
    from .fit import lift_fit
    from .ground import fit_ground_plane
    from .points import frame_points

    pts = frame_points(f.velodyne, f.calib, None)
    road = fit_ground_plane(pts.rect)
    return lift_fit(f.boxes, f.priors, pts.with_plane(road), f.calib, f.image_size, road)


METHODS: dict[str, LiftMethod] = {m.name: m for m in (
    LiftMethod("frustum", "the thesis's frustum clustering (falls back to mono)", True, "planes",
               "any", _frustum),
    LiftMethod("fit", "a box fitted to the object's returns and the 2D box", True, "scan", "any",
               _fit),
    LiftMethod("mono", "image only: the 2D box's sides and the road plane", False, "planes", "any",
               _mono),
    LiftMethod("roadside", "mono for a fixed roadside camera", False, "planes-or-scan",
               "roadside", _roadside),
)}
SCAN_METHODS = tuple(n for n, m in METHODS.items() if m.needs_scan)


def get_method(name: str) -> LiftMethod:
    if name not in METHODS:
        raise ValueError(f"unknown lifting method '{name}' (one of {', '.join(METHODS)})")
    return METHODS[name]
