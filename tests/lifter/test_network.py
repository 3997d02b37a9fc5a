"""Size and orientation network: MultiBin coding, the loss, a tiny seeded training run, inference."""

import numpy as np
import pytest
import torch

from lifter import multibin
from lifter.network import CLASSES, NetConfig, SizeOrientationNet, loss_fn
from lifter.predictor import DEFAULT_WEIGHTS, Predictor, forward_mirrored, load_network
from lifter.train import train
from lifter.types import Box2D
from tests.lifter.synth import make_frame, write_dataset


def test_multibin_round_trip_and_overlap():
    alpha = np.linspace(-np.pi, np.pi, 721)[:-1] + 1e-3  # no angle exactly on a bin edge
    best, cs, cover = multibin.encode(alpha)
    logits = np.eye(multibin.N_BINS)[best] * 5
    np.testing.assert_allclose(multibin.wrap(multibin.decode(logits, cs) - alpha), 0, atol=1e-12)
    # two bins centred at -90 and +90 degrees, overlapping by 15 degrees either side of 0 and 180
    near_seam = np.minimum(np.abs(alpha), np.pi - np.abs(alpha)) <= np.deg2rad(15)
    np.testing.assert_array_equal(cover.all(axis=1), near_seam)
    _, _, cov = multibin.encode(np.deg2rad([10.0, 60.0, -170.0]))
    np.testing.assert_array_equal(cov, [[True, True], [False, True], [True, True]])


def test_loss_is_zero_at_the_truth_and_weighted_6_and_3():
    dims = torch.tensor([[1.5, 1.6, 3.9]])
    best, cs, cover = multibin.encode(np.array([0.3]))
    conf = torch.tensor([[-50.0, 50.0]]) if best[0] == 1 else torch.tensor([[50.0, -50.0]])
    out = (dims, conf, torch.from_numpy(cs).float())
    total, parts = loss_fn(out, dims, torch.from_numpy(best), torch.from_numpy(cs).float(),
                           torch.from_numpy(cover))
    assert float(total) == pytest.approx(0.0, abs=1e-6)
    # orientation off by 90 degrees in the covering bin: |u - v|^2 = 2, weighted by 6
    rot = torch.from_numpy(np.stack([-cs[..., 1], cs[..., 0]], -1)).float()
    total, parts = loss_fn((dims, conf, rot), dims, torch.from_numpy(best),
                           torch.from_numpy(cs).float(), torch.from_numpy(cover))
    assert parts["orient"] == pytest.approx(2.0, abs=1e-5)
    assert float(total) == pytest.approx(12.0, abs=1e-4)


def test_mobilenet_v2_shapes_and_class_means():
    net = SizeOrientationNet(NetConfig(width=0.25, crop=64, last_channels=64, hidden=32)).eval()
    x = torch.zeros(5, 3, 64, 64)
    cls = torch.tensor([0, 1, 2, 3, 4])
    with torch.no_grad():
        torch.nn.init.zeros_(net.dims.weight)
        torch.nn.init.zeros_(net.dims.bias)
        dims, conf, cs = net(x, cls)
    assert conf.shape == (5, 2) and cs.shape == (5, 2, 2)
    np.testing.assert_allclose(dims.numpy(), np.array(NetConfig().class_means), rtol=1e-6)
    assert CLASSES[:3] == ("Car", "Pedestrian", "Cyclist")


def test_mirrored_inference_is_exactly_mirror_symmetric():
    """Averaged with its mirror image, a crop and its mirror get the same size and alphas that
    are each other's mirror (alpha -> pi - alpha) to float precision; a single pass does not."""
    net = load_network(DEFAULT_WEIGHTS)
    rng = np.random.default_rng(5)
    x = torch.from_numpy(rng.normal(size=(4, 3, net.cfg.crop, net.cfg.crop)).astype(np.float32))
    cls = torch.tensor([0, 0, 1, 2])
    with torch.no_grad():
        fused = [forward_mirrored(net, v, cls) for v in (x, x.flip(-1))]
        single = [net(v, cls) for v in (x, x.flip(-1))]
    a, b = (multibin.decode(f[1].numpy(), f[2].numpy()) for f in fused)
    np.testing.assert_allclose(multibin.wrap(a + b - np.pi), 0, atol=1e-5)
    np.testing.assert_allclose(fused[0][0].numpy(), fused[1][0].numpy(), atol=1e-5)
    a1, b1 = (multibin.decode(f[1].numpy(), f[2].numpy()) for f in single)
    assert np.abs(multibin.wrap(a1 + b1 - np.pi)).max() > 1e-3


