"""A KITTI-format dataset root (ours or the real benchmark): ImageSets/ plus training/ and testing/."""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np

from .calib import Calibration, read_calib
from .errors import KittiFormatError
from .labels import Object3D, read_label
from .planes import read_plane
from .splits import read_split
from .velodyne import read_velodyne


class KittiDataset:
    """Typed access to one part (`training` or `testing`) of a KITTI-format root."""

    def __init__(self, root: str | Path, part: str = "training"):
        self.root = Path(root)
        self.part = part
        self.dir = self.root / part
        if not self.dir.is_dir():
            raise KittiFormatError(f"no '{part}' folder in the dataset root", self.root)

    def path(self, sub: str, fid: str, ext: str) -> Path:
        return self.dir / sub / f"{fid}.{ext}"

    def ids(self, split: str | None = None) -> list[str]:
        """Frame ids of ImageSets/<split>.txt, or every frame with an image when split is None."""
        if split is not None:
            split_file = self.root / "ImageSets" / f"{split}.txt"
            if not split_file.exists():
                raise KittiFormatError("split file not found", split_file)
            return read_split(split_file)
        return sorted(p.stem for p in (self.dir / "image_2").glob("*.png"))

    def image_path(self, fid: str) -> Path:
        return self.path("image_2", fid, "png")

    def image(self, fid: str) -> np.ndarray:
        path = self.image_path(fid)
        try:
            img = iio.imread(path)
        except (OSError, SyntaxError, ValueError) as e:  # imageio's decoders raise all three
            raise KittiFormatError(f"cannot be read as an image ({e})", path) from None
        if img.ndim == 2:
            img = np.repeat(img[..., None], 3, axis=2)
        return img[..., :3]

    def image_size(self, fid: str) -> tuple[int, int]:
        """(width, height) of image_2."""
        path = self.image_path(fid)
        try:
            meta = iio.improps(path)
        except (OSError, SyntaxError, ValueError) as e:
            raise KittiFormatError(f"cannot be read as an image ({e})", path) from None
        return int(meta.shape[1]), int(meta.shape[0])

    def labels(self, fid: str) -> list[Object3D]:
        return read_label(self.path("label_2", fid, "txt"))

    def calib(self, fid: str) -> Calibration:
        return read_calib(self.path("calib", fid, "txt"))

    def has_velodyne(self, fid: str) -> bool:
        return self.path("velodyne", fid, "bin").exists()

    def velodyne(self, fid: str) -> np.ndarray | None:
        return read_velodyne(self.path("velodyne", fid, "bin")) if self.has_velodyne(fid) else None

    def planes(self, fid: str) -> np.ndarray | None:
        p = self.path("planes", fid, "txt")
        return read_plane(p) if p.exists() else None
