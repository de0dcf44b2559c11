"""Train / validation split of video frames by contiguous chunks.

Consecutive frames of a video are near copies: a random per-frame split puts a frame's twin in the
other set and the validation figure measures memory, not generalisation. As datasheets for video
data advise, frames are grouped in chunks of ``chunk`` consecutive frame indices (frame // chunk)
and whole chunks are drawn, seeded, for validation; a chunk never straddles the two sets.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["chunk_split"]


def chunk_split(frames: Sequence[int], chunk: int, val_frac: float, seed: int = 0) -> tuple[list[int], list[int]]:
    """Positions (into ``frames``) of the training and the validation items.

    Args:
        frames: each item's frame index (any order, gaps allowed).
        chunk: frames per chunk (> 0); chunk k holds frame indices k*chunk .. (k+1)*chunk - 1.
        val_frac: share of the chunks (not frames) held out, in [0, 1); at least one chunk when it is
            > 0 and there are two or more chunks, never every chunk.
        seed: which chunks are drawn.

    Returns:
        (train, val): ascending positions; together every position once.
    """
    if chunk < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    if not 0.0 <= val_frac < 1.0:
        raise ValueError(f"val_frac must be in [0, 1), got {val_frac}")
    ids = np.asarray(frames, dtype=np.int64) // chunk
    chunks = np.unique(ids)
    n_val = round(val_frac * len(chunks))
    if val_frac > 0 and len(chunks) >= 2:
        n_val = min(max(n_val, 1), len(chunks) - 1)
    else:
        n_val = 0
    held = set(np.random.default_rng(seed).permutation(chunks)[:n_val].tolist())
    train = [i for i, c in enumerate(ids.tolist()) if c not in held]
    val = [i for i, c in enumerate(ids.tolist()) if c in held]
    return train, val
