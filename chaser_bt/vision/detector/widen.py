"""Grow a trained detector's stage widths without changing what it computes (Net2WiderNet).

A CPU cannot afford to train a larger detector from scratch, but it can fine-tune one that starts
where the trained one is. Each conv of the wider net keeps the trained kernel in its first channels;
the new output channels start from the fresh net's random initialisation (so they can learn), and the
trained channels read the new ones through zero weights (so, at the start, they cannot disturb them).
Batch norm keeps its trained statistics. The head therefore gives exactly the old output until the
fine-tune moves the new weights (Chen, Goodfellow, Shlens, "Net2Net", ICLR 2016, with zero rather
than replicated new units).
"""

from __future__ import annotations

from dataclasses import replace

import torch
from torch import nn

from chaser_bt.vision.detector.model import TinyYolo

__all__ = ["widen"]


def _input_channels(name: str, old: TinyYolo, new: TinyYolo, n_in: int) -> torch.Tensor:
    """Where each of a conv's old input channels sits in the wider net.

    Every conv reads one stage's output (its first channels carry over), except the fuse, which reads
    ``cat([p8, top])``: its second half moves up by the growth of the stride-8 width.
    """
    idx = torch.arange(n_in)
    if name == "fuse.0.0":
        w_old, w_new = old.config.widths[2], new.config.widths[2]
        idx = torch.where(idx < w_old, idx, idx - w_old + w_new)
    return idx


def widen(model: TinyYolo, widths: tuple[int, ...]) -> TinyYolo:
    """A copy of ``model`` with stage ``widths`` (each ≥ the old one) that computes the same output."""
    old_w = model.config.widths
    if len(widths) != len(old_w) or any(n < o for n, o in zip(widths, old_w)):
        raise ValueError(f"widths {tuple(widths)} must be {len(old_w)} stages, each at least the trained {old_w}")
    wide = TinyYolo(replace(model.config, widths=tuple(int(w) for w in widths)))
    old_modules = dict(model.named_modules())
    with torch.no_grad():
        for name, m in wide.named_modules():
            o = old_modules[name]
            if isinstance(m, nn.Conv2d):
                n_out, n_in = o.weight.shape[:2]
                cols = _input_channels(name, model, wide, n_in)
                m.weight[:n_out].zero_()                      # trained channels: nothing from the new inputs
                m.weight[:n_out, cols] = o.weight
                if m.bias is not None:
                    m.bias[:n_out] = o.bias
            elif isinstance(m, nn.BatchNorm2d):
                n = o.num_features
                for attr in ("weight", "bias", "running_mean", "running_var"):
                    getattr(m, attr)[:n] = getattr(o, attr)
                m.num_batches_tracked.copy_(o.num_batches_tracked)
    return wide
