"""RandConv's consistency term: the Bernoulli Jensen-Shannon divergence against values computed by
hand, its scaling as the objectness loss, and a training run on pairs."""
import math

import numpy as np
import pytest
import torch

from detector.augment import AugmentConfig
from detector.loss import DetectionLoss, bernoulli_js, bernoulli_kl
from detector.model import FlexiNet, ModelConfig
from detector.train import TrainConfig, train
from tests.detector.toydata import write_toy_dataset


def _js_by_hand(p: float, q: float) -> float:
    m = (p + q) / 2
    kl = lambda a: a * math.log(a / m) + (1 - a) * math.log((1 - a) / (1 - m))  # noqa: E731
    return 0.5 * (kl(p) + kl(q))


def test_bernoulli_js_matches_hand_values_and_is_bounded():
    # p = 0.5 and 0.75: m = 0.625; KL(0.5||m) = 0.032269, KL(0.75||m) = 0.035375
    js = bernoulli_js(torch.tensor([0.0]), torch.tensor([math.log(3.0)])).item()
    assert js == pytest.approx(0.5 * (0.0322693 + 0.0353749), abs=1e-6)
    xs = torch.tensor([-6.0, -2.0, 0.3, 1.0, 4.0], dtype=torch.float64)
    for xa in xs:
        for xb in xs:
            want = _js_by_hand(1 / (1 + math.exp(-xa)), 1 / (1 + math.exp(-xb)))
            assert bernoulli_js(xa.view(1), xb.view(1)).item() == pytest.approx(want, abs=1e-12)
            assert bernoulli_js(xa.view(1), xb.view(1)).item() == bernoulli_js(xb.view(1), xa.view(1)).item()
    # saturated scores stay finite: certain-yes against certain-no is ln 2, the bound
    far = bernoulli_js(torch.tensor([60.0], dtype=torch.float64), torch.tensor([-60.0], dtype=torch.float64))
    assert torch.isfinite(far).all() and far.item() == pytest.approx(math.log(2.0), abs=1e-9)
    assert bernoulli_js(torch.tensor([60.0]), torch.tensor([60.0])).item() == pytest.approx(0.0, abs=1e-12)


def test_pair_consistency_is_zero_for_twins_and_scaled_as_objectness():
    head = FlexiNet(ModelConfig.from_preset("small", num_classes=3)).head
    crit = DetectionLoss(head)
    gen = torch.Generator().manual_seed(0)
    # raw head outputs of a 128 x 64 input (strides 8, 16, 32), logits spread as a trained head's are
    shapes = [(16, 8), (8, 4), (4, 2)]
    other = [torch.randn(2, head.na, h, w, 8, generator=gen, dtype=torch.float64) * 3 for w, h in shapes]
    twins = [torch.cat((p[:1], p[:1], p[1:], p[1:])) for p in other]
    assert crit.pair_consistency(twins).item() == pytest.approx(0.0, abs=1e-12)
    got = crit.pair_consistency(other).item()
    cells = sum(w * h for w, h in shapes)
    want = sum(bernoulli_js(p[0, ..., 4], p[1, ..., 4]).mean().item() * b for p, b in zip(other, crit.g.balance))
    want *= crit.g.obj * cells / (80 ** 2 + 40 ** 2 + 20 ** 2) * 2  # per 640 x 640 cell, times the batch
    assert got > 0 and got == pytest.approx(want, rel=1e-9)
    with pytest.raises(ValueError, match="even"):
        crit.pair_consistency([p[:1] for p in other])


def test_plain_target_is_a_fixed_kl_target():
    # KL(0.5 || 0.75) = 0.5 ln(2/3) + 0.5 ln 2 = 0.143841
    assert bernoulli_kl(torch.tensor([0.0]), torch.tensor([math.log(3.0)])).item() == pytest.approx(0.143841, abs=1e-6)
    assert bernoulli_kl(torch.tensor([2.0]), torch.tensor([2.0])).item() == pytest.approx(0.0, abs=1e-7)
    head = FlexiNet(ModelConfig.from_preset("small", num_classes=3)).head
    crit = DetectionLoss(head)
    gen = torch.Generator().manual_seed(1)
    raw = [(torch.randn(4, head.na, h, w, 8, generator=gen, dtype=torch.float64) * 3).requires_grad_()
           for w, h in [(16, 8), (8, 4), (4, 2)]]
    got = crit.pair_consistency(raw, "plain")
    want = sum(bernoulli_kl(p[0::2, ..., 4], p[1::2, ..., 4]).mean() * b for p, b in zip(raw, crit.g.balance))
    want = want * crit.g.obj * (16 * 8 + 8 * 4 + 4 * 2) / (80 ** 2 + 40 ** 2 + 20 ** 2) * 4
    assert got.item() == pytest.approx(want.item(), rel=1e-9)
    got.backward()
    for p in raw:  # the plain views (even images) get no gradient, the convolved ones do
        assert torch.count_nonzero(p.grad[0::2]) == 0 and torch.count_nonzero(p.grad[1::2, ..., 4]) > 0
        assert torch.count_nonzero(p.grad[1::2, ..., :4]) == 0  # objectness only
    with pytest.raises(ValueError, match="consistency target"):
        crit.pair_consistency(raw, "both")


def test_training_on_pairs_logs_the_term_and_config_is_checked(tmp_path):
    root = write_toy_dataset(tmp_path / "ds", 6, seed=5, size=(128, 64), max_objects=3)
    base = dict(data=str(root), img_size=(128, 64), epochs=1, batch=4, eval_every=0, progress=False,
                threads=1, close_mosaic=0)
    train(TrainConfig(out=str(tmp_path / "run"), randconv_consistency=12.0, **base))
    head, row = (tmp_path / "run" / "history.csv").read_text().splitlines()[:2]
    cons = float(row.split(",")[head.split(",").index("cons")])
    loss, box, obj, cls = (float(row.split(",")[head.split(",").index(k)]) for k in ("loss", "box", "obj", "cls"))
    assert cons > 0 and loss == pytest.approx(box + obj + cls + cons, rel=1e-5)
    saved = torch.load(tmp_path / "run" / "weights.pt", weights_only=True)["train_config"]
    assert saved["randconv_consistency"] == 12.0
    for bad, field in ((dict(randconv_consistency=-1.0), "randconv_consistency"),
                       (dict(randconv_consistency=1.0, batch=3), "batch"),
                       (dict(randconv_consistency=1.0, augment=AugmentConfig(randconv_prob=0.5)), "randconv_prob"),
                       (dict(randconv_consistency=1.0, augment=AugmentConfig(photometric=False)), "photometric"),
                       (dict(randconv_consistency=1.0, randconv_consistency_target="both"), "randconv_consistency_target")):
        with pytest.raises(ValueError, match=field):
            TrainConfig(**{**base, "out": str(tmp_path / "x"), **bad})
    assert np.isfinite(cons)
