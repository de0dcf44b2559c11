"""A small single-stage detector in the YOLO family (paper section 3.1: YOLOv2; here sized for a CPU).

A plain conv backbone (stride 2 stages to 1/32) with one top-down merge back to stride 8, and a
1x1 head per stride-8 cell giving objectness, the box centre offset and size, and class scores:
anchor-free like YOLOX/FCOS, one scale because drone targets are small. Decoding follows YOLOv5:
centre = (cell + 2 sigmoid(t) - 0.5) * stride, size = stride * exp(t) (clamped).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

__all__ = ["DetectorConfig", "TinyYolo", "conv_bn_act"]


@dataclass(frozen=True)
class DetectorConfig:
    """Network shape: ``widths`` of the stride-2 stages, number of classes and their names."""

    widths: tuple[int, ...] = (16, 32, 48, 96, 128)
    num_classes: int = 2
    class_names: tuple[str, ...] = ("s1000", "phantom")
    stride: int = 8

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "DetectorConfig":
        return cls(widths=tuple(d["widths"]), num_classes=int(d["num_classes"]), class_names=tuple(d["class_names"]), stride=int(d["stride"]))


def conv_bn_act(cin: int, cout: int, k: int = 3, s: int = 1) -> nn.Sequential:
    """Conv (no bias), batch norm, leaky ReLU 0.1: the darknet block."""
    return nn.Sequential(nn.Conv2d(cin, cout, k, s, k // 2, bias=False), nn.BatchNorm2d(cout), nn.LeakyReLU(0.1, inplace=True))


class TinyYolo(nn.Module):
    """Input (B, 3, H, W) float in [0, 1], H and W multiples of 32; output (B, 5 + C, H/8, W/8) raw logits."""

    def __init__(self, config: DetectorConfig = DetectorConfig()) -> None:
        super().__init__()
        w = config.widths
        self.config = config
        self.stem = nn.Sequential(conv_bn_act(3, w[0], 3, 2), conv_bn_act(w[0], w[1], 3, 2))          # /4
        self.s8 = nn.Sequential(conv_bn_act(w[1], w[2], 3, 2), conv_bn_act(w[2], w[2]))                 # /8
        self.s16 = nn.Sequential(conv_bn_act(w[2], w[3], 3, 2), conv_bn_act(w[3], w[3]))                # /16
        self.s32 = nn.Sequential(conv_bn_act(w[3], w[4], 3, 2), conv_bn_act(w[4], w[4]))                # /32
        self.lat32 = conv_bn_act(w[4], w[2], 1)
        self.lat16 = conv_bn_act(w[3], w[2], 1)
        self.fuse = nn.Sequential(conv_bn_act(2 * w[2], w[2], 3), conv_bn_act(w[2], w[2], 3))
        self.head = nn.Conv2d(w[2], 5 + config.num_classes, 1)
        nn.init.constant_(self.head.bias[0], -4.6)  # start with objectness ~ 1 %

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        p8 = self.s8(self.stem(x))
        p16 = self.s16(p8)
        p32 = self.s32(p16)
        top = nn.functional.interpolate(self.lat32(p32), scale_factor=2.0, mode="nearest") + self.lat16(p16)
        top = nn.functional.interpolate(top, scale_factor=2.0, mode="nearest")
        return self.head(self.fuse(torch.cat([p8, top], 1)))


def decode(raw: torch.Tensor, stride: int) -> torch.Tensor:
    """Raw head output -> (B, H*W, 5 + C): x0, y0, x1, y1 (input pixels), objectness prob, class probs."""
    b, c, h, w = raw.shape
    r = raw.permute(0, 2, 3, 1).reshape(b, h * w, c)
    gy, gx = torch.meshgrid(torch.arange(h, device=raw.device), torch.arange(w, device=raw.device), indexing="ij")
    grid = torch.stack([gx, gy], -1).reshape(1, h * w, 2).to(raw.dtype)
    centre = (grid + 2.0 * torch.sigmoid(r[..., 1:3]) - 0.5) * stride
    size = stride * torch.exp(r[..., 3:5].clamp(-4.0, 4.5))
    return torch.cat([centre - size / 2, centre + size / 2, torch.sigmoid(r[..., :1]), torch.sigmoid(r[..., 5:])], -1)
