from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def street(tmp_path_factory):
    """One rendered frame of scenes/quickstart.yaml (seed 3, no LiDAR): a street with cars the
    shipped detector finds."""
    from kitti.dataset import KittiDataset
    from simgen.generate import generate
    from simgen.spec import load_spec
    out = tmp_path_factory.mktemp("street") / "q"
    spec = load_spec(Path(__file__).resolve().parents[2] / "scenes/quickstart.yaml")
    generate(spec.model_copy(update={"lidar": None}), out, frames=1, seed=3)
    ds = KittiDataset(out)
    return ds.image(ds.ids(None)[0])
