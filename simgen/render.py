"""Off-screen camera: colour, depth and instance ids of a world through its rig, with pyrender.

One OffscreenRenderer per worker process, reused across frames (EGL; Mesa's llvmpipe on a
machine without a GPU). Two passes per frame: first the instance pass (simgen.instance_pass),
without multisampling, sampled at pixel centres, which names the triangle seen at each pixel:
its actor gives the instance map, its depth the depth image; then the lit colour pass (4x MSAA),
which leaves out the triangles the instance pass shows no sample of it can see
(simgen.occlusion), with the same bytes. In the instance pass each actor is one draw call (its
parts merged); in the lit colour pass all actors together are one draw call per texture they
wear (glass, plates, paint) and one for the rest (BuiltScene), as the static world is one per
texture.

The lit looks (day, dusk) are shaded per face on the CPU and drawn unlit (see _Shader); on top
of that the surfaces wear procedural textures (simgen.textures) mapped from world coordinates,
and on the actors' glass, plates and paint mapped per part (_texture_coordinates),
the sky is a dome with a gradient and clouds, car paint and glass mirror the sky with Fresnel's
reflectance, and the sun casts shadows (simgen.shadows) from the same meshes the LiDAR sees;
actors also hide part of the sky from the ground under and beside them (skylight occlusion).
The colour pass keeps HEADROOM over the unit of radiance so that the camera (simgen.camera),
not the 8-bit framebuffer, decides what saturates.

Exact camera: the real KITTI rectified camera 2 is not a rigid transform of the world (R0_rect
times Tr_velo_to_cam is orthonormal only to ~1e-4). The camera node gets the nearest rigid pose
(for lighting) and the projection matrix absorbs the small residual, so every pixel lands where
P2 puts it. pyrender puts pixel centres at u + 0.5; KITTI at integer u: the principal point is
shifted by half a pixel to match.
"""

from __future__ import annotations

import ctypes
import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from collections.abc import Callable, Iterable, MutableSet  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from functools import cache  # noqa: E402

import cv2  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402
import pyrender  # noqa: E402
from OpenGL import GL  # noqa: E402
from pyrender.constants import ProgramFlags, RenderFlags  # noqa: E402

from . import facets, instance_pass, occlusion, textures  # noqa: E402
from .camera import LUMA  # noqa: E402
from .factors import factor_rng  # noqa: E402
from .meshes import EMISSIVE  # noqa: E402
from .shadows import Occluders, Reach, SplitCasters, WorldScene, sky_occlusion, sun_shadow  # noqa: E402
from .texture_layout import FACADE_KINDS, StaticLayout, Wearing, facade_uv, static_layout  # noqa: E402
from .world import Part, World  # noqa: E402

ZNEAR, ZFAR = 0.3, 400.0
_F = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenGL camera axes <-> computer-vision camera axes

SKY = {"day": (0.62, 0.74, 0.90), "dusk": (0.55, 0.42, 0.38), "night": (0.015, 0.015, 0.025)}
# Skylight against the sun: on a clear day the diffuse share of the global horizontal irradiance is
# 0.1-0.2 with the sun above 30 deg (Erbs et al. 1982 correlation at clearness index > 0.8: 0.165);
# 0.2 / (0.2 + 1.17 sin 45 deg) = 0.19.
AMBIENT = {"day": 0.2, "dusk": 0.18, "night": 0.02}
SUN = {"day": (1.0, 0.97, 0.92), "dusk": (1.0, 0.62, 0.38), "night": (0.4, 0.45, 0.6)}
SUN_POWER = {"day": 4.0, "dusk": 2.0, "night": 0.08}
# Linear radiance the lit colour pass can hold, in units of a white surface under the sky alone
# plus the sun's diffuse term at normal incidence (which reaches 1.6 at noon): room for sunlit
# white and bright cloud before the camera's exposure decides what clips.
HEADROOM = 2.0
# Sky radiance on the same scale: clear sky is a quarter to a half of the luminance of sunlit
# white paper (zenith about 4,000-8,000 cd/m2, sunlit white about 30,000), brightest near the
# horizon (haze); sunlit cumulus is about as bright as sunlit white.
SKY_ZENITH, SKY_HORIZON, CLOUD = (0.30, 0.42, 0.75), (0.62, 0.68, 0.78), (1.45, 1.45, 1.45)
# Clear coat and glass: Fresnel reflectance at normal incidence for n = 1.5 (((n-1)/(n+1))^2),
# Schlick's approximation at other angles; the sun's highlight on them, Blinn-Phong.
GLOSSY = {"paint", "glass", "headlight", "taillight"}
F0 = 0.04
# Stop lamps lit by day (Actor.stop_lamps): ECE R7 asks 60 to 185 cd of a stop lamp; their geometric
# mean, 105 cd, over a car's rear lamp face (0.28 x 0.20 m, simgen.meshes.TAIL_LAMP_*) is about
# 1,900 cd/m2. On this look's scale sunlit white, about 30,000 cd/m2 (SKY_ZENITH's note), is 1.5,
# so one unit is about 20,000 cd/m2: 0.094 in luminance, all of it in the red primary (luminance
# 0.2126 R).
STOP_LAMP = (105.0 / (0.28 * 0.20) / 20000.0 / 0.2126, 0.0, 0.0)
HIGHLIGHT_EXPONENT = 300.0
GROUND_RADIANCE = 0.08  # what a glossy face mirrors below the horizon (dark ground)

# Thermal emulation ("white hot", 0..1): a temperature per material; moving vehicles run warm.
TEMPERATURE = {"asphalt": 0.42, "marking": 0.40, "curb": 0.38, "sidewalk": 0.38, "verge": 0.30,
               "sand": 0.55, "forest_floor": 0.27, "facade": 0.33, "bark": 0.30, "foliage": 0.24,
               "pole": 0.28, "fence": 0.30, "sign_white": 0.30, "sign_yellow": 0.30, "sign_red": 0.30,
               "sign_blue": 0.30, "signal_lens": 0.60, "bin": 0.32,
               "paint": 0.45, "trim": 0.45, "rim": 0.50, "glass": 0.28, "tyre": 0.55, "plate": 0.42,
               "headlight": 0.80, "taillight": 0.70, "bike_frame": 0.40, "skin": 0.97, "clothes": 0.78,
               "hair": 0.78, "shoes": 0.78,  # they cover the body as clothes do
               "user": 0.50}
_WARM_WHEN_MOVING = {"tyre": 0.30, "paint": 0.10}


@dataclass
class RenderOutput:
    color: np.ndarray  # (H, W, 3) uint8 RGB, gamma-encoded radiance / headroom, before simgen.look
    depth: np.ndarray  # (H, W) float32 camera-2 z in metres, 0 where no surface
    instance: np.ndarray  # (H, W) uint16 actor id, 0 = background
    headroom: float = 1.0  # linear radiance of a colour value of 255


@dataclass
class Casters:
    """What can darken the lit colour pass: the static world's and the actors' triangles
    (world frame), and where each actor can hide the sky."""

    static: Occluders
    actors: Occluders
    reach: Reach
    world: WorldScene | None = None  # the LiDAR's scene of this world, where it has one

    def every(self) -> Occluders:
        return Occluders.join(self.static, self.actors)

    def sun(self) -> Occluders | SplitCasters:
        """What casts the sun's shadows: every triangle in a scene of its own, or where the LiDAR's
        scene of the world is at hand, that scene for the static world (no second build of it)."""
        return self.every() if self.world is None else SplitCasters(self.world, self.static, self.actors)


class _ExactCamera(pyrender.IntrinsicsCamera):
    """An intrinsics camera whose projection also applies a fixed near-identity 4x4 residual."""

    def __init__(self, K: np.ndarray, residual_gl: np.ndarray):
        super().__init__(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2] + 0.5, cy=K[1, 2] + 0.5,
                         znear=ZNEAR, zfar=ZFAR)
        self.residual_gl = residual_gl

    def get_projection_matrix(self, width=None, height=None):
        return super().get_projection_matrix(width, height) @ self.residual_gl


# Pixels beyond an image side that a face must reach to be drawn: the multisampled pass's samples
# lie within their pixels, so one would do; two leave room for rounding.
VIEW_MARGIN_PX = 2.0


