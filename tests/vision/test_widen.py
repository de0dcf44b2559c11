"""Widening a trained detector keeps its output and leaves the new channels free to learn."""

from __future__ import annotations

import pytest
import torch

from chaser_bt.vision.detector.model import DetectorConfig, TinyYolo
from chaser_bt.vision.detector.widen import widen


def _trained_like(seed: int) -> TinyYolo:
    """A small net whose batch norms carry non-trivial statistics, as a trained one's do."""
    torch.manual_seed(seed)
    model = TinyYolo(DetectorConfig(widths=(8, 16, 24, 32, 40), num_classes=3, class_names=("a", "b", "c")))
    with torch.no_grad():
        for m in model.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.uniform_(-0.5, 0.5)
                m.running_var.uniform_(0.5, 2.0)
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
    return model.eval()


@pytest.mark.parametrize("widths", [(8, 16, 24, 32, 40), (8, 16, 40, 32, 40), (12, 20, 36, 64, 96)])
def test_the_wider_net_computes_the_same_output(widths):
    model = _trained_like(0)
    wide = widen(model, widths).eval()
    x = torch.rand(2, 3, 96, 128)
    with torch.no_grad():
        assert torch.allclose(wide(x), model(x), atol=1e-5)
    assert wide.config.widths == widths and wide.config.class_names == model.config.class_names


def test_the_new_channels_learn():
    """The zero weights into the trained channels take gradient at once; the new kernels after one step."""
    wide = widen(_trained_like(1), (8, 16, 32, 48, 64)).train()
    opt = torch.optim.SGD(wide.parameters(), lr=0.1)
    x = torch.rand(2, 3, 64, 64)
    wide(x).square().mean().backward()
    assert wide.s16[1][0].weight.grad[:32, 32:].abs().sum() > 0
    assert wide.head.weight.grad[:, 24:].abs().sum() > 0
    assert wide.s16[1][0].weight.grad[32:].abs().sum() == 0   # nothing reads them yet
    opt.step()
    opt.zero_grad()
    wide(x).square().mean().backward()
    assert wide.s16[1][0].weight.grad[32:].abs().sum() > 0


def test_a_narrower_or_different_depth_request_is_refused():
    model = _trained_like(2)
    with pytest.raises(ValueError, match="at least the trained"):
        widen(model, (8, 16, 20, 32, 40))
    with pytest.raises(ValueError, match="5 stages"):
        widen(model, (8, 16, 24, 32))
