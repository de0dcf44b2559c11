"""Groot2's wire format, checked against bytes written out by hand from BT.CPP 4.10's groot2_protocol.h."""

from __future__ import annotations

import uuid

import pytest

from chaser_bt.log.groot2.protocol import (
    REPLY_HEADER_SIZE,
    ProtocolError,
    ReplyHeader,
    RequestHeader,
    RequestType,
    Transition,
    decode_reply_header,
    decode_request_header,
    decode_statuses,
    decode_transitions,
    encode_reply_header,
    encode_request_header,
    encode_statuses,
    encode_transitions,
    error_reply,
    new_tree_id,
)


def test_request_header_is_protocol_type_then_little_endian_id():
    # SerializeHeader: protocol (u8 2), type (u8 'S'), unique_id memcpy'd (little-endian)
    data = encode_request_header(RequestHeader(RequestType.STATUS, 0x01020304))
    assert data == b"\x02S\x04\x03\x02\x01"
    assert decode_request_header(data) == RequestHeader(ord("S"), 0x01020304, 2)


def test_request_types_are_the_header_letters():
    letters = {"FULLTREE": "T", "STATUS": "S", "BLACKBOARD": "B", "HOOK_INSERT": "I", "HOOK_REMOVE": "R",
               "BREAKPOINT_REACHED": "N", "BREAKPOINT_UNLOCK": "U", "HOOKS_DUMP": "D", "REMOVE_ALL_HOOKS": "A",
               "DISABLE_ALL_HOOKS": "X", "TOGGLE_RECORDING": "r", "GET_TRANSITIONS": "t"}
    assert {t.name: chr(t.value) for t in RequestType if t.value} == letters


@pytest.mark.parametrize("size", [0, 5, 7, 22])
def test_a_request_header_is_exactly_six_bytes(size):
    with pytest.raises(ProtocolError):
        decode_request_header(b"\x02" * size)


def test_reply_header_appends_the_16_byte_tree_id():
    tree_id = bytes(range(16))
    data = encode_reply_header(ReplyHeader(RequestHeader(RequestType.FULLTREE, 7), tree_id))
    assert data == b"\x02T\x07\x00\x00\x00" + tree_id
    assert len(data) == REPLY_HEADER_SIZE == 22
    assert decode_reply_header(data) == ReplyHeader(RequestHeader(ord("T"), 7), tree_id)
    with pytest.raises(ValueError):
        encode_reply_header(ReplyHeader(RequestHeader(RequestType.FULLTREE, 7), b"short"))


def test_statuses_are_three_bytes_per_node():
    data = encode_statuses([(1, 1), (2, 12), (0x0102, 3)])
    assert data == b"\x01\x00\x01" + b"\x02\x00\x0c" + b"\x02\x01\x03"
    assert decode_statuses(data) == [(1, 1), (2, 12), (0x0102, 3)]
    with pytest.raises(ProtocolError):
        decode_statuses(b"\x01\x00")


def test_transitions_keep_six_bytes_of_the_timestamp():
    # memcpy(&buf, &timestamp_usec, 6): the low 48 bits, little-endian; then uid (u16), status (u8)
    data = encode_transitions([Transition(0x0A0B0C0D0E0F, 5, 2), Transition((1 << 48) + 3, 0x0100, 0)])
    assert data == bytes.fromhex("0f0e0d0c0b0a" "0500" "02" "030000000000" "0001" "00")
    assert decode_transitions(data) == [Transition(0x0A0B0C0D0E0F, 5, 2), Transition(3, 0x0100, 0)]
    with pytest.raises(ProtocolError):
        decode_transitions(data[:-1])


def test_error_reply_and_tree_id():
    assert error_reply("Request not recognized") == [b"error", b"Request not recognized"]
    tree_id = new_tree_id()
    assert len(tree_id) == 16 and tree_id != new_tree_id()
    assert uuid.UUID(bytes=tree_id).version == 4  # CreateRandomUUID sets the same version and variant bits
    assert tree_id[8] & 0xC0 == 0x80