@dataclass(frozen=True)
class _View:
    """The camera's view volume as five planes (world frame): near, left, right, top, bottom.

    The world reaches all round the sensor (the LiDAR's 360 deg), the camera looks one way (on
    urban.yaml about half the faces could reach a pixel, results/simgen.md): the colour and
    instance passes leave out every face that lies wholly outside one plane of the volume
    (behind the near plane, or VIEW_MARGIN_PX beyond an image side). Such a face has no fragment
    in the volume, a convex set, so the same pixels come out as with it, at less to upload and
    rasterize; shadow casters and the LiDAR keep every face."""

    planes: np.ndarray  # (5, 4): a point p lies outside plane k where planes[k] @ (p, 1) < 0

    @staticmethod
    def of(K: np.ndarray, cam2_from_world: np.ndarray, width: int, height: int) -> _View:
        m = 0.5 + VIEW_MARGIN_PX  # pixel centres at integers: the image spans -0.5 to W - 0.5
        z = np.array([0.0, 0.0, 1.0])
        cam = np.array([[*z, -ZNEAR], [*(K[0] + m * z), 0.0], [*((width - 1 + m) * z - K[0]), 0.0],
                        [*(K[1] + m * z), 0.0], [*((height - 1 + m) * z - K[1]), 0.0]])
        return _View(cam @ cam2_from_world)

    def faces(self, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(F,) bool: which triangles may reach a pixel, of world-frame `vertices` (V, 3) and
        `faces` (F, 3) indexing them."""
        return ~facets.beyond(vertices, faces, self.planes)


_RENDERERS: dict[tuple[int, int, int], pyrender.OffscreenRenderer] = {}


class _InsertionOrdered(MutableSet):
    """A set that iterates in the order its items were added."""

    def __init__(self, items: Iterable = ()):
        self._items = dict.fromkeys(items)

    def __contains__(self, item) -> bool:
        return item in self._items

    def __iter__(self):
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def add(self, item) -> None:
        self._items[item] = None

    def discard(self, item) -> None:
        self._items.pop(item, None)


class _Scene(pyrender.Scene):
    """A pyrender.Scene whose mesh and light nodes iterate in the order they were added. The
    renderer draws mesh nodes farthest first and, among nodes at one distance, in this order, and
    sums lights in it: in a plain set both changed from run to run (an orbit view's target car
    stands at the origin with the static world, whose road its tyres touch at one depth)."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._mesh_nodes = _InsertionOrdered()
        self._point_light_nodes = _InsertionOrdered()
        self._spot_light_nodes = _InsertionOrdered()
        self._directional_light_nodes = _InsertionOrdered()


class _ColourRenderer(pyrender.Renderer):
    """pyrender's renderer for the colour pass alone (the instance pass gives the depth): it
    resolves and reads the colour buffer as pyrender does, and leaves the depth buffer unread.
    `meanwhile`, where set, runs after the draws are sent and before the read, while llvmpipe's
    threads rasterize; its result is kept in `meanwhile_result`."""

    meanwhile: Callable[[], object] | None = None
    meanwhile_result: object = None
    _identity: int | None = None  # one buffer of the identity instance matrix, for every primitive

    def _update_context(self, scene, flags):
        """pyrender's upload of the scene's meshes and textures, each primitive's vertices
        interleaved by one copy into one buffer (pyrender's layout) and the identity instance
        matrix shared; the process's texture tiles (_textured) stay on the GPU when a frame
        does not use them."""
        meshes = scene.meshes
        for mesh in meshes - self._meshes:
            for p in mesh.primitives:
                self._upload(p)
        for mesh in self._meshes - meshes:
            for p in mesh.primitives:
                p.delete()
        self._meshes = meshes.copy()
        used = {t for m in meshes for p in m.primitives for t in p.material.textures}
        for texture in used - self._mesh_textures:
            if texture._texid is None:
                texture._add_to_context()
        for texture in self._mesh_textures - used:
            if texture not in _TILES:
                texture.delete()
        self._mesh_textures = used | (self._mesh_textures & _TILES)

    def _upload(self, p: pyrender.Primitive) -> None:
        if p.normals is not None or p.tangents is not None or p.texcoord_1 is not None or p.poses is not None:
            p._add_to_context()
            return
        columns = [a for a in (p.positions, p.texcoord_0, p.color_0) if a is not None]
        data = np.empty((len(p.positions), sum(a.shape[1] for a in columns)), np.float32)
        first = 0
        for a in columns:
            data[:, first:first + a.shape[1]] = a
            first += a.shape[1]
        p._vaid = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(p._vaid)
        p._buffers = [GL.glGenBuffers(1)]
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, p._buffers[0])
        GL.glBufferData(GL.GL_ARRAY_BUFFER, data.nbytes, data, GL.GL_STATIC_DRAW)
        offset = 0
        for i, a in enumerate(columns):
            GL.glVertexAttribPointer(i, a.shape[1], GL.GL_FLOAT, GL.GL_FALSE, data.strides[0],
                                     ctypes.c_void_p(4 * offset))
            GL.glEnableVertexAttribArray(i)
            offset += a.shape[1]
        if self._identity is None:
            self._identity = GL.glGenBuffers(1)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._identity)
            GL.glBufferData(GL.GL_ARRAY_BUFFER, 64, np.eye(4, dtype=np.float32), GL.GL_STATIC_DRAW)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._identity)
        for i in range(4):
            GL.glEnableVertexAttribArray(len(columns) + i)
            GL.glVertexAttribPointer(len(columns) + i, 4, GL.GL_FLOAT, GL.GL_FALSE, 64, ctypes.c_void_p(16 * i))
            GL.glVertexAttribDivisor(len(columns) + i, 1)
        GL.glBindVertexArray(0)

    def _forward_pass(self, scene, flags, seg_node_map=None):
        """pyrender's forward pass, for the flat looks with one program bound, the camera's
        uniforms set and the state of pyrender's materials here (opaque, double-sided, filled)
        once per program rather than once per primitive: the same draws, uniforms and state."""
        if not flags & RenderFlags.FLAT or flags & RenderFlags.SEG:
            return super()._forward_pass(scene, flags, seg_node_map)
        self._configure_forward_pass_viewport(flags)
        GL.glClearColor(*scene.bg_color)
        GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
        GL.glEnable(GL.GL_MULTISAMPLE)
        GL.glEnable(GL.GL_BLEND)
        GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
        V, P = self._get_camera_matrices(scene)
        program = None
        for node in self._sorted_mesh_nodes(scene):
            if not node.mesh.is_visible:
                continue
            pose = scene.get_pose(node)
            for primitive in node.mesh.primitives:
                material = primitive.material
                if not material.doubleSided or material.alphaMode == "BLEND" or material.wireframe:
                    raise ValueError("the flat colour pass draws opaque, double-sided, filled materials")
                chosen = self._get_primitive_program(primitive, flags, ProgramFlags.USE_MATERIAL)
                if chosen is not program:
                    program = chosen
                    program._bind()
                    program.set_uniform("V", V)
                    program.set_uniform("P", P)
                program.set_uniform("M", pose)
                primitive._bind()
                if material.baseColorTexture is not None:
                    GL.glActiveTexture(GL.GL_TEXTURE0)
                    material.baseColorTexture._bind()
                    program.set_uniform("material.base_color_texture", 0)
                program.set_uniform("material.base_color_factor", material.baseColorFactor)
                GL.glDrawArraysInstanced(primitive.mode, 0, len(primitive.positions), 1)
        GL.glBindVertexArray(0)
        if program is not None:
            program._unbind()
        GL.glFlush()
        return self._read_main_framebuffer(scene, flags)

    def _read_main_framebuffer(self, scene, flags):
        if self.meanwhile is not None:
            GL.glFlush()
            self.meanwhile_result = self.meanwhile()
        width, height = self._main_fb_dims
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb_ms)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
        GL.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL.GL_COLOR_BUFFER_BIT, GL.GL_LINEAR)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb)
        channels, fmt = (4, GL.GL_RGBA) if flags & RenderFlags.RGBA else (3, GL.GL_RGB)
        color = GL.glReadPixels(0, 0, width, height, fmt, GL.GL_UNSIGNED_BYTE)
        return np.flip(np.frombuffer(color, np.uint8).reshape(height, width, channels), axis=0), None


