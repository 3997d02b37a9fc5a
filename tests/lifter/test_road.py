"""The road under an object from the scan (`lifter.road.LocalRoad`), on road returns laid by hand."""

import numpy as np

from lifter.road import FAR_WINDOW, WINDOWS, LocalRoad

FRAME = np.array([0.0, -1.0, 0.0, 1.65])  # the frame's plane: level, 1.65 m below the camera


def _grid(z0: float, z1: float, drop: float) -> np.ndarray:
    """Road returns (rect frame) every 0.25 m over x in [-6, 6], z in [z0, z1], `drop` m below the
    frame's plane."""
    x, z = np.meshgrid(np.arange(-6.0, 6.01, 0.25), np.arange(z0, z1 + 0.01, 0.25))
    return np.column_stack([x.ravel(), np.full(x.size, 1.65 + drop), z.ravel()])


def _height_at(plane: np.ndarray, x: float, z: float) -> float:
    """Height of the plane above the frame's plane at bird's-eye (x, z)."""
    y = -(plane[0] * x + plane[2] * z + plane[3]) / plane[1]
    return 1.65 - y


def test_far_road_between_sparse_rings_comes_from_the_stretched_window():
    """A sparse scan's road: near returns on the frame's plane, then only bands at 20-31 m and
    49-60 m, 0.15 m lower (the road falls away). At 40 m no square window holds road; the window
    stretched along the range reaches both bands and gives their height exactly, where the frame's
    plane would be 0.15 m off (3.6 m of image depth at 40 m)."""
    rect = np.vstack([_grid(5.0, 15.0, 0.0), _grid(20.0, 31.0, 0.15), _grid(49.0, 60.0, 0.15)])
    road = LocalRoad(rect, FRAME, np.zeros(2))
    assert road.is_road.all()
    assert 40.0 - WINDOWS[-1] > 31.0 and 40.0 + WINDOWS[-1] < 49.0  # no square holds road at 40 m
    assert 40.0 - FAR_WINDOW[1] < 31.0 and 40.0 + FAR_WINDOW[1] > 49.0
    plane = road.plane_at(0.0, 40.0)
    assert abs(_height_at(plane, 0.0, 40.0) + 0.15) < 1e-9
    assert abs(_height_at(plane, 3.0, 45.0) + 0.15) < 1e-9  # level: both bands lie at one height
    # inside a band the square windows decide, as before
    assert abs(_height_at(road.plane_at(0.0, 25.0), 0.0, 25.0) + 0.15) < 1e-9
    assert abs(_height_at(road.plane_at(0.0, 10.0), 0.0, 10.0)) < 1e-9
    # beyond the reach of every window: the frame's plane
    np.testing.assert_allclose(road.plane_at(0.0, 90.0), FRAME, atol=1e-12)
    # across, the stretched window stays within a lane or so of the object
    np.testing.assert_allclose(road.plane_at(FAR_WINDOW[0] + 6.5, 40.0), FRAME, atol=1e-12)
