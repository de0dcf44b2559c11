"""The live ground view: a Foxglove WebSocket server streaming the flight log's channels as they happen.

:class:`LiveSink` is a recorder sink (beside or instead of the MCAP file) backed by the Foxglove
SDK's WebSocket server (subprotocol ``foxglove.sdk.v1``, the successor of ``foxglove.websocket.v1``
with the same operations; Foxglove connects to either): it advertises every channel of
:data:`chaser_bt.log.schemas.CHANNELS` when it starts, so an operator's Foxglove (``Open
connection`` -> ``ws://HOST:PORT``) sees the tracks, the tree, the belief map and the video with
boxes, with the same schemas as a recorded file. Messages to a channel nobody subscribes to are
dropped by the server at no cost to the mission.
"""

from __future__ import annotations

import logging
import time

import foxglove

from chaser_bt.log import schemas as S

__all__ = ["LiveSink", "LiveViewError", "DEFAULT_PORT"]

log = logging.getLogger(__name__)

DEFAULT_PORT = 8765  # Foxglove's default


class LiveViewError(RuntimeError):
    """The live view cannot start (the port is taken, the address is not ours)."""


class LiveSink:
    """Serve the flight's channels on ``ws://host:port`` (port 0: any free port, see :attr:`port`).

    ``linger_s``: how long :meth:`close` keeps serving before it stops the server. The SDK sends from
    its own tasks and has no flush, so stopping at once can drop the flight's last messages (the
    tree's final state, written as the recorder closes) before they reach a subscriber.
    """

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1", name: str = "chaser-bt",
                 linger_s: float = 0.5) -> None:
        self.linger_s = linger_s
        self._context = foxglove.Context()
        self._channels = {
            topic: foxglove.Channel(
                topic, message_encoding=spec.message_encoding, context=self._context,
                schema=foxglove.Schema(name=spec.schema_name, encoding=spec.schema_encoding, data=spec.schema_data),
            )
            for topic, spec in S.CHANNELS.items()
        }
        try:
            self._server = foxglove.start_server(name=name, host=host, port=port, context=self._context)
        except RuntimeError as exc:  # FoxgloveError: failed to bind
            raise LiveViewError(f"live view on {host}:{port}: {exc}") from None
        self.closed = False
        log.info("live view on ws://%s:%d", host, self.port)

    @property
    def port(self) -> int:
        return int(self._server.port)

    def write(self, spec: S.ChannelSpec, t_ns: int, data: bytes) -> None:
        if not self.closed:
            self._channels[spec.topic].log(data, log_time=t_ns)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        time.sleep(self.linger_s)
        self._server.stop()
