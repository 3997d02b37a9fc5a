"""Which frames share a drive: the two-column file, the KITTI devkit's mapping folder, the errors
that name the file and line, and the bootstrap's draws of whole drives."""

from __future__ import annotations

import numpy as np
import pytest

from kitti import KittiFormatError, read_drives
from kitti.drives import draw_units, drive_units


def test_frame_drive_pairs_with_comments(tmp_path):
    path = tmp_path / "drives.txt"
    path.write_text("# traffic jam\n1206 jam\n001497   jam  # same street\n\n000005 rural\n")
    assert read_drives(path) == {"001206": "jam", "001497": "jam", "000005": "rural"}


@pytest.mark.parametrize("text, line, what", [
    ("000001 a\n000002\n", 2, "found 1 fields"),
    ("000001 a b\n", 1, "found 3 fields"),
    ("x1 a\n", 1, "'x1' is not a frame id"),
    ("000001 a\n000001 b\n", 2, "already on drive 'a'"),
])
def test_a_bad_line_is_named(tmp_path, text, line, what):
    path = tmp_path / "drives.txt"
    path.write_text(text)
    with pytest.raises(KittiFormatError, match=what) as e:
        read_drives(path)
    assert e.value.path == str(path) and e.value.line == line


def test_the_devkit_mapping_folder(tmp_path):
    """train_rand.txt gives, frame by frame, the 1-based line of train_mapping.txt behind it."""
    (tmp_path / "train_mapping.txt").write_text(
        "2011_09_26 2011_09_26_drive_0001_sync 0000000000\n"
        "2011_09_26 2011_09_26_drive_0001_sync 0000000050\n"
        "2011_09_28 2011_09_28_drive_0016_sync 0000000010\n")
    (tmp_path / "train_rand.txt").write_text("3,1,2\n")
    assert read_drives(tmp_path) == {"000000": "2011_09_28_drive_0016_sync",
                                     "000001": "2011_09_26_drive_0001_sync",
                                     "000002": "2011_09_26_drive_0001_sync"}
    (tmp_path / "train_rand.txt").write_text("3,4,2\n")
    with pytest.raises(KittiFormatError, match="'4' is not a line of train_mapping.txt") as e:
        read_drives(tmp_path)
    assert e.value.field == "entry 2"
    (tmp_path / "train_rand.txt").unlink()
    with pytest.raises(KittiFormatError, match="no such file"):
        read_drives(tmp_path)


def test_units_and_their_draws():
    """Frames b and d on drive x (e names a frame not read): three units; a draw takes three, each
    with all its frames; with every frame alone the draw is rng.integers(n, size=n) itself."""
    units = drive_units(["a", "b", "c", "d"], {"b": "x", "d": "x", "e": "y"})
    assert [u.tolist() for u in units] == [[0], [1, 3], [2]]
    rng, same = np.random.default_rng(3), np.random.default_rng(3)
    for _ in range(20):
        picked = same.integers(3, size=3)
        assert draw_units(rng, units).tolist() == [i for p in picked for i in units[p].tolist()]
    alone = drive_units(["a", "b", "c"])
    assert draw_units(np.random.default_rng(7), alone).tolist() == \
        np.random.default_rng(7).integers(3, size=3).tolist()
