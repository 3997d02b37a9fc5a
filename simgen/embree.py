"""Embree scenes for everything that casts rays at the world: the LiDAR's sweep (simgen.lidar)
and the camera's sun shadows and skylight occlusion (simgen.shadows).

One builder, so both see the same triangles through the same kernels: the device is configured
with EMBREE_CONFIG, and the buffers are filled with one memmove each.
"""

from __future__ import annotations

import ctypes
import warnings
from functools import cache

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh
from embreex.rtcore import EmbreeDevice
from embreex.rtcore_scene import EmbreeScene

# Embree picks its kernels by the CPU it runs on (SSE2 up to AVX-512), and kernels of different
# widths round differently: the same triangles and rays give hits a few ulps apart, enough to move
# a return across an edge or a threshold (3 urban scans hashed with devices capped at AVX2, AVX and
# SSE4.2: three different outputs). Capped at AVX2 (x86-64 CPUs since 2013; one without it runs its
# own best), every such machine runs the same kernels and finds the same triangles; the distances
# still divide by an approximate reciprocal whose last bits differ between Intel and AMD, so the
# LiDAR takes each hit's range and normal from the triangle's plane (simgen.lidar.kernels.exact_hits;
# kitti.cpu pins the other libraries).
EMBREE_CONFIG = b"max_isa=avx2"
# Embree 4's enums (rtcore_common.h, rtcore_buffer.h) for one triangle geometry.
_TRIANGLE, _INDEX, _VERTEX, _UINT3, _FLOAT3 = 0, 0, 1, 0x5003, 0x9003
_HEAD = object.__basicsize__  # bytes of a CPython object header; a Cython class's fields follow


def embree_scene(vertices: np.ndarray, faces: np.ndarray, config: bytes = EMBREE_CONFIG) -> EmbreeScene:
    """A new Embree scene of one triangle geometry: `vertices` (V, 3) and `faces` (F, 3) indexing
    them, held as float32 and uint32 as embreex's TriangleMesh holds them, on a device made with
    Embree's `config` string (`_device`). embreex copies into Embree one Python-level read per
    number (100 ms for a street's 70k vertices and 130k
    triangles); where its objects have the layout `_handles` reads, the buffers are filled with
    one memmove each through the same library calls instead, and Embree gets the same numbers."""
    device = _device(config)
    scene = EmbreeScene(device)
    lib, handles = _embree_lib(), _handles(scene, device)
    if lib is None or handles is None:
        TriangleMesh(scene, np.asarray(vertices, np.float32), np.asarray(faces, np.int32))
        return scene
    v = np.zeros((len(vertices), 4), np.float32)  # Embree reads vertices 16 bytes apart
    v[:, :3] = vertices
    f = np.ascontiguousarray(faces, np.uint32)
    geom = lib.rtcNewGeometry(handles[1], _TRIANGLE)
    for kind, fmt, a in ((_VERTEX, _FLOAT3, v), (_INDEX, _UINT3, f)):
        buffer = lib.rtcSetNewGeometryBuffer(geom, kind, 0, fmt, a.strides[0], len(a))
        ctypes.memmove(buffer, a.ctypes.data, a.nbytes)
    lib.rtcCommitGeometry(geom)
    lib.rtcAttachGeometry(handles[0], geom)
    lib.rtcReleaseGeometry(geom)
    return scene


@cache
def _embree_lib() -> ctypes.CDLL | None:
    """Embree 4's geometry calls, looked up through embreex's own extension (so in the very
    library embreex uses); None for an embreex built on another Embree."""
    lib = ctypes.CDLL(rtcore_scene.__file__)
    try:
        calls = {"rtcNewDevice": ([ctypes.c_char_p], ctypes.c_void_p),
                 "rtcReleaseDevice": ([ctypes.c_void_p], None),
                 "rtcNewGeometry": ([ctypes.c_void_p, ctypes.c_int], ctypes.c_void_p),
                 "rtcSetNewGeometryBuffer": ([ctypes.c_void_p, ctypes.c_int, ctypes.c_uint, ctypes.c_int,
                                              ctypes.c_size_t, ctypes.c_size_t], ctypes.c_void_p),
                 "rtcCommitGeometry": ([ctypes.c_void_p], None),
                 "rtcAttachGeometry": ([ctypes.c_void_p, ctypes.c_void_p], ctypes.c_uint),
                 "rtcReleaseGeometry": ([ctypes.c_void_p], None)}
        for name, (args, res) in calls.items():
            getattr(lib, name).argtypes, getattr(lib, name).restype = args, res
    except AttributeError:
        return None
    return lib


def _device(config: bytes) -> EmbreeDevice:
    """An embreex device whose RTCDevice is made with `config`: embreex makes its own with Embree's
    defaults and takes no config, so that one is released and the configured one put in its C
    field (rtcore.pxd: device), which the object releases when it goes, as it did its own."""
    device = EmbreeDevice()
    lib = _embree_lib()
    if lib is None or EmbreeDevice.__basicsize__ != _HEAD + 8:
        warnings.warn("embreex's device has an unknown layout: Embree runs its kernels for this CPU, "
                      "and scans may differ in the last bits between machines", stacklevel=3)
        return device
    configured = lib.rtcNewDevice(config)
    if not configured:
        raise ValueError(f"Embree refused the device config {config!r}")
    field = ctypes.c_void_p.from_address(id(device) + _HEAD)
    lib.rtcReleaseDevice(field.value)
    field.value = configured
    return device


def _handles(scene: EmbreeScene, device: EmbreeDevice) -> tuple[int, int] | None:
    """The RTCScene and RTCDevice behind `scene` (made with `device`), which embreex keeps in C
    fields (rtcore_scene.pxd: scene_i, is_committed, device; rtcore.pxd: device); None unless the
    objects have that layout and the scene's device field is `device`."""
    def pointer_at(obj, offset: int) -> int | None:
        return ctypes.c_void_p.from_address(id(obj) + offset).value

    if (EmbreeScene.__basicsize__, EmbreeDevice.__basicsize__) != (_HEAD + 24, _HEAD + 8):
        return None
    if pointer_at(scene, _HEAD + 16) != id(device):
        return None
    return pointer_at(scene, _HEAD), pointer_at(device, _HEAD)
