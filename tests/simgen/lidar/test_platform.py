"""The recording car under an onboard sensor (simgen.lidar.platform): the directions KITTI's own car
hides from its HDL-64E return nothing on an onboard rig, and everything else is untouched."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import trimesh

from simgen.lidar import preset, ray_table, scan
from simgen.lidar.platform import HIDDEN, hidden_rays
from simgen.rigs import onboard_rig
from simgen.world import Material, Part, Weather, World


def _ground_world(rig) -> World:
    """A flat, bright ground all around the sensor (1.73 m below it): every downward ray hits."""
    ground = trimesh.creation.box(bounds=[[-200, -200, -1.0], [200, 200, 0.0]])
    return World(actors=[], static=[Part(ground, Material("g", (0.5,) * 3, 0.8))],
                 weather=Weather(), lidar_pose=rig.reference_pose.copy(), rig=rig)


def _in(az_deg: np.ndarray, sectors) -> np.ndarray:
    return np.any([(az_deg >= a0) & (az_deg < a1) for a0, a1 in sectors], axis=0)


def test_hdl64e_hides_the_measured_sectors_of_each_laser():
    spec = preset("hdl64e")
    rays = ray_table(spec)
    hidden = hidden_rays(spec)
    az = np.degrees(rays.azimuth.astype(np.float64)) % 360.0
    for ring in range(spec.beams):
        on = rays.ring == ring
        expected = _in(az[on], HIDDEN[ring]) if ring in HIDDEN else np.zeros(on.sum(), bool)
        assert np.array_equal(hidden[on], expected)
    low = rays.ring == 63  # the bonnet ahead, the roof and boot behind; clear to the left
    assert hidden[low & (np.abs(az - 180.0) < 5)].all()
    assert hidden[low & ((az < 5) | (az > 355))].all()
    assert not hidden[low & (np.abs(az - 90.0) < 5)].any()


def test_other_layouts_take_the_nearest_kitti_laser():
    spec = preset("uniform", beams=16)  # +2 .. -24.9 degrees: its lowest beam is KITTI's lowest
    rays = ray_table(spec)
    hidden = hidden_rays(spec)
    az = np.degrees(rays.azimuth.astype(np.float64)) % 360.0
    low = rays.ring == spec.beams - 1
    assert np.array_equal(hidden[low], _in(az[low], HIDDEN[63]))
    assert not hidden[rays.ring == 8].any()  # about -12.5 degrees: nearest KITTI laser unhidden


def test_onboard_scan_loses_exactly_the_hidden_rays():
    spec = replace(preset("hdl64e"), dropout=0.0, noise_sigma=0.0, bias_sigma=0.0)
    rig = onboard_rig()
    rays = ray_table(spec)
    hidden = hidden_rays(spec)
    index = {(int(r), float(a)): i for i, (r, a) in enumerate(zip(rays.ring, rays.azimuth))}

    def ray_ids(world: World) -> np.ndarray:
        s = scan(world, spec, 0)
        return np.array([index[(int(r), float(a))] for r, a in zip(s.ring, s.azimuth)])

    onboard = ray_ids(_ground_world(rig))
    free = ray_ids(replace(_ground_world(rig), rig=None))  # the same sensor on no car
    assert not hidden[onboard].any()
    assert set(onboard.tolist()) == set(free[~hidden[free]].tolist())
    assert hidden[free].sum() > 1000  # without the car they return: the car is the only cause
