"""`testbed relabel` against `testbed generate`: the same frames under other label rules."""

from __future__ import annotations

import json

import pytest
import yaml
from click.testing import CliRunner

from kitti.labels import read_label
from simgen.spec import SpecError, load_spec
from testbed.cli import cli

FID = "000000"
RULES = {"min_lidar_points": 20, "max_distance": 50.0}  # both move rows of urban.yaml's frame 0


def _run(*args):
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


def _fails(*args) -> str:
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code != 0
    return res.output


def _files(root):
    return sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())


def _spec_with_labels(tmp_path, labels: dict):
    data = yaml.safe_load(open("scenes/urban.yaml"))
    data["labels"] = {**data["labels"], **labels}
    path = tmp_path / "urban_rules.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_spec(path)


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    from simgen.generate import generate

    root = tmp_path_factory.mktemp("relabel_src")
    generate(load_spec("scenes/urban.yaml"), root, frames=1)
    return root


def test_relabel_with_the_source_rules_reproduces_the_dataset(source, tmp_path):
    out = tmp_path / "same"
    _run("relabel", "--data", source, "--out", out, "--workers", 1)
    files = _files(source)
    assert len(files) >= 9  # image, depth, instance, label, calib, plane, scan, side file, meta...
    for rel in files:
        assert (out / rel).read_bytes() == (source / rel).read_bytes(), rel
    img, label = "training/image_2/000000.png", "training/label_2/000000.txt"
    assert (out / img).stat().st_ino == (source / img).stat().st_ino  # linked, not rewritten
    assert (out / label).stat().st_ino != (source / label).stat().st_ino


def test_relabel_writes_what_generate_writes_under_the_new_rules(source, tmp_path):
    from simgen.generate import generate

    direct = tmp_path / "direct"
    generate(_spec_with_labels(tmp_path, RULES), direct, frames=1)
    out = tmp_path / "relabelled"
    _run("relabel", "--data", source, "--out", out, "--min-lidar-points", 20, "--max-distance", 50,
         "--workers", 1)
    for rel in _files(direct):
        assert (out / rel).read_bytes() == (direct / rel).read_bytes(), rel
    # the rules did move rows, each for its own reason
    meta = json.loads((out / "training/meta/000000.json").read_text())
    before = json.loads((source / "training/meta/000000.json").read_text())
    moved = [(a, b) for a, b in zip(meta["actors"], before["actors"]) if a["label"] != b["label"]]
    assert moved and all(a["label"] == "dontcare" and b["label"] == "label" for a, b in moved)
    assert all(a["lidar_points"] < 20 or a["distance"] > 50 for a, _ in moved)
    assert any(a["lidar_points"] < 20 and a["distance"] <= 50 for a, _ in moved)
    kept = [a for a in meta["actors"] if a["label"] == "label"]
    assert kept and all(a["lidar_points"] >= 20 and a["distance"] <= 50 for a in kept)
    rows = read_label(out / "training/label_2/000000.txt")
    assert sum(o.type != "DontCare" for o in rows) == len(kept)
    assert json.loads((out / "labels.json").read_text())["labels"]["min_lidar_points"] == 20


def test_relabel_resumes_and_refuses_another_request_into_its_root(source, tmp_path):
    out = tmp_path / "r"
    _run("relabel", "--data", source, "--out", out, "--max-distance", 40, "--workers", 1)
    label = out / "training/label_2/000000.txt"
    before = label.stat().st_mtime_ns
    _run("relabel", "--data", source, "--out", out, "--max-distance", 40, "--workers", 1)
    assert label.stat().st_mtime_ns == before
    assert "different request" in _fails("relabel", "--data", source, "--out", out, "--max-distance", 30)


def test_relabel_names_what_it_cannot_do(source, tmp_path):
    from simgen.generate import generate

    assert "--min-visible-share: Input should be less than or equal to 1" in \
        _fails("relabel", "--data", source, "--out", tmp_path / "a", "--min-visible-share", 2)
    assert "--silhouette-sides (item 2)" in \
        _fails("relabel", "--data", source, "--out", tmp_path / "b", "--silhouette-sides", "Pedestrian,Dog")
    not_generated = tmp_path / "kitti"
    (not_generated / "training" / "meta").mkdir(parents=True)
    assert "simgen.json: no generator manifest" in \
        _fails("relabel", "--data", not_generated, "--out", tmp_path / "c")
    manifest = json.loads((source / "simgen.json").read_text())
    (not_generated / "simgen.json").write_text(json.dumps(manifest))
    assert "no meta/NNNNNN.json" in _fails("relabel", "--data", not_generated, "--out", tmp_path / "c")
    manifest["spec"]["labels"]["min_height_px"] = -1.0  # a manifest the rules no longer accept
    (not_generated / "simgen.json").write_text(json.dumps(manifest))
    assert "simgen.json: key 'spec.labels'" in _fails("relabel", "--data", not_generated, "--out", tmp_path / "c")
    camera_only = tmp_path / "camera_only"
    generate(load_spec("scenes/urban.yaml").model_copy(update={"lidar": None}), camera_only, frames=1)
    assert "000000.json: the frame has no scan" in \
        _fails("relabel", "--data", camera_only, "--out", tmp_path / "d", "--min-lidar-points", 5)


def test_a_spec_that_counts_lidar_returns_needs_a_lidar(tmp_path):
    data = yaml.safe_load(open("scenes/urban.yaml"))
    data["labels"]["min_lidar_points"] = 5
    data["lidar"] = "none"
    path = tmp_path / "no_lidar.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(SpecError, match="labels.min_lidar_points counts LiDAR returns"):
        load_spec(path)


def test_relabel_of_a_rescan_counts_the_new_sensors_returns(source, tmp_path):
    """A rescan's meta holds each actor's returns from its own sensor: a point-count rule applied
    to it reads those, so a 16-beam scan leaves more objects below the floor than the 64-beam one."""
    vlp16 = tmp_path / "vlp16"
    _run("rescan", "--data", source, "--out", vlp16, "--lidar", "vlp16", "--workers", 1)
    rules = ("--min-lidar-points", 20, "--workers", 1)
    _run("relabel", "--data", source, "--out", tmp_path / "r64", *rules)
    _run("relabel", "--data", vlp16, "--out", tmp_path / "r16", *rules)
    m16 = json.loads((tmp_path / "r16/training/meta/000000.json").read_text())
    m64 = json.loads((tmp_path / "r64/training/meta/000000.json").read_text())
    assert m16["lidar"]["preset"] == "vlp16"
    for a in m16["actors"]:
        if a["label"] in ("label", "dontcare"):
            assert (a["label"] == "label") == (a["lidar_points"] >= 20 and a["distance"] <= 80
                                               and a["visible_share"] >= 0.1
                                               and a["bbox"][3] - a["bbox"][1] >= 10), a["id"]
    dontcare = [sum(a["label"] == "dontcare" for a in m["actors"]) for m in (m64, m16)]
    assert dontcare[1] > dontcare[0]
    # the scans themselves are the rescan's, linked
    scan = "training/velodyne/000000.bin"
    assert (tmp_path / "r16" / scan).read_bytes() == (vlp16 / scan).read_bytes()
