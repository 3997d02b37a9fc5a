"""Stop lamps lit by day (traffic.braking): which vehicles brake, what a lit lamp adds to the lit
look, and that nothing else in the image or the world moves."""

from __future__ import annotations

import os

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

from simgen.meta import world_from_meta, world_to_meta
from simgen.render import HEADROOM, STOP_LAMP, _Shader
from simgen.sample import sample_world
from simgen.spec import VEHICLE_CLASSES, spec_from_dict


def _spec(**traffic):
    return spec_from_dict({
        "name": "brake", "road": {"type": "straight", "lanes_per_direction": 2, "ego_lane": 1},
        "rig": {"type": "onboard", "ego_speed": 8.0},
        "light": {"time": "day", "sun_elevation_deg": 40.0, "sun_azimuth_deg": 150.0},
        "traffic": {"vehicles_per_100m": 3.0, "parking_occupancy": 0.3, **traffic}})


def _moving_vehicle(actor) -> bool:
    return actor.cls in VEHICLE_CLASSES and float(np.linalg.norm(actor.velocity)) > 0.5


def test_braking_lights_moving_vehicles_only_and_keeps_every_other_draw():
    plain, all_brake = sample_world(_spec(), 3, 0), sample_world(_spec(braking=1.0), 3, 0)
    assert [a.cls for a in plain.actors] == [a.cls for a in all_brake.actors]
    assert all(np.array_equal(a.pose, b.pose) and a.recipe == b.recipe
               for a, b in zip(plain.actors, all_brake.actors))
    assert not any(a.stop_lamps for a in plain.actors)
    moving = [_moving_vehicle(a) for a in all_brake.actors]
    assert sum(moving) >= 3 and sum(not m for m in moving) >= 3  # both kinds in the world
    assert [a.stop_lamps for a in all_brake.actors] == moving  # parked vehicles stay dark
    half = [a.stop_lamps for i in range(8) for a in sample_world(_spec(braking=0.5), 3, i).actors
            if _moving_vehicle(a)]
    n = len(half)  # binomial at p = 0.5: the bounds are 4 sd out
    assert n >= 40 and abs(sum(half) - n / 2) <= 2 * np.sqrt(n)


def test_meta_keeps_the_lit_lamps():
    world = sample_world(_spec(braking=0.5), 3, 1)
    back = world_from_meta(world_to_meta(world))
    assert [a.stop_lamps for a in back.actors] == [a.stop_lamps for a in world.actors]
    assert any(a.stop_lamps for a in world.actors) and not all(a.stop_lamps for a in world.actors)


def test_a_lit_lamp_adds_its_radiance_and_a_shadow_never_dims_it():
    world = sample_world(_spec(), 3, 0)
    shader = _Shader(world, np.zeros(3))
    albedo = np.array([[0.60, 0.02, 0.02], [0.30, 0.30, 0.30]])
    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    points = np.array([[10.0, 0.0, 0.5], [10.0, 0.0, 0.5]])
    glossy = np.zeros(2, bool)
    emitted = np.array([STOP_LAMP, (0.0, 0.0, 0.0)])
    dark = shader._lit(albedo, glossy, points, normals)
    lit = shader._lit(albedo, glossy, points, normals, emitted)
    np.testing.assert_array_equal(dark[1], lit[1])  # a point that emits nothing is untouched
    # By hand: the lamp face's diffuse radiance, then the lamp's on top (no channel clips).
    cos = max(float(normals[0] @ shader.sun), 0.0)
    total = cos * shader.sun_rgb * 0.96 * 0.96 / np.pi + shader.ambient * (0.7 + 0.3 * normals[0, 2])
    diffuse = albedo[0] * total
    np.testing.assert_allclose(dark[0, :3], (diffuse / HEADROOM) ** (1 / 2.2), rtol=1e-12)
    np.testing.assert_allclose(lit[0, :3], ((diffuse + STOP_LAMP) / HEADROOM) ** (1 / 2.2), rtol=1e-12)
    # The share of light that is not direct sun: the sky's in each channel, plus what it emits.
    sky = shader.ambient * (0.7 + 0.3 * normals[0, 2])
    share = (albedo[0] * sky + np.array(STOP_LAMP)) / (diffuse + np.array(STOP_LAMP))
    np.testing.assert_allclose(lit[0, 3], np.clip(share.mean(), 0, 1) ** (1 / 2.2), rtol=1e-12)
    assert lit[0, 3] > dark[0, 3]


@pytest.mark.skipif(os.environ.get("PYOPENGL_PLATFORM") != "egl", reason="needs off-screen EGL")
def test_lit_lamps_change_only_the_pixels_of_their_own_vehicles_and_redden_them():
    from simgen.render import render

    world = sample_world(_spec(braking=1.0, lead_vehicle=1.0, headway_s=1.0), 3, 0)
    lit = render(world)
    for a in world.actors:
        a.stop_lamps = False
    dark = render(world)
    np.testing.assert_array_equal(lit.instance, dark.instance)
    np.testing.assert_array_equal(lit.depth, dark.depth)
    changed = np.any(lit.color != dark.color, axis=2)
    braking = [a.id for a in world.actors if _moving_vehicle(a)]
    assert changed.sum() > 20  # the leader's lamps, 9 m ahead, cover many pixels
    # Shadows and lamps never bleed onto other objects: a changed pixel is a braking vehicle's or
    # borders one (the lamps wrap round the body's corner, onto its outline, and 4x MSAA blends an
    # outline pixel's samples of both sides); a pixel the lamp lights is redder.
    own = np.isin(lit.instance, braking)
    near = binary_dilation(own, structure=np.ones((3, 3), bool))
    assert near[changed].all() and own[changed].mean() > 0.9
    r, g = (c.astype(int) for c in (lit.color[changed][:, 0], lit.color[changed][:, 1]))
    r0, g0 = (c.astype(int) for c in (dark.color[changed][:, 0], dark.color[changed][:, 1]))
    assert np.all(r - g >= r0 - g0) and np.mean(r - r0) > 20
