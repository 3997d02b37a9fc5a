"""FlexiNet shapes for every preset and activation, scaling rules, BN folding; torch's kernels."""
import os
import subprocess
import sys

import pytest
import torch

from detector.layers import ACTIVATIONS, Focus
from detector.model import PRESETS, STRIDES, FlexiNet, ModelConfig, count_parameters
from kitti.cpu import portable_networks


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_output_shapes_every_preset(preset):
    torch.manual_seed(0)
    cfg = ModelConfig.from_preset(preset, num_classes=3)
    model = FlexiNet(cfg).eval()
    x = torch.rand(1, 3, 64, 96)
    raw = model(x)
    assert len(raw) == 3
    for p, s in zip(raw, STRIDES):
        assert p.shape == (1, 3, 64 // s, 96 // s, 8)
    dec = model.predict_raw(x)
    n = sum(3 * (64 // s) * (96 // s) for s in STRIDES)
    assert dec.shape == (1, n, 8)
    assert torch.isfinite(dec).all()


def test_inference_convolutions_do_not_follow_torch_s_nnpack_setting():
    """`detect --batch 8` reads 16 images with the mirrored ones, a batch for which ATen would
    take NNPACK, whose sums follow the CPU's cache sizes; the reads' products are OpenBLAS's."""
    torch.manual_seed(0)
    model = FlexiNet(ModelConfig.from_preset("small", num_classes=3)).eval()
    x = torch.rand(16, 3, 64, 96)
    out = []
    for enabled in (True, False):
        with torch.backends.nnpack.flags(enabled=enabled), torch.no_grad(), portable_networks():
            out.append(model.predict_raw(x))
    assert torch.equal(*out)


@pytest.mark.parametrize("shape", [  # (in, out, kernel, stride, padding, dilation, groups, bias)
    (3, 16, 3, 2, 1, 1, 1, True), (32, 64, 1, 1, 0, 1, 1, False), (24, 24, 3, 1, 1, 1, 24, False),
    (16, 32, 5, 1, 2, 2, 4, True), (8, 12, (3, 1), (2, 1), (1, 0), 1, 1, True),
    (16, 16, 3, 2, 1, 1, 16, True), (8, 8, 3, 1, 2, 2, 8, False)])  # depthwise: tap by tap
def test_portable_convolutions_compute_torch_s_convolution(shape):
    cin, cout, k, s, p, d, g, bias = shape
    conv = torch.nn.Conv2d(cin, cout, k, s, p, d, g, bias=bias)
    x = torch.randn(3, cin, 23, 37, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        want = conv(x)
        with portable_networks():
            got = conv(x)
    assert got.shape == want.shape
    torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-5)
    lin = torch.nn.Linear(cin, cout)
    with torch.no_grad():
        want = lin(x.transpose(1, 3))
        with portable_networks():
            got = lin(x.transpose(1, 3))
    torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-5)


def test_training_keeps_torch_s_operators_and_their_gradients():
    conv = torch.nn.Conv2d(3, 4, 3)
    with portable_networks():
        y = conv(torch.rand(1, 3, 8, 8))
    assert y.requires_grad
    y.sum().backward()
    assert conv.weight.grad is not None and conv.weight.grad.abs().sum() > 0


def test_presets_scale_depth_and_width():
    sizes = {p: count_parameters(FlexiNet(ModelConfig.from_preset(p))) for p in PRESETS}
    assert sizes["small"] < sizes["s"] < sizes["vehicle"]
    # width 0.25 -> 0.50 with the same depth: conv weights grow about 4x
    assert 3.3 < sizes["s"] / sizes["small"] < 4.5
    m = FlexiNet(ModelConfig.from_preset("vehicle"))
    # vehicle: 0.55 x (3, 9, 9, 3) CSP repeats -> 2, 5, 5, 2 bottlenecks; 0.55 x 64 -> 40 stem channels
    assert [len(s[1].m) for s in (m.down1, m.down2, m.down3)] == [2, 5, 5]
    assert m.stem.conv.conv.out_channels == 40


@pytest.mark.parametrize("act", ACTIVATIONS)
def test_every_activation_runs_and_fuses_exactly(act):
    torch.manual_seed(1)
    model = FlexiNet(ModelConfig(activation=act, width_multiple=0.125))
    model.train()
    for _ in range(2):  # give batch norms non-trivial running statistics
        model(torch.rand(2, 3, 64, 96))
    model.eval()
    x = torch.rand(1, 3, 64, 96)
    ref = model.predict_raw(x)
    fused = model.fuse().predict_raw(x)
    assert torch.allclose(ref, fused, rtol=1e-4, atol=1e-4)


def test_focus_is_space_to_depth():
    f = Focus(3, 8)
    x = torch.arange(2 * 3 * 4 * 6, dtype=torch.float32).view(2, 3, 4, 6)
    captured = {}

    def grab(module, inputs, output):
        captured["in"] = inputs[0]

    f.conv.conv.register_forward_hook(grab)
    f(x)
    s2d = captured["in"]
    assert s2d.shape == (2, 12, 2, 3)
    # channel block 1 holds the odd rows, even columns: input pixel (1, 0) goes to (0, 0)
    assert s2d[0, 3, 0, 0] == x[0, 0, 1, 0]
    assert s2d[0, 6, 0, 0] == x[0, 0, 0, 1]
    assert s2d[0, 9, 1, 2] == x[0, 0, 3, 5]


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="multiples of 32"):
        FlexiNet(ModelConfig())(torch.rand(1, 3, 100, 96))
    with pytest.raises(ValueError, match="activation"):
        FlexiNet(ModelConfig(activation="relu6"))
    with pytest.raises(ValueError, match="preset"):
        ModelConfig.from_preset("huge")


@pytest.mark.parametrize("package", ["detector", "lifter"])
def test_importing_a_torch_package_caps_torch_at_avx2(package):
    """Kernels of different widths round differently: on any CPU from AVX2 up, torch must run AVX2's
    (on an AVX-512 machine it would otherwise pick AVX512's). A fresh interpreter, nothing set."""
    env = {k: v for k, v in os.environ.items() if k not in ("ATEN_CPU_CAPABILITY", "ONEDNN_MAX_CPU_ISA")}
    code = (f"import torch, {package}, os; torch.ones(2) + 1; "
            "print(torch.backends.cpu.get_cpu_capability(), os.environ['ONEDNN_MAX_CPU_ISA'])")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    has_avx2 = "avx2" in open("/proc/cpuinfo").read()
    assert out.stdout.split() == ["AVX2" if has_avx2 else "DEFAULT", "AVX2"]
