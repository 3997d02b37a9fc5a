"""Fixtures shared by the fidelity tests."""

from pathlib import Path

import pytest

REAL = Path(__file__).resolve().parents[3] / "shared" / "kitti_real_dev"  # beside the repository


@pytest.fixture(scope="module")
def real_root() -> Path:
    """The real KITTI dev frames; tests that need them skip, saying why, where they are absent."""
    if not (REAL / "training").is_dir():
        pytest.skip(f"real KITTI frames not found at {REAL}")
    return REAL