def renderer(width: int, height: int) -> pyrender.OffscreenRenderer:
    """The process's renderer for this image size, created once, drawing colour passes only.
    Keyed by process id too: a forked child must not reuse its parent's GL context."""
    key = (os.getpid(), width, height)
    if key not in _RENDERERS:
        r = pyrender.OffscreenRenderer(width, height)
        r._renderer.__class__ = _ColourRenderer
        _RENDERERS[key] = r
    return _RENDERERS[key]


def software(r: pyrender.OffscreenRenderer) -> bool:
    """Whether `r` draws on Mesa's llvmpipe. The occlusion culling's margins are llvmpipe's
    (its float32 set-up and 24-bit depth): on another driver (a GPU's EGL) every triangle is drawn,
    which a GPU does at little cost."""
    if not hasattr(r, "_software"):
        r._platform.make_current()
        r._software = b"llvmpipe" in (GL.glGetString(GL.GL_RENDERER) or b"")
        r._platform.make_uncurrent()
    return r._software


def camera_node_pose(cam2_from_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(world-from-GL-camera rigid pose, GL residual) that together reproduce cam2_from_world."""
    U, _, Vt = np.linalg.svd(cam2_from_world[:3, :3])
    rigid = np.eye(4)
    rigid[:3, :3] = U @ Vt
    rigid[:3, 3] = cam2_from_world[:3, 3]
    residual_cv = cam2_from_world @ np.linalg.inv(rigid)
    return np.linalg.inv(rigid) @ _F, _F @ residual_cv @ _F


_PLAIN = pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0), metallicFactor=0.0,
                                            roughnessFactor=0.9, doubleSided=True)
# pyrender's diffuse term for a white base: (1 - F) c_diff / pi with F ~ 0.04, c_diff = 0.96.
_DIFFUSE = 0.96 * 0.96 / np.pi
_TEXTURED: dict[tuple[int, str, int], pyrender.MetallicRoughnessMaterial] = {}
_TILES: set[pyrender.Texture] = set()  # their textures


def _textured(kind: str, variant: int) -> pyrender.MetallicRoughnessMaterial:
    """The process's material for one texture tile, made once: pyrender keeps a texture in the
    GL context for as long as consecutive scenes use the same object."""
    key = (os.getpid(), kind, variant)
    if key not in _TEXTURED:
        tex = pyrender.Texture(source=textures.tile(kind, variant), source_channels="RGB")
        _TILES.add(tex)
        _TEXTURED[key] = pyrender.MetallicRoughnessMaterial(baseColorTexture=tex, metallicFactor=0.0,
                                                            roughnessFactor=0.9, doubleSided=True)
    return _TEXTURED[key]


def _primitive(tris: np.ndarray, normals: np.ndarray | None, rgba: np.ndarray | None, material,
               uv: np.ndarray | None = None) -> pyrender.Primitive:
    """Faces with their vertices unshared, a colour per face (F, 4) or per corner (F, 3, 4), or
    none (drawn by the instance pass only). Normals only where pyrender lights per pixel (None
    under its flat shader, which never reads them: less to upload)."""
    return pyrender.Primitive(
        positions=tris.reshape(-1, 3).astype(np.float32),
        normals=None if normals is None else np.repeat(normals, 3, axis=0).astype(np.float32),
        color_0=None if rgba is None else
        (np.repeat(rgba, 3, axis=0) if rgba.ndim == 2 else rgba.reshape(-1, 4)).astype(np.float32),
        texcoord_0=None if uv is None else uv.reshape(-1, 2).astype(np.float32), material=material)


def _to_sun(light) -> np.ndarray:
    el, az = np.radians(light.sun_elevation_deg), np.radians(light.sun_azimuth_deg)
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def _sky_radiance(up: np.ndarray) -> np.ndarray:
    """(N, 3) clear-sky radiance for directions of height `up` (sine of the elevation)."""
    t = np.clip(up, 0.0, 1.0)[:, None] ** 0.5
    return np.asarray(SKY_HORIZON) * (1 - t) + np.asarray(SKY_ZENITH) * t


class _Shader:
    """Face colours for the three looks.

    'lit' (day, dusk): Lambertian sun plus a sky term brighter on upward faces, evaluated per
    face on the CPU and gamma-encoded, then drawn with pyrender's unlit shader: 5-7x faster
    on llvmpipe than its per-pixel PBR shader, and the same picture for flat-shaded diffuse
    surfaces. Glossy faces (paint, glass, lamps) add the sky or ground they mirror (Fresnel,
    Schlick) and the sun's highlight. The alpha channel carries each face's share of light that
    is not direct sun (gamma-encoded): what is left where a shadow falls (simgen.shadows).
    'pbr' (night): albedo only; pyrender lights per pixel, as the headlamp cones need.
    'thermal': a temperature per material, unlit.
    """

    def __init__(self, world: World, eye: np.ndarray):
        light = world.light
        self.mode = ("thermal" if world.sensor == "thermal"
                     else "pbr" if light.time == "night" else "lit")
        self.sun = _to_sun(light)
        self.sun_rgb = np.asarray(SUN[light.time]) * SUN_POWER[light.time] * light.sun_intensity
        self.ambient = AMBIENT[light.time]
        self.eye = eye
        self.headroom = HEADROOM if self.mode == "lit" else 1.0

    def colors(self, parts: list[Part], tris: np.ndarray, normals: np.ndarray, moving: bool,
               albedo_gain: np.ndarray | None = None, corner_normals: np.ndarray | None = None,
               glow: np.ndarray | None = None, only: np.ndarray | None = None) -> np.ndarray:
        """(F, 4) RGBA of all faces of the parts (world-frame triangles and normals), in
        _triangles order, or with `only` (a mask over them) of those faces alone; with
        `corner_normals` (F, 3, 3) the lit look shades each corner of each face with its own
        normal, (F, 3, 4), and the rasteriser blends them across the face. `glow` (P, 3): the
        linear radiance each part emits (lit look only; lit stop lamps)."""
        pick = (lambda a: a) if only is None else (lambda a: a[only])
        owner = pick(np.repeat(np.arange(len(parts)), [len(p.mesh.faces) for p in parts]))  # each face's part
        if self.mode == "thermal":
            rgb = np.array([_thermal(p, moving) for p in parts])[owner]
            return np.c_[rgb, np.ones(len(rgb))]
        albedo = np.array([p.material.color for p in parts], float)[owner]
        if albedo_gain is not None:
            albedo = albedo * albedo_gain[owner]
        if self.mode == "pbr":
            return np.c_[albedo, np.ones(len(albedo))]
        glossy = np.array([p.material.name in GLOSSY for p in parts])[owner]
        emitted = None if glow is None else glow[owner]
        tris, normals = pick(tris), pick(normals)
        if corner_normals is None:
            centres = (tris[:, 0] + tris[:, 1] + tris[:, 2]) / 3  # the mean over corners, in its order
            return self._lit(albedo, glossy, centres, normals, emitted)
        rgba = self._lit(np.repeat(albedo, 3, axis=0), np.repeat(glossy, 3), tris.reshape(-1, 3),
                         pick(corner_normals).reshape(-1, 3),
                         None if emitted is None else np.repeat(emitted, 3, axis=0))
        return rgba.reshape(-1, 3, 4)

    def _lit(self, albedo: np.ndarray, glossy: np.ndarray, points: np.ndarray,
             normals: np.ndarray, emitted: np.ndarray | None = None) -> np.ndarray:
        """(N, 4) gamma-encoded RGB and the share of light that is not direct sun, of N surface
        points of the given albedo and normal, and (N, 3) emitted radiance if any: a shadow
        never dims what a point emits."""
        totals, share = self._skylight(normals)
        lin = np.empty((len(normals), 3))
        for c in range(3):  # channel by channel: numpy's loops run over all points, not 3 channels
            lin[:, c] = albedo[:, c] * totals[c]
        shiny = np.flatnonzero(glossy)
        if len(shiny):
            lin[shiny] += self._mirror(np.take(points, shiny, axis=0), np.take(normals, shiny, axis=0))
        lamps = np.zeros(0, int) if emitted is None else np.flatnonzero(emitted.any(axis=1))
        if len(lamps):  # each channel's emitted part counts as light that is not direct sun
            e, lit = emitted[lamps], lin[lamps]
            for c in range(3):
                total = np.maximum(lit[:, c] + e[:, c], 1e-9)
                share[c][lamps] = (share[c][lamps] * lit[:, c] + e[:, c]) / total
            lin[lamps] += e
        rest = (share[0] + share[1] + share[2]) / 3  # the mean over channels, in its order
        out = np.empty((len(lin), 4))
        out[:, :3] = np.clip(lin / self.headroom, 0.0, 1.0) ** (1 / 2.2)
        out[:, 3] = np.clip(rest, 0.0, 1.0) ** (1 / 2.2)
        return out

    def _skylight(self, normals: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Per channel, of N surface points of unit albedo: the light received (sun and sky) and
        the share of it that is not direct sun."""
        cos = np.clip(normals @ self.sun, 0.0, 1.0)
        sky = self.ambient * (0.7 + 0.3 * normals[:, 2])
        totals, share = [], []
        for c in range(3):  # channel by channel: numpy's loops run over all points, not 3 channels
            totals.append(cos * self.sun_rgb[c] * _DIFFUSE + sky)
            share.append(sky / np.maximum(totals[c], 1e-9))
        return totals, share

    def alpha(self, normals: np.ndarray) -> np.ndarray:
        """(N,) the alpha `colors` gives faces of these unit normals that emit nothing: in the lit
        look the share of their light that is not direct sun, gamma-encoded; 1 in the others."""
        if self.mode != "lit":
            return np.ones(len(normals))
        share = self._skylight(normals)[1]
        return np.clip((share[0] + share[1] + share[2]) / 3, 0.0, 1.0) ** (1 / 2.2)

    def gl_normals(self, normals: np.ndarray) -> np.ndarray | None:
        """The normals pyrender needs: per-pixel lighting ('pbr') reads them, the flat shader of
        the other looks does not."""
        return normals if self.mode == "pbr" else None

    def _mirror(self, centres: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Radiance a clear coat or pane reflects towards the eye: sky or ground, and the sun."""
        view = self.eye - centres
        view /= np.maximum(facets.lengths(view), 1e-9)[:, None]
        cos = np.einsum("ij,ij->i", normals, view)
        n = np.where(cos[:, None] < 0, -normals, normals)  # double-sided
        cos = np.abs(cos)
        fresnel = F0 + (1 - F0) * (1 - cos) ** 5
        r = 2 * cos[:, None] * n - view
        env = np.full((len(r), 3), GROUND_RADIANCE)
        up = np.flatnonzero(r[:, 2] > 0)
        env[up] = _sky_radiance(r[up, 2])
        half = view + self.sun
        half /= np.maximum(facets.lengths(half), 1e-9)[:, None]
        glint = np.clip(np.einsum("ij,ij->i", n, half), 0.0, 1.0) ** HIGHLIGHT_EXPONENT
        return fresnel[:, None] * (env + glint[:, None] * self.sun_rgb)


def _thermal(part: Part, moving: bool) -> tuple[float, float, float]:
    t = TEMPERATURE.get(part.material.name, 0.35)
    if moving:
        t += _WARM_WHEN_MOVING.get(part.material.name, 0.0)
    return (t, t, t)


@dataclass
class _Layer:
    """A node of the colour pass whose triangles it may leave out (simgen.occlusion): the node
    (its mesh gets the primitives drawn), each primitive's triangles (node frame, float32 as
    pyrender uploads them) and their corners as indices into the layer's shared vertices (equal
    keys, equal bits), and how to make the primitives with some of their triangles (`keep`, a
    mask per primitive; none left out where it is empty)."""

    node: pyrender.Node
    corners: list[np.ndarray]
    keys: list[np.ndarray]
    make: Callable[[list[np.ndarray]], list[pyrender.Primitive]]
    vertices: np.ndarray  # (V, 3) float32, node frame: corners == vertices[keys]
    ready: Callable[[], None] = lambda: None  # what `make` needs that no culling changes

    @staticmethod
    def of(node: pyrender.Node, keys: list[np.ndarray], vertices: np.ndarray) -> _Layer:
        """A layer of a node whose primitives are made in full: thinned by copying."""
        primitives = list(node.mesh.primitives)
        return _Layer(node, [p.positions.reshape(-1, 3, 3) for p in primitives], keys,
                      lambda keep: _shown(primitives, keep), vertices)

    def triangles(self) -> int:
        return sum(len(c) for c in self.corners)


class _Mesh(pyrender.Mesh):
    """A pyrender mesh that keeps its place in pyrender's draw order (transparent or not, as the
    primitives it is made with say, or as given) whatever part of them the colour pass draws."""

    def __init__(self, primitives: list[pyrender.Primitive], transparent: bool | None = None):
        super().__init__(primitives)
        self._transparent = super().is_transparent if transparent is None else transparent

    @property
    def is_transparent(self) -> bool:
        return self._transparent


@dataclass
class _Actors:
    """The actors as the two passes draw them: per actor its faces in view (actor frame; None for
    an actor wholly out of view) for the instance pass, and where the colour pass draws each of
    them (a layer and triangle indices in it); the colour pass's layers; all triangles (world
    frame) as shadow casters, and each body's box, where it can hide the sky."""

    own: list[np.ndarray | None]
    drawn_as: list[tuple[int, np.ndarray] | None]
    layers: list[_Layer]
    casters: Occluders
    reach: Reach


