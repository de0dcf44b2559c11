"""The simulated ArduCopter's MAVFTP server: the parameter file ``@PARAM/param.pck``, read-only.

ArduPilot serves a virtual file system over FILE_TRANSFER_PROTOCOL (GCS_FTP.cpp); ground stations
(MAVProxy, Mission Planner, QGroundControl) fetch every parameter in one file from it rather than
one PARAM_VALUE at a time. This server keeps the part they use for that: OpenFileRO of
``@PARAM/param.pck`` (``?withdefaults=1`` adds the defaults), ReadFile, BurstReadFile,
TerminateSession and ResetSessions, one session at a time as ArduPilot. Anything else is refused
with a Nack carrying the error code the 4.7.0-dev SITL in ``../shared/ardupilot`` sent for it:
another path FileNotFound, a second open Fail, a wrong session InvalidSession, a read past the
end EOF (offset 0 in the Nack), any other operation Fail.

The file is AP_Filesystem_Param's packed format: a header (magic 0x671b, 0x671c with defaults;
the parameter count twice), then per parameter a type byte (AP_Param type 1 int8, 2 int16, 3 int32,
4 float; bit 4 set when a default follows), a byte with the length of the name shared with the
previous one (low 4 bits) and of the rest less one (high 4 bits), the rest of the name, the value
and, with defaults, the default when it differs. It is built when the file is opened, so one
download is one consistent snapshot.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

from sitl.vehicle.params import (
    MAV_PARAM_TYPE_INT8,
    MAV_PARAM_TYPE_INT16,
    MAV_PARAM_TYPE_INT32,
    MAV_PARAM_TYPE_REAL32,
    ParamStore,
)

__all__ = ["PARAM_FILE", "MavFtpServer", "encode_param_pck"]

PARAM_FILE = "@PARAM/param.pck"
MAX_DATA = 239  # FILE_TRANSFER_PROTOCOL payload (251) less its 12-byte header
_HEADER = struct.Struct("<HBBBBBBI")  # seq, session, opcode, size, req_opcode, burst_complete, pad, offset

# opcodes and errors (mavlink common.xml MAV_FTP_OPCODE / MAV_FTP_ERR)
OP_TERMINATE, OP_RESET, OP_OPEN_RO, OP_READ, OP_BURST_READ = 1, 2, 4, 5, 15
OP_ACK, OP_NACK = 128, 129
ERR_FAIL, ERR_INVALID_SESSION, ERR_EOF, ERR_NOT_FOUND = 1, 4, 6, 10

_AP_TYPES = {MAV_PARAM_TYPE_INT8: (1, "b"), MAV_PARAM_TYPE_INT16: (2, "h"), MAV_PARAM_TYPE_INT32: (3, "i"),
             MAV_PARAM_TYPE_REAL32: (4, "f")}
_MAGIC, _MAGIC_DEFAULTS = 0x671B, 0x671C


def encode_param_pck(params: ParamStore, *, with_defaults: bool = False) -> bytes:
    """``params`` as AP_Filesystem_Param's packed file (see module docstring)."""
    n = params.count()
    out = bytearray(struct.pack("<HHH", _MAGIC_DEFAULTS if with_defaults else _MAGIC, n, n))
    last = b""
    for name in params.names():
        spec = params.spec(name)
        ap_type, fmt = _AP_TYPES[spec.mav_type]
        raw = name.encode("ascii")
        common = 0
        while common < min(len(last), len(raw) - 1, 15) and last[common] == raw[common]:
            common += 1
        rest = raw[common:]
        value = params.get(name)
        default = float(spec.default)
        has_default = with_defaults and value != default
        out.append(ap_type | (0x10 if has_default else 0))
        out.append(common | (len(rest) - 1) << 4)
        out += rest
        out += _pack(fmt, value)
        if has_default:
            out += _pack(fmt, default)
        last = raw
    return bytes(out)


def _pack(fmt: str, value: float) -> bytes:
    return struct.pack("<" + fmt, value if fmt == "f" else int(value))


class MavFtpServer:
    """Answers FILE_TRANSFER_PROTOCOL payloads (see module docstring).

    Args:
        params: the parameters the file is made from.
    """

    def __init__(self, params: ParamStore) -> None:
        self._params = params
        self._session: int | None = None
        self._file = b""

    def handle(self, payload: bytes | list[int], send: Callable[[bytes], None]) -> None:
        """One request payload; ``send`` gets each reply payload (a burst read sends several)."""
        data = bytes(payload)
        if len(data) < _HEADER.size:
            return  # not an FTP request: ArduPilot drops it
        seq, session, opcode, size, _, _, _, offset = _HEADER.unpack_from(data)
        body = data[_HEADER.size:_HEADER.size + min(size, MAX_DATA)]
        seq_out = [seq]

        def reply(op: int, content: bytes = b"", *, at: int = 0, burst_complete: int = 0) -> None:
            seq_out[0] = (seq_out[0] + 1) & 0xFFFF
            head = _HEADER.pack(seq_out[0], session, op, len(content), opcode, burst_complete, 0, at)
            send((head + content).ljust(251, b"\0"))

        def nack(err: int, *, burst_complete: int = 0) -> None:
            reply(OP_NACK, bytes([err]), burst_complete=burst_complete)

        if opcode == OP_OPEN_RO:
            path = body.split(b"\0", 1)[0].decode("ascii", "replace")
            name, _, query = path.partition("?")
            if name != PARAM_FILE:
                nack(ERR_NOT_FOUND)
                return
            if self._session is not None:
                nack(ERR_FAIL)
                return
            self._session = session
            self._file = encode_param_pck(self._params, with_defaults="withdefaults=1" in query)
            reply(OP_ACK, struct.pack("<I", len(self._file)))
        elif opcode in (OP_READ, OP_BURST_READ):
            if session != self._session:
                nack(ERR_INVALID_SESSION)
                return
            if offset >= len(self._file):
                nack(ERR_EOF, burst_complete=1 if opcode == OP_BURST_READ else 0)
                return
            chunk = min(size, MAX_DATA) or MAX_DATA
            if opcode == OP_READ:
                reply(OP_ACK, self._file[offset:offset + chunk], at=offset)
                return
            at = offset
            while at < len(self._file):
                part = self._file[at:at + chunk]
                last = at + len(part) >= len(self._file)
                reply(OP_ACK, part, at=at, burst_complete=1 if last else 0)
                at += len(part)
        elif opcode == OP_TERMINATE:
            if session != self._session:
                nack(ERR_INVALID_SESSION)
                return
            self._session = None
            reply(OP_ACK)
        elif opcode == OP_RESET:
            self._session = None
            reply(OP_ACK)
        else:
            nack(ERR_FAIL)
