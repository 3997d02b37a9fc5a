"""User meshes: any file trimesh loads (OBJ, GLB, PLY, STL...), registered with a class.

The file's frame is taken as x forward, y left, z up (`up: y` converts the glTF/OBJ habit of
y up, -z forward... to it). With a target size the mesh is scaled per axis to exactly h, w, l;
without, it keeps its own size. Either way the label box is the mesh's exact extent.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh

from .world import Material, Part, fit_parts

# y-up files (x right, y up, z towards the viewer) to x forward, y left, z up: the model's
# front is taken to be +x in the file as well, so only the vertical axis moves.
_Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@lru_cache(maxsize=32)
def _load(path: str, up: str) -> trimesh.Trimesh:
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as e:  # trimesh raises many types for unreadable files
        raise ValueError(f"{path}: trimesh cannot load this mesh: {e}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{path}: no triangles in this mesh")
    v = np.asarray(mesh.vertices, dtype=float)
    if up == "y":
        v = v @ _Y_UP_TO_Z_UP.T
    return trimesh.Trimesh(v, np.asarray(mesh.faces), process=False)


def user_recipe(path: str, cls: str, size, up: str, color, reflectivity: float) -> dict:
    """A recipe for a user mesh; dims are the final h, w, l (its own extent if size is None)."""
    mesh = _load(str(Path(path).resolve()), up)
    if size is None:
        ext = mesh.bounds[1] - mesh.bounds[0]
        size = (float(ext[2]), float(ext[1]), float(ext[0]))
    return {"kind": "user", "cls": cls, "path": str(Path(path).resolve()), "up": up,
            "dims": [float(s) for s in size], "color": [float(c) for c in color],
            "reflectivity": float(reflectivity)}


def build_user_parts(recipe: dict) -> list[Part]:
    mesh = _load(recipe["path"], recipe.get("up", "z"))
    mat = Material("user", tuple(recipe["color"]), recipe["reflectivity"])
    h, w, l = recipe["dims"]
    return fit_parts([Part(mesh.copy(), mat)], h, w, l)
