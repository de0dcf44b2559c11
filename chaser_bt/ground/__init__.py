"""Streaming to the ground (paper's fourth task): target estimate, radar tracks, video with boxes.

The wire format is in :mod:`chaser_bt.ground.protocol` and docs/ground.md; the UDP sender in
:mod:`chaser_bt.ground.sender`; the optional HMAC on every datagram in :mod:`chaser_bt.ground.auth`.
"""

from chaser_bt.ground.auth import StreamSigner, StreamVerifier, VerifierCounters
from chaser_bt.ground.protocol import (
    MAX_DATAGRAM,
    VERSION,
    Box,
    FrameAssembler,
    VideoChunk,
    chunk_frame,
    parse_chunk,
    parse_datagram,
)
from chaser_bt.ground.sender import GroundSender, SenderCounters

__all__ = [
    "MAX_DATAGRAM", "VERSION", "Box", "FrameAssembler", "GroundSender", "SenderCounters", "VideoChunk",
    "StreamSigner", "StreamVerifier", "VerifierCounters", "chunk_frame", "parse_chunk", "parse_datagram",
]
