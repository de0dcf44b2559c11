"""The BLACKBOARD reply's MessagePack, against bytes written out by hand from the MessagePack spec."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import pytest

from chaser_bt.log.groot2.blackboard import blackboard_reply, json_value, msgpack


@pytest.mark.parametrize("value, expected", [
    (None, "c0"), (True, "c3"), (False, "c2"),
    (0, "00"), (127, "7f"), (128, "cc80"), (255, "ccff"), (256, "cd0100"), (65536, "ce00010000"),
    (2**32, "cf0000000100000000"), (-1, "ff"), (-32, "e0"), (-33, "d0df"), (-129, "d1ff7f"),
    (-2**31, "d280000000"), (-2**31 - 1, "d3ffffffff7fffffff"),
    (0.5, "ca3f000000"), (0.1, "cb3fb999999999999a"), (math.inf, "cb7ff0000000000000"),
    ("", "a0"), ("abc", "a3616263"), ("x" * 32, "d920" + "78" * 32), ("é", "a2c3a9"),
    ([], "90"), ([1, "a"], "9201a161"), (list(range(16)), "dc0010" + "".join(f"{i:02x}" for i in range(16))),
    ({}, "80"), ({"b": 1, "a": None}, "82a161c0a16201"),  # keys sorted, as nlohmann's std::map
])
def test_msgpack_is_the_smallest_form(value, expected):
    assert msgpack(value).hex() == expected


def test_msgpack_refuses_what_json_cannot_hold():
    with pytest.raises(TypeError):
        msgpack(object())
    with pytest.raises(OverflowError):
        msgpack(2**64)


class Mode(enum.Enum):
    GUIDED = 4


@dataclass
class Cue:
    east_m: float
    mode: Mode
    path: list


def test_json_values_follow_btcpps_exporter():
    assert json_value(Cue(1.5, Mode.GUIDED, [1, (2, 3)])) == {"__type": "Cue", "east_m": 1.5, "mode": "GUIDED",
                                                             "path": [1, [2, 3]]}
    assert json_value(object()) is None
    assert json_value({"a": 1}) is None  # a mapping has no BT.CPP export


def test_a_subtree_scope_brings_the_root_along():
    scopes = {"Main": {"alt": "/alt"}, "leg": {"n": "/leg/n", "unset": "/leg/unset"}, "empty": {}}
    storage = {"/alt": 20, "/leg/n": "two"}
    assert blackboard_reply(["leg"], scopes, storage, "Main") == msgpack(
        {"leg": {"n": "two", "unset": None}, "ROOT": {"alt": 20}})
    assert blackboard_reply(["Main", "empty", "zzz"], scopes, storage, "Main") == msgpack(
        {"Main": {"alt": 20}, "empty": None, "ROOT": {"alt": 20}})
    assert blackboard_reply(["zzz"], scopes, storage, "Main") == b"\xc0"
    with pytest.raises(ValueError, match="ROOT"):
        blackboard_reply(["ROOT"], {"Main": {}, "ROOT": {}}, storage, "Main")
