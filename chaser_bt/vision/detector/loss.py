"""Detection loss: focal objectness over all cells, GIoU box and BCE class loss on the assigned cells.

Assignment follows YOLOv5 at one scale: a ground-truth box is predicted by the stride-8 cell holding
its centre and the two neighbouring cells nearest that centre (the decode reaches them). Sums are
normalised by the number of assigned cells (FCOS). ``obj_iou`` is YOLOv5's ``gr``: an assigned cell's
objectness target is ``1 - obj_iou + obj_iou * IoU`` of its predicted box, so a badly placed box
learns to score lower than a well placed one (the focal term takes soft targets as in quality focal
loss, Li et al. 2020).
"""

from __future__ import annotations

import torch
from torch import nn

from chaser_bt.vision.detector.model import decode

__all__ = ["detection_loss", "box_iou", "giou"]


def box_iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Elementwise IoU of (N, 4) x0, y0, x1, y1 boxes."""
    lt = torch.maximum(a[:, :2], b[:, :2])
    rb = torch.minimum(a[:, 2:], b[:, 2:])
    inter = (rb - lt).clamp(min=0).prod(1)
    area = (a[:, 2:] - a[:, :2]).clamp(min=0).prod(1) + (b[:, 2:] - b[:, :2]).clamp(min=0).prod(1)
    return inter / (area - inter + 1e-9)


def giou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Elementwise generalised IoU (Rezatofighi et al. 2019) of (N, 4) boxes."""
    lt = torch.maximum(a[:, :2], b[:, :2])
    rb = torch.minimum(a[:, 2:], b[:, 2:])
    inter = (rb - lt).clamp(min=0).prod(1)
    union = (a[:, 2:] - a[:, :2]).clamp(min=0).prod(1) + (b[:, 2:] - b[:, :2]).clamp(min=0).prod(1) - inter
    hull = (torch.maximum(a[:, 2:], b[:, 2:]) - torch.minimum(a[:, :2], b[:, :2])).clamp(min=0).prod(1)
    return inter / (union + 1e-9) - (hull - union) / (hull + 1e-9)


def _assign(targets: list[torch.Tensor], h: int, w: int, stride: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(batch index, cell index, target row (class, x0, y0, x1, y1)) for every assigned cell."""
    bi, ci, rows = [], [], []
    for b, t in enumerate(targets):
        for row in t:
            cx, cy = float(row[1] + row[3]) / 2 / stride, float(row[2] + row[4]) / 2 / stride
            gx, gy = min(int(cx), w - 1), min(int(cy), h - 1)
            fx, fy = cx - gx, cy - gy
            cells = {(gx, gy), (gx - 1 if fx < 0.5 else gx + 1, gy), (gx, gy - 1 if fy < 0.5 else gy + 1)}
            for x, y in cells:
                if 0 <= x < w and 0 <= y < h:
                    bi.append(b)
                    ci.append(y * w + x)
                    rows.append(row)
    if not rows:
        return torch.zeros(0, dtype=torch.long), torch.zeros(0, dtype=torch.long), torch.zeros(0, 5)
    return torch.tensor(bi), torch.tensor(ci), torch.stack(rows)


def detection_loss(raw: torch.Tensor, targets: list[torch.Tensor], stride: int, obj_iou: float = 0.0) -> tuple[torch.Tensor, dict[str, float]]:
    """Total loss and its parts for raw head output (B, 5 + C, H, W) and per-image (N, 5) targets."""
    b, c, h, w = raw.shape
    flat = raw.permute(0, 2, 3, 1).reshape(b, h * w, c)
    bi, ci, rows = _assign(targets, h, w, stride)
    npos = max(len(bi), 1)
    obj_t = torch.zeros(b, h * w)
    positive = torch.zeros(b, h * w)
    if len(bi):
        boxes = decode(raw, stride)[bi, ci, :4]
        obj_t[bi, ci] = 1.0 - obj_iou + obj_iou * box_iou(boxes.detach(), rows[:, 1:5]).clamp(0.0, 1.0)
        positive[bi, ci] = 1.0
    p = torch.sigmoid(flat[..., 0])
    bce = nn.functional.binary_cross_entropy_with_logits(flat[..., 0], obj_t, reduction="none")
    alpha = 0.25 * positive + 0.75 * (1 - positive)
    obj_loss = (alpha * (obj_t - p).abs() ** 2 * bce).sum() / npos
    if len(bi):
        box_loss = (1.0 - giou(boxes, rows[:, 1:5])).mean()
        cls_t = nn.functional.one_hot(rows[:, 0].long(), c - 5).float()
        cls_loss = nn.functional.binary_cross_entropy_with_logits(flat[bi, ci, 5:], cls_t)
    else:
        box_loss = cls_loss = raw.sum() * 0.0
    total = obj_loss + 2.0 * box_loss + 0.5 * cls_loss
    return total, {"obj": float(obj_loss.detach()), "box": float(box_loss.detach()), "cls": float(cls_loss.detach())}
