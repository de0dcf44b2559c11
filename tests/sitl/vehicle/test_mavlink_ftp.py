"""MAVFTP parameter download, decoded by pymavlink's own MAVFTP code.

References: ArduPilot's GCS_FTP.cpp (opcodes, one session, replies with seq + 1 and req_opcode,
Nack payload = the error code) and AP_Filesystem_Param (``@PARAM/param.pck``); the file is
decoded with ``pymavlink.mavftp.MAVFTP.ftp_param_decode``, the decoder MAVProxy's parameter
download uses, and compared with what PARAM_REQUEST_LIST says. The 4.7.0-dev SITL in
``../shared/ardupilot`` served its 1354 parameters this way, and answered (request -> reply
opcode, size, data): ResetSessions -> Ack; OpenFileRO of a missing path -> Nack [10]; of
``@PARAM/param.pck`` -> Ack, 4 bytes (the size); a second open -> Nack [1]; ReadFile on another
session -> Nack [4] with that session; ReadFile offset 6 size 10 -> Ack, 10 bytes at offset 6;
past the end -> Nack [6] at offset 0; an opcode it does not know -> Nack [1]; each reply's seq
the request's + 1 and its req_opcode the request's opcode.
"""

from __future__ import annotations

import struct

from mavlink_gcs import mav, ready_gcs
from pymavlink.mavftp import MAVFTP
from pymavlink.mavftp_op import (
    OP_Ack,
    OP_BurstReadFile,
    OP_Nack,
    OP_OpenFileRO,
    OP_ReadFile,
    OP_ResetSessions,
    OP_TerminateSession,
)

HEADER = struct.Struct("<HBBBBBBI")
AP_TYPE = {mav.MAV_PARAM_TYPE_INT8: 1, mav.MAV_PARAM_TYPE_INT16: 2, mav.MAV_PARAM_TYPE_INT32: 3,
           mav.MAV_PARAM_TYPE_REAL32: 4}
FAIL, EOF_ERROR, NOT_FOUND, INVALID_SESSION = 1, 6, 10, 4


def _request(gcs, seq: int, opcode: int, *, session: int = 0, offset: int = 0, size: int = 0, data: bytes = b""):
    payload = HEADER.pack(seq, session, opcode, size or len(data), 0, 0, 0, offset) + data
    gcs.send(mav.MAVLink_file_transfer_protocol_message(0, 1, 1, list(payload.ljust(251, b"\0"))))
    replies = [m for m in gcs.run(0.05) if m.get_type() == "FILE_TRANSFER_PROTOCOL"]
    out = []
    for m in replies:
        raw = bytes(m.payload)
        seq_r, sess, op, n, req, burst, _, ofs = HEADER.unpack_from(raw)
        out.append((seq_r, sess, op, req, burst, ofs, raw[HEADER.size:HEADER.size + n]))
    return out


def _download(gcs, path: str) -> bytes:
    ((seq, _, op, req, _, _, data),) = _request(gcs, 1, OP_OpenFileRO, data=path.encode() + b"\0")
    assert (seq, op, req) == (2, OP_Ack, OP_OpenFileRO)
    (size,) = struct.unpack("<I", data)
    replies = _request(gcs, 3, OP_BurstReadFile, offset=0, size=239)
    content = b"".join(d for _, _, op, _, _, _, d in replies if op == OP_Ack)
    assert replies[-1][4] == 1  # burst_complete on the last
    assert len(content) == size
    assert _request(gcs, 9, OP_TerminateSession)[0][2] == OP_Ack
    return content


def _param_list(gcs) -> dict:
    gcs.send(mav.MAVLink_param_request_list_message(1, 1))
    gcs.run(0.5)
    return {m.param_id: m for m in gcs.of_type("PARAM_VALUE")}


def test_the_parameter_file_holds_every_parameter_as_param_value_gives_it():
    gcs = ready_gcs(params={"RTL_ALT": 2500, "WPNAV_SPEED": 750.5})
    decoded = MAVFTP.ftp_param_decode(_download(gcs, "@PARAM/param.pck"))
    assert decoded is not None
    listed = _param_list(gcs)
    assert [n.decode() for n, _, _ in decoded.params] == list(listed)  # same names, same order
    for name, value, ap_type in decoded.params:
        ref = listed[name.decode()]
        assert ap_type == AP_TYPE[ref.param_type]
        assert abs(value - ref.param_value) < 1e-3
    assert {n.decode(): v for n, v, _ in decoded.params}["RTL_ALT"] == 2500


def test_with_defaults_the_file_carries_each_changed_parameters_default():
    gcs = ready_gcs(params={"RTL_ALT": 2500})
    decoded = MAVFTP.ftp_param_decode(_download(gcs, "@PARAM/param.pck?withdefaults=1"))
    defaults = {n.decode(): v for n, v, _ in decoded.defaults}
    values = {n.decode(): v for n, v, _ in decoded.params}
    assert (values["RTL_ALT"], defaults["RTL_ALT"]) == (2500, 1500)
    assert defaults["ANGLE_MAX"] == values["ANGLE_MAX"] == 3000


def test_a_plain_read_returns_one_chunk_at_the_offset_and_eof_past_the_end():
    gcs = ready_gcs()
    ((_, _, _, _, _, _, data),) = _request(gcs, 1, OP_OpenFileRO, data=b"@PARAM/param.pck\0")
    (size,) = struct.unpack("<I", data)
    ((_, _, op, req, _, ofs, chunk),) = _request(gcs, 3, OP_ReadFile, offset=6, size=10)
    assert (op, req, ofs, len(chunk)) == (OP_Ack, OP_ReadFile, 6, 10)
    ((seq, _, op, req, _, ofs, err),) = _request(gcs, 5, OP_ReadFile, offset=size, size=10)
    assert (seq, op, req, ofs, err) == (6, OP_Nack, OP_ReadFile, 0, bytes([EOF_ERROR]))


def test_other_paths_and_wrong_sessions_are_refused_with_arducopters_errors():
    gcs = ready_gcs()
    ((_, _, op, _, _, _, err),) = _request(gcs, 1, OP_OpenFileRO, data=b"/APM/LOGS/1.BIN\0")
    assert (op, err) == (OP_Nack, bytes([NOT_FOUND]))
    ((_, session, op, _, _, _, err),) = _request(gcs, 3, OP_ReadFile, session=3, size=10)
    assert (session, op, err) == (3, OP_Nack, bytes([INVALID_SESSION]))
    _request(gcs, 5, OP_OpenFileRO, data=b"@PARAM/param.pck\0")
    ((_, _, op, _, _, _, err),) = _request(gcs, 7, OP_OpenFileRO, data=b"@PARAM/param.pck\0")
    assert (op, err) == (OP_Nack, bytes([FAIL]))  # one session at a time
    ((_, _, op, req, _, _, err),) = _request(gcs, 9, 74)
    assert (op, req, err) == (OP_Nack, 74, bytes([FAIL]))
    assert _request(gcs, 11, OP_ResetSessions)[0][2] == OP_Ack