def test_priors_are_the_same_whatever_torch_s_nnpack_setting():
    """A frame of 11 crops is a batch of 22 with their mirror images, for which ATen would take
    NNPACK, whose sums follow the CPU's cache sizes: the predictor's priors must be the same
    either way (its products run on OpenBLAS: kitti.cpu.portable_networks)."""
    rng = np.random.default_rng(3)
    image = rng.integers(0, 256, (375, 1242, 3), dtype=np.uint8)
    x1, y1 = rng.uniform(0, 1100, 11), rng.uniform(120, 250, 11)
    boxes = [Box2D("Car", np.array([a, b, a + w, b + h]), 1.0)
             for a, b, w, h in zip(x1, y1, rng.uniform(30, 140, 11), rng.uniform(25, 110, 11))]
    pred, priors = Predictor(), []
    for enabled in (True, False):
        with torch.backends.nnpack.flags(enabled=enabled):
            priors.append(pred(image, boxes))
    for a, b in zip(*priors):
        assert a.alpha == b.alpha
        np.testing.assert_array_equal(a.dims, b.dims)

def _tiny_dataset(root):
    rng = np.random.default_rng(0)
    frames = []
    for _ in range(6):
        boxes = [[rng.uniform(-6, 6), 1.65, rng.uniform(8, 30), 1.5, 1.7, 4.2, rng.uniform(-3, 3)]
                 for _ in range(3)]
        frames.append(make_frame(boxes, beams=8))
    return write_dataset(root, frames, split="train")


def test_tiny_training_run_is_seeded_and_its_checkpoint_serves(tmp_path):
    _tiny_dataset(tmp_path / "data")
    kw = dict(epochs=2, crop_size=32, width=0.25, batch_size=8, seed=3, threads=1)
    s1 = train(tmp_path / "data", tmp_path / "run1", **kw)
    s2 = train(tmp_path / "data", tmp_path / "run2", **kw)
    assert s1["epochs_run"] == 2 and s1["train_samples"] > 0
    assert s1["last"] == s2["last"]  # same data and seed: same run
    for name in ("last.pt", "best.pt", "log.jsonl", "summary.json"):
        assert (tmp_path / "run1" / name).exists()
    a = load_network(tmp_path / "run1" / "best.pt").state_dict()
    b = load_network(tmp_path / "run2" / "best.pt").state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    pred = Predictor(tmp_path / "run1" / "best.pt")
    img = np.full((375, 1242, 3), 100, dtype=np.uint8)
    priors = pred(img, [Box2D("Car", np.array([100.0, 150, 200, 220]), 0.9),
                        Box2D("Pedestrian", np.array([500.0, 150, 530, 230]), 0.8)])
    assert len(priors) == 2 and all(p.dims.shape == (3,) and -np.pi <= p.alpha <= np.pi for p in priors)


def test_fine_tuning_starts_from_the_given_weights(tmp_path):
    _tiny_dataset(tmp_path / "data")
    kw = dict(crop_size=32, width=0.25, batch_size=8, seed=3, threads=1)
    train(tmp_path / "data", tmp_path / "base", epochs=1, **kw)
    init = tmp_path / "base" / "last.pt"
    # with a zero learning rate the parameters stay exactly where --init put them
    train(tmp_path / "data", tmp_path / "tuned", epochs=1, lr=0.0, init=init, **kw)
    a = load_network(init).named_parameters()
    b = dict(load_network(tmp_path / "tuned" / "last.pt").named_parameters())
    assert all(torch.equal(p, b[k]) for k, p in a)
    fresh = dict(load_network(tmp_path / "base" / "last.pt").named_parameters())
    train(tmp_path / "data", tmp_path / "other", epochs=1, lr=0.0, **{**kw, "seed": 4})
    other = dict(load_network(tmp_path / "other" / "last.pt").named_parameters())
    assert not all(torch.equal(p, other[k]) for k, p in fresh.items())  # without --init they differ
    with pytest.raises(ValueError, match="crop 32"):
        train(tmp_path / "data", tmp_path / "bad", epochs=1, init=init, **{**kw, "crop_size": 64})


def test_bad_checkpoint_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.pt"):
        load_network(tmp_path / "nope.pt")
    torch.save({"weights": 1}, tmp_path / "bad.pt")
    with pytest.raises(ValueError, match="bad.pt"):
        load_network(tmp_path / "bad.pt")
