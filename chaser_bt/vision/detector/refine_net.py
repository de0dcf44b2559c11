"""The box refiner's network, its training and its ONNX export (torch). The refiner itself, its
configuration and what runs it at inference without torch are :mod:`chaser_bt.vision.detector.refine`;
this module imports nothing of it (a configuration is any object with ``input_px``, ``widths`` and ``to_dict()``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import torch
from torch import nn

from chaser_bt.vision.detector.model import conv_bn_act

__all__ = ["BoxRefinerNet", "train_refiner", "export_network_onnx"]


class BoxRefinerNet(nn.Module):
    """(B, 3, P, P) crops in [0, 1] and (B, 4) the boxes they were cut around -> (B, 4) refined boxes;
    boxes are x0, y0, x1, y1 as fractions of the crop side, and the network predicts the correction.
    With ``config.scores`` it returns ``(refined, logit)``, logit (B, 1): the crop holds a target."""

    def __init__(self, config) -> None:
        super().__init__()
        self.config = config
        layers, cin = [], 3
        for w in config.widths:
            layers += [conv_bn_act(cin, w, 3, 2), conv_bn_act(w, w, 3, 1)]
            cin = w
        self.features = nn.Sequential(*layers)
        cells = (config.input_px // 2 ** len(config.widths)) ** 2
        self.scores = bool(getattr(config, "scores", False))
        self.head = nn.Sequential(nn.Flatten(), nn.Linear(cin * cells, 128), nn.LeakyReLU(0.1, inplace=True),
                                  nn.Linear(128, 5 if self.scores else 4))

    def forward(self, x: torch.Tensor, boxes: torch.Tensor) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        out = self.head(self.features(x))
        if not self.scores:
            return boxes + out
        return boxes + out[:, :4], out[:, 4:]


def _to_tensor(crops: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(crops[..., ::-1])).permute(0, 3, 1, 2).float().div_(255.0)


def train_refiner(crops: np.ndarray, given: np.ndarray, targets: np.ndarray, out_path: str | Path, config,
                  steps: int = 3000, batch: int = 128, lr: float = 2e-3, seed: int = 0, progress="stderr",
                  negatives: tuple[np.ndarray, np.ndarray] | None = None) -> Path:
    """Fit :class:`BoxRefinerNet` (smooth L1 on the box fractions, horizontal flips, AdamW with a cosine decay)
    and save ``{"config", "state_dict"}`` (fp16) to ``out_path``.

    With ``config.scores`` the score is learnt besides (binary cross-entropy): the crops given are targets,
    ``negatives`` (crops and the boxes they were cut around, :func:`~chaser_bt.vision.detector.refine.make_negative_set`)
    are not; each batch is half of each, and only the targets' boxes count in the box loss."""
    if progress == "stderr":  # the stream at call time, not at import (a test runner swaps it)
        progress = sys.stderr
    scores = bool(getattr(config, "scores", False))
    if scores and (negatives is None or len(negatives[0]) == 0):
        raise ValueError("a scoring refiner needs negative crops (the detector's false boxes)")
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = BoxRefinerNet(config)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    n_pos = len(crops)
    if scores:
        crops, given = np.concatenate([crops, negatives[0]]), np.concatenate([given, negatives[1]])
        # Negatives' rows only keep the arrays aligned: their boxes never enter the box loss (a batch's first half does).
        targets = np.concatenate([targets, negatives[1]])
    x_all = _to_tensor(crops)
    g_all = torch.from_numpy(given)
    y_all = torch.from_numpy(targets)
    net.train()
    for step in range(steps):
        for g in opt.param_groups:
            g["lr"] = lr * 0.5 * (1 + math.cos(math.pi * step / steps))
        if scores:
            half = batch // 2
            idx = torch.from_numpy(np.concatenate([rng.integers(n_pos, size=half), rng.integers(n_pos, len(x_all), size=batch - half)]))
        else:
            idx = torch.from_numpy(rng.integers(len(x_all), size=batch))
        x, g, y = x_all[idx], g_all[idx].clone(), y_all[idx].clone()
        flip = torch.from_numpy(rng.random(batch) < 0.5)
        x[flip] = x[flip].flip(3)
        for b in (g, y):
            b[flip] = torch.stack([1 - b[flip, 2], b[flip, 1], 1 - b[flip, 0], b[flip, 3]], 1)
        if scores:
            is_target = (idx < n_pos).float()[:, None]
            refined, logit = net(x, g)
            loss = (nn.functional.smooth_l1_loss(refined[:half], y[:half], beta=0.02)
                    + 0.1 * nn.functional.binary_cross_entropy_with_logits(logit, is_target))
        else:
            loss = nn.functional.smooth_l1_loss(net(x, g), y, beta=0.02)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if progress is not None and ((step + 1) % 100 == 0 or step + 1 == steps):
            progress.write(f"refiner {step + 1}/{steps} loss {float(loss.detach()):.4f}\n")
            progress.flush()
    net.eval()
    sd = {k: (v.half() if v.dtype == torch.float32 else v) for k, v in net.state_dict().items()}
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"config": config.to_dict(), "state_dict": sd}, out)
    return out


def export_network_onnx(net: BoxRefinerNet, out_path: str | Path) -> Path:
    """Write ``net`` to ONNX: inputs ``crops`` (B, 3, P, P) and ``boxes`` (B, 4), output ``refined`` (B, 4)
    and, for a scoring refiner, ``logit`` (B, 1); B free."""
    p = net.config.input_px
    outputs = ["refined", "logit"] if getattr(net.config, "scores", False) else ["refined"]
    torch.onnx.export(net.eval(), (torch.zeros(2, 3, p, p), torch.zeros(2, 4)), str(out_path), input_names=["crops", "boxes"],
                      output_names=outputs, opset_version=17,
                      dynamic_axes={"crops": {0: "n"}, "boxes": {0: "n"}} | {o: {0: "n"} for o in outputs}, dynamo=False)
    return Path(out_path)
