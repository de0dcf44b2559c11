"""A Groot2 client written from BT.CPP 4.10's groot2_protocol.h (not from chaser_bt's protocol module)."""

from __future__ import annotations

import random
import socket
import struct

import zmq


def free_port_pair() -> int:
    """A port P with P and P + 1 both free on loopback (the publisher binds both)."""
    for _ in range(200):
        port = random.randint(20000, 60000)
        try:
            for p in (port, port + 1):
                with socket.socket() as s:
                    s.bind(("127.0.0.1", p))
        except OSError:
            continue
        return port
    raise RuntimeError("no two free consecutive ports")


class Client:
    """A REQ socket that sends ``[header, *extra]`` and returns the reply's parts."""

    def __init__(self, port: int, host: str = "127.0.0.1") -> None:
        self.context = zmq.Context()
        self.socket = self.context.socket(zmq.REQ)
        self.socket.setsockopt(zmq.RCVTIMEO, 5000)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.connect(f"tcp://{host}:{port}")
        self.next_id = 0x0A000000

    def ask_raw(self, parts: list[bytes]) -> list[bytes]:
        self.socket.send_multipart(parts)
        return self.socket.recv_multipart()

    def ask(self, letter: str, *extra: bytes) -> tuple[int, list[bytes]]:
        """Send request type ``letter``; returns (the unique id sent, the reply parts)."""
        self.next_id += 1
        header = struct.pack("<BBI", 2, ord(letter), self.next_id)  # protocol, type, unique_id
        return self.next_id, self.ask_raw([header, *extra])

    def close(self) -> None:
        self.socket.close(linger=0)
        self.context.term()


def statuses(payload: bytes) -> dict[int, int]:
    """STATUS payload -> {uid: status}: 3 bytes a node, uid u16 LE then status u8."""
    return {struct.unpack_from("<H", payload, i)[0]: payload[i + 2] for i in range(0, len(payload), 3)}