def _actor_meshes(bodies: list[tuple[list[Part], np.ndarray, bool]], shader: _Shader, view: _View,
                  rng: np.random.Generator | None = None, glow: np.ndarray | None = None) -> _Actors:
    """Each actor's faces in `view` (parts in the actor frame), all actors shaded in one
    vectorised pass in the world frame; drawn by the colour pass as one flat-shaded layer per
    actor, or with `rng` (the lit look with textures) all actors in one layer, glass, paint and
    plates wearing their textures (_texture_coordinates; one primitive per texture, where one per
    actor and texture would cost pyrender a draw call each). `glow` (P, 3): what each part emits
    in the lit look."""
    if not bodies:
        return _Actors([], [], [], Occluders.empty(),
                       Reach(np.zeros((0, 4, 4)), np.zeros((0, 3)), np.zeros((0, 3))))
    parts = [p for b, _, _ in bodies for p in b]
    vertices, faces = facets.shared(parts)  # each part in its actor's frame
    own_tris, own_n = facets.faceted(vertices, faces)  # row by row: the same bits as actor by actor
    counts = [sum(len(p.mesh.faces) for p in b) for b, _, _ in bodies]  # faces per actor
    ends = np.cumsum(counts)[:-1]
    v_starts = np.cumsum([0, *(sum(len(p.mesh.vertices) for p in b) for b, _, _ in bodies)])[:-1]
    reach = Reach(np.array([np.linalg.inv(pose) for _, pose, _ in bodies]),
                  np.minimum.reduceat(vertices, v_starts), np.maximum.reduceat(vertices, v_starts))
    geo = list(zip(np.split(own_tris, ends), np.split(own_n, ends)))
    world_v = np.concatenate([v @ pose[:3, :3].T + pose[:3, 3]
                              for v, (_, pose, _) in zip(np.split(vertices, v_starts[1:]), bodies)])
    world_tris = np.take(world_v, faces, axis=0)  # the same bits as each corner moved on its own
    casters = Occluders.of_mesh(parts, world_v, faces)
    seen = view.faces(world_v, faces)
    own_seen = np.split(seen, ends)
    own = [t[s] if s.any() else None for (t, _), s in zip(geo, own_seen)]
    # Colours, bent normals and texture coordinates only for the actors with a face in view
    # (`sel`: all their faces): each is a face's or a part's own, the same bits as over all actors.
    visible = [i for i, s in enumerate(own_seen) if s.any()]
    if not visible:
        return _Actors(own, [None] * len(bodies), [], casters, reach)
    in_view = np.zeros(len(bodies), bool)
    in_view[visible] = True
    sel = np.repeat(in_view, counts)
    seen_parts = [p for i in visible for p in bodies[i][0]]
    seen_n = np.concatenate([geo[i][1] @ bodies[i][1][:3, :3].T for i in visible])
    seen_tris = world_tris[sel]
    seen_ends = np.cumsum([counts[i] for i in visible])[:-1]
    if shader.mode == "thermal":  # warm when moving: per actor
        rgba = np.concatenate([shader.colors(bodies[i][0], None, None, bodies[i][2]) for i in visible])
    elif shader.mode == "lit":
        bent = _bent_normals([len(p.mesh.faces) for p in seen_parts], own_tris[sel], own_n[sel])
        bent = np.concatenate([b @ bodies[i][1][:3, :3].T
                               for b, i in zip(np.split(bent, seen_ends), visible)])
        part_in_view = np.repeat(in_view, [len(b) for b, _, _ in bodies])
        rgba = shader.colors(seen_parts, seen_tris, seen_n, False, corner_normals=bent,
                             glow=None if glow is None else glow[part_in_view])
    else:
        rgba = shader.colors(seen_parts, seen_tris, seen_n, False)
    if rng is None:
        colours = dict(zip(visible, np.split(rgba, seen_ends)))
        own_faces = np.split(faces, ends)
        own_v = np.split(vertices.astype(np.float32), v_starts[1:])
        layers = [_Layer.of(pyrender.Node(mesh=_Mesh([_primitive(t[s], shader.gl_normals(n[s]), colours[i][s],
                                                                  _PLAIN)]), matrix=bodies[i][1]),
                            [own_faces[i][s] - v_starts[i]], own_v[i])
                  for i, ((t, n), s) in enumerate(zip(geo, own_seen)) if s.any()]
        drawn_as = [None] * len(bodies)
        for k, i in enumerate(visible):
            drawn_as[i] = (k, np.arange(int(own_seen[i].sum())))
        return _Actors(own, drawn_as, layers, casters, reach)
    # Each actor draws a shift of its glass and paint and a plate of the plates' tile.
    shift = np.repeat(rng.uniform(0.0, 1.0, len(bodies)), counts)[sel]
    plate = np.repeat(rng.integers(textures.PLATES_PER_TILE, size=len(bodies)), counts)[sel]
    seen = seen[sel]  # from here on, of the faces of `sel`
    prims, keys, order, plain = [], [], [], seen.copy()
    gain = np.array([textures.MAX_GAIN] * 3 + [1.0])
    worn = _texture_coordinates(seen_parts, own_tris[sel], own_n[sel], shift, plate)
    sel_faces = faces[sel]
    # The merged mesh sits at the actors' centroid, not at the static world's origin: pyrender
    # draws the nodes farthest first, and two nodes at one distance in the order of a set (of
    # objects hashed by address), which would decide run by run who wins a depth tie (a tyre on
    # the road). The centroid of all actors, in view or not: every frame keeps its draw order.
    origin = world_tris.reshape(-1, 3).mean(axis=0)
    local = seen_tris - origin
    for kind, (idx, uv) in worn.items():
        plain[idx] = False
        shown = seen[idx]
        if shown.any():
            prims.append(_primitive(local[idx[shown]], None, rgba[idx[shown]] * gain, _textured(kind, 0),
                                    uv[shown]))
            keys.append(sel_faces[idx[shown]])
            order.append(idx[shown])
    if plain.any():
        prims.append(_primitive(local[plain], None, rgba[plain], _PLAIN))
        keys.append(sel_faces[plain])
        order.append(np.flatnonzero(plain))
    merged = _Layer.of(pyrender.Node(mesh=_Mesh(prims), translation=origin), keys,  # `visible`: a face at least
                       (world_v - origin).astype(np.float32))
    at = np.full(len(seen), -1)
    at[np.concatenate(order)] = np.arange(len(seen[seen]))
    in_sel = np.cumsum(sel) - 1  # each face's place among the faces of `sel`
    drawn_as = [(0, at[in_sel[np.flatnonzero(s) + start]]) if s.any() else None
                for s, start in zip(own_seen, np.r_[0, ends])]
    return _Actors(own, drawn_as, [merged], casters, reach)


