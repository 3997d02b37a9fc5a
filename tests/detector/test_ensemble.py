"""Output-space ensembles (`detector.infer.save_ensemble`, `Detector.models`): every network's
plain and mirrored reads are views of one NMS, each box scored by the mean over the views."""
from pathlib import Path

import numpy as np
import pytest
import torch

from detector.infer import DEFAULT_WEIGHTS, Detector, save_ensemble

ONE = (1.0,)  # each network read at its input size only (with its mirror): two views a network


def blind_copy(path: Path) -> Path:
    """The shipped network with every objectness logit pushed to -1e4: it proposes nothing."""
    ck = torch.load(DEFAULT_WEIGHTS, map_location="cpu", weights_only=True)
    na = 3
    for k, v in ck["model"].items():
        if k.startswith("head.m.") and k.endswith(".bias"):
            b = v.clone().view(na, -1)
            b[:, 4] = -1e4
            ck["model"][k] = b.view(-1)
    torch.save(ck, path)
    return path


def test_one_network_twice_reads_as_the_network(street, tmp_path):
    save_ensemble(tmp_path / "twice.pt", [DEFAULT_WEIGHTS, DEFAULT_WEIGHTS])
    twice, once = Detector.load(tmp_path / "twice.pt", scales=ONE), Detector.load(scales=ONE)
    assert len(twice.models) == 2 and twice.views == 4 and once.views == 2
    a, b = once.detect([street], 0.05)[0], twice.detect([street], 0.05)[0]
    assert len(a) >= 10 and a.shape == b.shape
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-4)


def test_a_network_that_proposes_nothing_halves_every_score(street, tmp_path):
    """Its two views hold no candidate, so each box's mean over four views is half its mean over
    the shipped network's two; the boxes and their order are the shipped network's."""
    save_ensemble(tmp_path / "half.pt", [DEFAULT_WEIGHTS, blind_copy(tmp_path / "blind.pt")])
    a = Detector.load(scales=ONE).detect([street], 0.05)[0]
    b = Detector.load(tmp_path / "half.pt", scales=ONE).detect([street], 0.05)[0]
    assert len(a) >= 10 and a.shape == b.shape
    np.testing.assert_array_equal(b[:, [0, 1, 2, 3, 5]], a[:, [0, 1, 2, 3, 5]])
    np.testing.assert_allclose(b[:, 4], a[:, 4] / 2, rtol=1e-6)
    assert len(Detector.load(tmp_path / "blind.pt").detect([street], 0.001)[0]) == 0


def test_bad_ensembles_are_named(tmp_path):
    with pytest.raises(ValueError, match="at least two"):
        save_ensemble(tmp_path / "one.pt", [DEFAULT_WEIGHTS])
    save_ensemble(tmp_path / "e.pt", [DEFAULT_WEIGHTS, DEFAULT_WEIGHTS])
    with pytest.raises(ValueError, match="e.pt: already an ensemble"):
        save_ensemble(tmp_path / "ee.pt", [tmp_path / "e.pt", DEFAULT_WEIGHTS])
    ck = torch.load(DEFAULT_WEIGHTS, map_location="cpu", weights_only=True)
    torch.save({**ck, "input_size": [640, 192]}, tmp_path / "small.pt")
    with pytest.raises(ValueError, match="ensemble member 1: another input size"):
        save_ensemble(tmp_path / "mixed.pt", [DEFAULT_WEIGHTS, tmp_path / "small.pt"])
    assert not (tmp_path / "mixed.pt").exists()
    torch.save({"members": [ck, {k: v for k, v in ck.items() if k != "model"}]}, tmp_path / "cut.pt")
    with pytest.raises(ValueError, match=r"cut.pt: ensemble member 1: not a FlexiNet checkpoint \(missing 'model"):
        Detector.load(tmp_path / "cut.pt")


def test_training_refuses_to_start_from_an_ensemble(tmp_path):
    from detector.train import TrainConfig, _checkpoints
    save_ensemble(tmp_path / "e.pt", [DEFAULT_WEIGHTS, DEFAULT_WEIGHTS])
    with pytest.raises(ValueError, match="e.pt: an ensemble of 2 networks; start from one of them"):
        _checkpoints(TrainConfig(data="x", out=str(tmp_path / "run"), init=str(tmp_path / "e.pt")),
                     tmp_path / "run" / "last.pt", resume=False)