def _texture_coordinates(parts: list[Part], tris: np.ndarray, normals: np.ndarray, shift: np.ndarray,
                         plate: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per texture the parts wear (textures.OF_ACTOR_MATERIAL): the indices of its faces (in the
    order of `tris`, each in its actor's frame: x forward, y left, z up) and their (n, 3, 2)
    texture coordinates. These run along the car in metres (across it on faces towards the
    front or back); up each pane's height on glass (v, 0 at its foot), up the car in metres on
    paint (along and across it on bonnet, roof and boot), across a plate's face seen from outside
    on plates. `shift` (per face) moves glass and paint along their tiles, `plate` (per face)
    picks a plate of its tile."""
    counts = [len(p.mesh.faces) for p in parts]
    owner = np.repeat(np.arange(len(parts)), counts)
    kinds = sorted(textures.ACTOR_MAKERS)
    code = np.array([kinds.index(textures.OF_ACTOR_MATERIAL[p.material.name])
                     if p.material.name in textures.OF_ACTOR_MATERIAL else -1 for p in parts])[owner]
    lo, hi = _part_boxes(counts, tris)
    out = {}
    for k, kind in enumerate(kinds):
        idx = np.flatnonzero(code == k)
        if not len(idx):
            continue
        t, n, a, b, sh = tris[idx], normals[idx], lo[owner[idx]], hi[owner[idx]], shift[idx, None]
        v = (t[..., 2] - a[:, 2:]) / np.maximum(b[:, 2:] - a[:, 2:], 1e-9)
        side = (np.abs(n[:, 1]) >= np.abs(n[:, 0]))[:, None]
        along = np.where(side, t[..., 0], t[..., 1])
        if kind == "glass":
            u = along / textures.GLASS_TILE_M + sh
        elif kind == "paint":
            up = (np.abs(n[:, 2]) >= 0.7)[:, None]
            tile_u, tile_v = textures.PAINT_TILE_M
            u = np.where(up, t[..., 0], along) / tile_u + sh
            v = np.where(up, t[..., 1], t[..., 2]) / tile_v + sh
        else:  # seen from the front (+x) the plate's left is -y, from behind +y
            across = (t[..., 1] - a[:, 1:2]) / np.maximum(b[:, 1:2] - a[:, 1:2], 1e-9)
            u = np.where(n[:, :1] >= 0, across, 1.0 - across)
            v = (v + plate[idx, None]) / textures.PLATES_PER_TILE
        out[kind] = (idx, np.stack([u, v], axis=2))
    return out


# Body panels are curved where the meshes are flat: a door's skin turns through about 30 deg
# between shoulder and sill (rounded in above the belt line, the sill tucked in below); roof,
# bonnet and boot are crowned; bumpers, lamps and screens wrap round (read off makers' front and
# side views; no survey). The meshes keep their flat faces (what the LiDAR and the labels see);
# the lit colour pass shades each corner of a face with the face normal bent towards the corner's
# direction from its part's centre, in units of the part's half extents, so the light and the
# mirrored sky change across a face as across a curved panel: BEND turns the normal at the
# middle of an edge by PANEL_TURN / 2 (tan = BEND / (1 + BEND)).
PANEL_TURN = np.radians(30.0)
BEND = np.tan(PANEL_TURN / 2) / (1 - np.tan(PANEL_TURN / 2))


def _part_boxes(face_counts: list[int], tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(P, 3) lowest and highest corners of consecutive parts' faces (`face_counts` faces each),
    corner by corner and one coordinate at a time: the same bits as a reduction over the corners,
    in numpy loops that run over all faces rather than three numbers."""
    lo, hi = np.empty((len(tris), 3)), np.empty((len(tris), 3))
    for j in range(3):
        a, b, c = tris[:, 0, j], tris[:, 1, j], tris[:, 2, j]
        np.minimum(np.minimum(a, b), c, out=lo[:, j])
        np.maximum(np.maximum(a, b), c, out=hi[:, j])
    starts = np.cumsum([0, *face_counts[:-1]])
    return np.minimum.reduceat(lo, starts), np.maximum.reduceat(hi, starts)


def _bent_normals(face_counts: list[int], tris: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(F, 3, 3) shading normals of the corners of consecutive parts' faces (`face_counts` faces
    each; tris and normals in one frame): each face normal bent by BEND towards the corner's
    direction from its part's box centre, measured in the box's half extents."""
    lo, hi = _part_boxes(face_counts, tris)
    owner = np.repeat(np.arange(len(face_counts)), face_counts)
    centre, half = ((lo + hi) / 2)[owner], np.maximum((hi - lo) / 2, 1e-6)[owner]
    bent = normals[:, None, :] + BEND * (tris - centre[:, None, :]) / half[:, None, :]
    return bent / facets.lengths(bent)[..., None]


def _lamp_mesh(part: Part, material) -> pyrender.Mesh:
    """An emissive lamp at night: white faces under an emissive material (actor frame)."""
    tris, normals = facets.triangles([part])
    return pyrender.Mesh([_primitive(tris, normals, np.ones((len(tris), 4)), material)])


def _planar_uv(tris: np.ndarray, normals: np.ndarray, tile: tuple[float, float],
               shift: np.ndarray) -> np.ndarray:
    """Texture coordinates from world coordinates: (x, y) on faces that face up or down, (along
    the face, z) on the others."""
    side = np.flatnonzero(np.abs(normals[:, 2]) < 0.7)  # row by row: only these need the tangent
    t = np.c_[-normals[side, 1], normals[side, 0]]
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-9)
    uv = tris[..., :2].copy()
    uv[side, :, 0] = np.einsum("fkj,fj->fk", tris[side][..., :2], t)
    uv[side, :, 1] = tris[side, :, 2]
    for k, column in enumerate(uv.reshape(-1, 2).T):  # u, then v: numpy loops over all corners
        column /= tile[k]
        column += shift[k]
    return uv


@dataclass
class _Wear:
    """One primitive of the static world's layer: the faces it draws (indices into the static
    faces, in order) and, where they wear a tile, its texture layout and where they stand among
    the faces of that layout (a façade is mapped from its whole wall)."""

    faces: np.ndarray
    wearing: Wearing | None = None
    among: np.ndarray | None = None
    uv: np.ndarray | None = None  # a façade's: its faces' texture coordinates (_Static.ready)


@dataclass
class _Static:
    """The static world's faces and what shades them, to make the colour pass's primitives of the
    faces it draws alone: those it leaves out are neither shaded nor mapped."""

    parts: list[Part]
    tris: np.ndarray
    normals: np.ndarray
    first: np.ndarray  # each part's first face, and the end
    layout: StaticLayout
    shader: _Shader
    wears: list[_Wear]

    def ready(self) -> None:
        """The façades' texture coordinates, which come from whole walls, drawn or not."""
        for w in self.wears:
            if w.wearing is not None and w.wearing.kind in FACADE_KINDS and w.uv is None:
                worn = w.wearing
                own = slice(self.first[worn.part], self.first[worn.part + 1])  # the part's faces
                t, n = self.tris[own][worn.faces], self.normals[own][worn.faces]
                w.uv = facade_uv(t, n, worn.tile, worn.shift)[w.among]

    def make(self, keep: list[np.ndarray]) -> list[pyrender.Primitive]:
        self.ready()
        drawn = np.zeros(len(self.tris), bool)
        for w, k in zip(self.wears, keep):
            drawn[w.faces[k]] = True
        rgba = np.zeros((len(self.tris), 4))  # shaded where drawn
        rgba[drawn] = self.shader.colors(self.parts, self.tris, self.normals, False, self.layout.gain, only=drawn)
        return [self._wear(w, k, rgba) for w, k in zip(self.wears, keep) if k.any()]

    def _wear(self, w: _Wear, keep: np.ndarray, rgba: np.ndarray) -> pyrender.Primitive:
        g = w.faces[keep]
        if w.wearing is None:
            return _primitive(self.tris[g], self.shader.gl_normals(self.normals[g]), rgba[g], _PLAIN)
        worn = w.wearing
        if worn.kind in FACADE_KINDS:
            uv = w.uv[keep]
        else:  # face by face
            uv = _planar_uv(self.tris[g], self.normals[g], worn.tile, worn.shift)
        colour = rgba[g] * np.array([textures.MAX_GAIN] * 3 + [1.0])
        return _primitive(self.tris[g], None, colour, _textured(worn.kind, worn.variant), uv)  # lit: flat


def _static_mesh(parts: list[Part], shader: _Shader, world: World, view: _View
                 ) -> tuple[_Layer | None, Occluders]:
    """The static world's faces in `view` as a layer, one primitive per texture tile (and one for
    untextured faces; None where no face is in view), shaded when the colour pass draws them,
    and all its triangles as shadow casters."""
    vertices, faces = facets.shared(parts)
    tris, normals = facets.faceted(vertices, faces)
    layout = static_layout(world, parts, normals)
    casters = Occluders.of_mesh(parts, vertices, faces)
    seen = view.faces(vertices, faces)
    if not seen.any():
        return None, casters
    first = np.cumsum([0] + [len(p.mesh.faces) for p in parts])
    wears, plain = [], seen.copy()
    if shader.mode == "lit" and world.appearance.textures:
        for w in layout.wearing:
            own = slice(first[w.part], first[w.part + 1])  # the part's faces
            plain[own] = False
            shown = seen[own][w.faces]
            if shown.any():
                among = np.flatnonzero(shown)
                wears.append(_Wear(first[w.part] + np.flatnonzero(w.faces)[among], w, among))
    if plain.any():
        wears.append(_Wear(np.flatnonzero(plain)))
    static = _Static(parts, tris, normals, first, layout, shader, wears)
    node = pyrender.Node(mesh=_Mesh([], _translucent(shader, normals[seen])))
    corners = [tris[w.faces].astype(np.float32) for w in wears]
    return (_Layer(node, corners, [faces[w.faces] for w in wears], static.make, vertices.astype(np.float32),
                   static.ready), casters)


def _translucent(shader: _Shader, normals: np.ndarray) -> bool:
    """Whether faces of these unit normals get an alpha below 1 somewhere (in float32, what
    pyrender tests: it draws such a mesh after the opaque ones), tried on the first faces first:
    in the lit look any face towards the sun has one."""
    return any(np.any(shader.alpha(part).astype(np.float32) != 1.0) for part in (normals[:256], normals[256:]))


_DOME_RADIUS = 350.0  # m, inside ZFAR
_DOME_LOW = np.radians(-20.0)  # the dome reaches below the horizon: the ground hides that part


def _sky_texture(rng: np.random.Generator, cover: float, headroom: float) -> np.ndarray:
    """(64, 256, 3) uint8 equirectangular sky from the horizon (bottom rows) to the zenith:
    the clear-sky gradient, and clouds where fractal noise exceeds the quantile that leaves
    `cover` of the sky clouded, greyer at their thick cores."""
    h, w = 64, 256
    elev = np.linspace(np.pi / 2, _DOME_LOW, h)
    sky = _sky_radiance(np.sin(elev))[:, None, :].repeat(w, axis=1)
    if cover > 0:
        n = textures._fractal(rng, 1.8, size=(h, w))  # periodic in azimuth
        thr = np.quantile(n, 1.0 - cover)
        density = np.clip((n - thr) / 0.6, 0.0, 1.0)[..., None]
        core = np.clip((n - thr - 0.8) / 1.5, 0.0, 0.45)[..., None]
        sky = sky * (1 - density) + np.asarray(CLOUD) * density * (1 - core)
    return np.clip(np.round((sky / headroom) ** (1 / 2.2) * 255), 0, 255).astype(np.uint8)


@cache
def _dome() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The sky dome's triangles (about its centre), texture coordinates, faces and the grid's
    vertices they index, made once."""
    az = np.linspace(0, 2 * np.pi, 49)
    el = np.linspace(_DOME_LOW, np.pi / 2, 13)
    A, E = np.meshgrid(az, el)
    P = _DOME_RADIUS * np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], axis=-1)
    UV = np.stack([A / (2 * np.pi), (E - _DOME_LOW) / (np.pi / 2 - _DOME_LOW)], axis=-1)
    i, j = np.meshgrid(np.arange(12), np.arange(48), indexing="ij")
    quads = np.stack([i * 49 + j, i * 49 + j + 1, (i + 1) * 49 + j + 1, (i + 1) * 49 + j], -1).reshape(-1, 4)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return P.reshape(-1, 3)[faces], UV.reshape(-1, 2)[faces], faces, P.reshape(-1, 3)


@dataclass
class _Dome:
    """The sky dome's one primitive, its texture drawn (this frame's clouds) when first needed."""

    world: World
    headroom: float
    primitive: pyrender.Primitive | None = None

    def ready(self) -> None:
        if self.primitive is None:
            rng = factor_rng(self.world.seed, self.world.frame_index, "sky")
            tris, uv, _, _ = _dome()
            tex = pyrender.Texture(source=_sky_texture(rng, self.world.appearance.cloud_cover, self.headroom),
                                   source_channels="RGB")
            mat = pyrender.MetallicRoughnessMaterial(baseColorTexture=tex, metallicFactor=0.0, doubleSided=True)
            self.primitive = _primitive(tris, None, np.ones((len(tris), 4)), mat, uv)  # lit looks: flat

    def make(self, keep: list[np.ndarray]) -> list[pyrender.Primitive]:
        self.ready()
        return _shown([self.primitive], keep)


def _sky_dome(world: World, headroom: float, eye: np.ndarray) -> _Layer:
    """A textured dome around the camera (at `eye`) for the lit looks (not in the instance pass:
    its pixels keep depth 0 and instance 0)."""
    tris, _, faces, grid = _dome()
    dome = _Dome(world, headroom)
    node = pyrender.Node(mesh=_Mesh([], False), matrix=np.r_[np.c_[np.eye(3), eye], [[0, 0, 0, 1]]])
    return _Layer(node, [tris.astype(np.float32)], [faces], dome.make, grid.astype(np.float32), dome.ready)


@dataclass
class _Instance:
    """A node of the instance pass: what it draws, the actor id its pixels carry (0 for the static
    world), and where the colour pass draws its triangles (a layer and the triangles' indices
    there; None where it leaves them out of the culling)."""

    draw: instance_pass.Draw
    actor: int
    drawn_as: tuple[int, np.ndarray] | None


@dataclass
class Seen:
    """The instance pass: per pixel the actor id (0 background and static world), the depth
    (metres, 0 where no surface) and the colour pass's triangle seen at the pixel centre (its
    number over the layers, -1 where none of theirs)."""

    instance: np.ndarray  # (H, W) uint16
    depth: np.ndarray  # (H, W) float32
    triangle: np.ndarray  # (H, W) int64


@dataclass
class BuiltScene:
    """A world's pyrender scene at t = 0 (what the colour pass draws) with what its two passes
    need: the nodes of the instance pass, the colour pass's render flags, its layers (the nodes
    whose hidden triangles it leaves out, and their triangles as the culling reads them), and
    what darkens it (shadow casters, the actors' reach)."""

    scene: pyrender.Scene
    instances: list[_Instance]
    flags: int
    layers: list[_Layer]
    casters: Casters
    triangles: occlusion.Triangles | None = None  # the layers' triangles, made by the instance pass

    def instance_pass(self, r: pyrender.OffscreenRenderer) -> Seen:
        """Actor ids, depth and triangles seen. Depth from this single-sample pass: the
        multisampled pass's depth is that of sample 0, a third of a pixel off the pixel centre."""
        camera = self.scene.main_camera_node
        first = np.cumsum([0, *(layer.triangles() for layer in self.layers)])
        view = np.linalg.inv(self.scene.get_pose(camera))
        order = instance_pass.order([i.draw for i in self.instances], self.scene.get_pose(camera)[:3, 3])
        todo = [self.instances[k] for k in order]
        r._platform.make_current()
        ids, z = instance_pass.draw([i.draw for i in todo], view, self._projection(r), r.viewport_width,
                                    r.viewport_height, lambda: self._meanwhile(r))
        r._platform.make_uncurrent()
        actor = np.concatenate([[0], *(np.full(len(i.draw.tris), i.actor) for i in todo)])
        triangle = np.concatenate([[-1], *(np.full(len(i.draw.tris), -1) if i.drawn_as is None
                                           else first[i.drawn_as[0]] + i.drawn_as[1] for i in todo)])
        return Seen(*instance_pass.resolve(ids, z, actor, triangle, camera.camera.znear, camera.camera.zfar))

    def colour_pass(self, r: pyrender.OffscreenRenderer, seen: Seen | None = None,
                    meanwhile: Callable[[], object] | None = None) -> np.ndarray | tuple[np.ndarray, object]:
        """The colour image (RGBA in the lit look: alpha is the light that is not direct sun);
        with `seen`, the layers' hidden triangles left out. With `meanwhile`, also its result:
        it runs on the CPU while llvmpipe draws."""
        if meanwhile is not None:
            r._renderer.meanwhile = meanwhile
            try:
                return self.colour_pass(r, seen), r._renderer.meanwhile_result
            finally:
                r._renderer.meanwhile, r._renderer.meanwhile_result = None, None
        hidden = None if seen is None else self._hidden(r, seen.triangle)
        first = 0
        for layer in self.layers:
            keep = []
            for c in layer.corners:
                keep.append(np.ones(len(c), bool) if hidden is None else ~hidden[first:first + len(c)])
                first += len(c)
            layer.node.mesh.primitives = layer.make(keep)
        return r.render(self.scene, flags=self.flags)[0]

    def _projection(self, r: pyrender.OffscreenRenderer) -> np.ndarray:
        return self.scene.main_camera_node.camera.get_projection_matrix(r.viewport_width, r.viewport_height)

    def _meanwhile(self, r: pyrender.OffscreenRenderer) -> None:
        """What the colour pass needs that the instance pass's image does not change, made while
        llvmpipe draws that pass: the culling's view of the layers, the layers' ready parts."""
        self._prepare(r)
        for layer in self.layers:
            layer.ready()

    def _prepare(self, r: pyrender.OffscreenRenderer) -> None:
        """The layers' triangles as the culling reads them (occlusion.prepare): no image needed,
        so made while llvmpipe draws the instance pass."""
        clip = self._projection(r) @ np.linalg.inv(self.scene.get_pose(self.scene.main_camera_node))
        points, keys, base = [], [], 0
        for layer in self.layers:
            points.append(occlusion.screen(layer.vertices, clip @ self.scene.get_pose(layer.node),
                                           r.viewport_width, r.viewport_height))
            keys.append(np.concatenate(layer.keys).astype(np.int64) + base)
            base += len(layer.vertices)
        keys = np.concatenate(keys)
        x, y, z, front = (np.take(np.concatenate(p), keys) for p in zip(*points))
        self.triangles = occlusion.prepare(x, y, z, front, keys, r.viewport_width, r.viewport_height)

    def _hidden(self, r: pyrender.OffscreenRenderer, triangle: np.ndarray) -> np.ndarray:
        """(n,) bool over the layers' triangles: those that win no sample of the colour pass."""
        if self.triangles is None:
            self._prepare(r)
        return occlusion.hidden(self.triangles, triangle)


def _shown(primitives: list[pyrender.Primitive], keep: list[np.ndarray]) -> list[pyrender.Primitive]:
    """The primitives with only their triangles `keep` (a mask per primitive) left."""
    out = []
    for p, k in zip(primitives, keep):
        if k.all():
            out.append(p)
        elif k.any():
            corner = np.repeat(k, 3)
            out.append(pyrender.Primitive(
                positions=p.positions[corner], normals=None if p.normals is None else p.normals[corner],
                color_0=None if p.color_0 is None else p.color_0[corner],
                texcoord_0=None if p.texcoord_0 is None else p.texcoord_0[corner], material=p.material))
    return out


def _stop_lamp_glow(actors: list, bodies: list[tuple[list[Part], np.ndarray, bool]]
                    ) -> np.ndarray | None:
    """(P, 3) STOP_LAMP on the tail lamps of actors with their stop lamps lit, 0 on every other
    part of `bodies` (in their order); None where no lamp is lit."""
    if not any(a.stop_lamps for a in actors):
        return None
    return np.array([STOP_LAMP if a.stop_lamps and p.material.name == "taillight" else (0.0, 0.0, 0.0)
                     for a, (parts, _, _) in zip(actors, bodies) for p in parts])


def build_scene(world: World) -> BuiltScene:
    """The pyrender scene of a world at t = 0 and what its passes need (BuiltScene)."""
    light = world.light
    rig = world.rig
    cam2_from_world = rig.cam2_from_world()
    eye = np.linalg.inv(cam2_from_world)[:3, 3]
    shader = _Shader(world, eye)
    scene = _Scene(bg_color=(*((0.02,) * 3 if shader.mode == "thermal" else SKY[light.time]), 1.0),
                   ambient_light=(AMBIENT[light.time],) * 3)
    layers: list[_Layer] = []
    instances: list[_Instance] = []
    casters = Occluders.empty()
    view = _View.of(rig.intrinsics(), cam2_from_world, rig.width, rig.height)
    if world.static:
        static, casters = _static_mesh(world.static, shader, world, view)
        if static is not None:
            instances.append(_Instance(_draw_of(static), 0, (len(layers), np.arange(static.triangles()))))
            layers.append(static)
    if shader.mode == "lit":
        layers.append(_sky_dome(world, shader.headroom, eye))
    lamps: list[tuple[Part, np.ndarray, int]] = []
    bodies = []
    for actor in world.actors:
        lit = shader.mode == "pbr" and actor.moving  # night: moving vehicles' lamps glow; parked stay off
        bodies.append(([p for p in actor.parts if not (lit and p.material.name in EMISSIVE)],
                       actor.pose, actor.moving))
        lamps += [(p, actor.pose, actor.id) for p in actor.parts if lit and p.material.name in EMISSIVE]
    textured = shader.mode == "lit" and world.appearance.textures
    actors = _actor_meshes(
        bodies, shader, view,
        factor_rng(world.seed, world.frame_index, "actor_textures") if textured else None,
        _stop_lamp_glow(world.actors, bodies) if shader.mode == "lit" else None)
    for actor, tris, drawn_as in zip(world.actors, actors.own, actors.drawn_as):
        if tris is not None:
            own = actors.layers[drawn_as[0]] if not textured else None  # its layer is its node
            draw = (_draw_of(own) if own is not None
                    else instance_pass.Draw(tris, pyrender.Node(matrix=actor.pose).matrix, False))
            instances.append(_Instance(draw, actor.id, (len(layers) + drawn_as[0], drawn_as[1])))
    layers += actors.layers
    for layer in layers:
        scene.add_node(layer.node)
    for part, pose, actor_id in lamps:
        mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=(0.0, 0.0, 0.0, 1.0),
                                                 emissiveFactor=EMISSIVE[part.material.name],
                                                 doubleSided=True)
        lamp = scene.add(_lamp_mesh(part, mat), pose=pose)
        instances.append(_Instance(_draw_of(_Layer.of(lamp, [], np.zeros((0, 3), np.float32))), actor_id, None))
    pose, residual = camera_node_pose(cam2_from_world)
    scene.add(_ExactCamera(rig.intrinsics(), residual), pose=pose)
    if shader.mode == "pbr":
        z = shader.sun
        x = np.cross([0.0, 0.0, 1.0], z) if abs(z[2]) < 0.999 else np.array([1.0, 0.0, 0.0])
        x /= np.linalg.norm(x)
        sun_pose = np.eye(4)
        sun_pose[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
        scene.add(pyrender.DirectionalLight(color=SUN[light.time],
                                            intensity=SUN_POWER[light.time] * light.sun_intensity),
                  pose=sun_pose)
        for dy in (-0.6, 0.6):  # the ego vehicle's (or the gantry's) headlamps
            p = pose.copy()
            p[:3, 3] += pose[:3, :3] @ np.array([dy, -0.9, 0.0])
            scene.add(pyrender.SpotLight(color=(1.0, 0.95, 0.85), intensity=800.0,
                                         innerConeAngle=0.15, outerConeAngle=0.45), pose=p)
    flags = {"pbr": RenderFlags.NONE, "thermal": RenderFlags.FLAT,
             "lit": RenderFlags.FLAT | RenderFlags.RGBA}[shader.mode]
    return BuiltScene(scene, instances, flags, layers, Casters(casters, actors.casters, actors.reach))


def _draw_of(layer: _Layer) -> instance_pass.Draw:
    """The instance pass's draw of a colour pass node: all its triangles, in primitive order."""
    return instance_pass.Draw(np.concatenate(layer.corners), layer.node.matrix, layer.node.mesh.is_transparent)


def _shade_tint(time: str) -> np.ndarray:
    """Gamma-encoded colour of skylight against sunlight plus skylight, luminance kept: shadows
    are lit by the sky alone, which is bluer than the sun."""
    sky = np.asarray(SKY[time]) / np.asarray(SUN[time])
    return (sky / (sky @ LUMA)) ** (1 / 2.2)


_LINEAR = ((np.arange(256) / 255.0) ** 2.2).astype(np.float32)  # gamma-encoded 8-bit value -> linear


def skylight(world: World, depth: np.ndarray, instance: np.ndarray, casters: Casters) -> np.ndarray | None:
    """The share of the sky the actors hide from the ground (sky_occlusion), where the look has
    shadows (None elsewhere): from the instance pass alone, so it can run while the colour pass
    draws."""
    if not world.appearance.shadows:
        return None
    rig = world.rig
    return sky_occlusion(casters.actors, casters.reach, depth, instance == 0, rig.intrinsics(), rig.cam2_from_world())


def shade(world: World, color: np.ndarray, depth: np.ndarray, instance: np.ndarray,
          casters: Casters, sky: np.ndarray | None = None) -> np.ndarray:
    """The lit colour pass (RGBA, alpha = the light left in shadow) with the sun's shadows and the
    actors' occlusion of the sky on the ground (instance 0; `skylight`'s, made here where not
    given) applied, as (H, W, 3) uint8."""
    rgb = color[..., :3]
    if not world.appearance.shadows:
        return rgb
    rig = world.rig
    K, cam2_from_world = rig.intrinsics(), rig.cam2_from_world()
    sun = sun_shadow(casters.sun(), depth, K, cam2_from_world, _to_sun(world.light), color[..., 3] < 250)
    if sky is None:
        sky = skylight(world, depth, instance, casters)
    # Only darkened pixels change (elsewhere the factor is exactly 1).
    out = cv2.cvtColor(color, cv2.COLOR_RGBA2RGB)  # a copy of rgb, faster than numpy's 3 bytes at a time
    hit = np.flatnonzero((sun != 0) | (sky != 0))
    flat = out.reshape(-1, 3)
    flat[hit] = darken(np.take(flat, hit, axis=0), color[..., 3].ravel()[hit], sun.ravel()[hit],
                       sky.ravel()[hit], (_shade_tint(world.light.time) ** 2.2).astype(np.float32))
    return out


def darken(rgb: np.ndarray, alpha: np.ndarray, sun: np.ndarray, sky: np.ndarray,
           tint: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 gamma-encoded colours with the light that shadow and sky occlusion take
    away. In linear light, per channel: a share r of the light is the sky's (alpha, gamma-encoded,
    times the linear `tint`, skylight being bluer than the sun); occlusion `sky` cuts that share,
    shadow depth `sun` the rest. All in float32 (sun, sky and tint are), as numpy's operators
    would take them one after another, pixel by pixel."""
    out = np.empty((len(rgb), 3), np.uint8)
    _darken(rgb, alpha, sun, sky, np.minimum(_LINEAR[:, None] * tint, np.float32(1.0)), out)  # r per 8-bit alpha
    return out


@numba.njit(cache=True, nogil=True)
def _darken(rgb, alpha, sun, sky, share, out):
    one, gamma = np.float32(1.0), np.float32(1 / 2.2)
    for i in range(rgb.shape[0]):
        for c in range(3):
            r = share[alpha[i], c]
            left = (one - sun[i]) * (one - r) + (one - sky[i]) * r
            v = np.round(np.float32(rgb[i, c]) * left ** gamma)
            out[i, c] = np.uint8(min(max(v, np.float32(0.0)), np.float32(255.0)))


def render(world: World, scene: WorldScene | None = None) -> RenderOutput:
    """The camera's images of `world`; `scene`, an Embree scene of it built for the LiDAR, spares
    the sun's shadows a scene of the static world of their own."""
    rig = world.rig
    r = renderer(rig.width, rig.height)
    built = build_scene(world)
    built.casters.world = scene
    seen = built.instance_pass(r)
    cull = seen if software(r) else None
    lit = bool(built.flags & RenderFlags.RGBA)
    if lit:
        color, sky = built.colour_pass(r, cull, lambda: skylight(world, seen.depth, seen.instance, built.casters))
        rgb = shade(world, color, seen.depth, seen.instance, built.casters, sky)
    else:
        rgb = built.colour_pass(r, cull)[..., :3]
    return RenderOutput(np.ascontiguousarray(rgb), seen.depth.astype(np.float32), seen.instance,
                        HEADROOM if lit else 1.0)
