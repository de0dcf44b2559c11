"""Groot2's BLACKBOARD reply: the entries of the named subtree scopes, as BT.CPP's msgpack of JSON.

BT.CPP answers ``nlohmann::json::to_msgpack`` of ``{scope name: ExportBlackboardToJSON(bb)}`` for
the names it knows (the main tree by its ID, a SubTree instance by its path, which brings the root
blackboard along as ``ROOT``); a scope with no entries is JSON null, and so is the whole reply when
no name is known. A blackboard holds an entry
for every port wired to it, valued or not (null). Values BT.CPP's exporter knows are strings,
integers, floats and vectors of them; here also a dataclass (an object with ``__type``, as BT.CPP's
registered converters write) and an enum (its name); anything else is null.

:func:`msgpack` writes what nlohmann 3.11 writes: the smallest integer form, a float as float32
when that is exact, map keys sorted (``std::map``).
"""

from __future__ import annotations

import dataclasses
import enum
import math
import struct
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["ROOT", "blackboard_reply", "json_value", "msgpack"]

_FLOAT32_MAX = 3.4028234663852886e38


#: BT.CPP's name for the root blackboard, added to a reply that names a SubTree instance.
ROOT = "ROOT"


def blackboard_reply(
    names: Iterable[str], scopes: Mapping[str, Mapping[str, str]], storage: Mapping[str, Any], main: str
) -> bytes:
    """The BLACKBOARD payload for ``names``; ``scopes``: scope name -> {entry name: absolute key}.

    A SubTree instance's blackboard comes with the root one as ``ROOT`` (BT.CPP: a subtree's root
    blackboard is not its own, so it is exported beside it).

    Raises:
        ValueError: a SubTree instance named ``ROOT`` is asked for with the root (BT.CPP's refusal).
    """
    dump: dict[str, Any] = {}
    for name in names:
        entries = scopes.get(name)
        if entries is None:
            continue
        if name == ROOT and (name != main or ROOT in dump):
            raise ValueError("blackboard dump request uses reserved name [ROOT] together with an "
                             "external root blackboard export")
        dump[name] = _entries(entries, storage)
        if name != main:
            if name == ROOT:
                raise ValueError("blackboard dump request would overwrite subtree [ROOT] with an "
                                 "external root blackboard export")
            dump[ROOT] = _entries(scopes.get(main, {}), storage)
    return msgpack(dump or None)


def _entries(entries: Mapping[str, str], storage: Mapping[str, Any]) -> Any:
    return {entry: json_value(storage.get(key)) for entry, key in entries.items()} or None  # no entries: null


def json_value(value: Any, depth: int = 0) -> Any:
    """``value`` as JSON BT.CPP's exporter would write it (None where it has no JSON form)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if depth > 8:
        return None
    if isinstance(value, enum.Enum):
        return value.name
    if isinstance(value, (list, tuple)):
        return [json_value(item, depth + 1) for item in value]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: json_value(getattr(value, f.name), depth + 1) for f in dataclasses.fields(value)}
        return {"__type": type(value).__name__, **fields}
    return None


def msgpack(value: Any) -> bytes:
    """MessagePack of a JSON value (None, bool, int, float, str, list, dict with str keys)."""
    out = bytearray()
    _pack(value, out)
    return bytes(out)


def _pack(value: Any, out: bytearray) -> None:
    if value is None:
        out.append(0xC0)
    elif isinstance(value, bool):
        out.append(0xC3 if value else 0xC2)
    elif isinstance(value, int):
        _pack_int(value, out)
    elif isinstance(value, float):
        if math.isfinite(value) and abs(value) <= _FLOAT32_MAX and struct.unpack(">f", struct.pack(">f", value))[0] == value:
            out += b"\xca" + struct.pack(">f", value)
        else:
            out += b"\xcb" + struct.pack(">d", value)
    elif isinstance(value, str):
        data = value.encode("utf-8")
        _pack_length(len(data), out, fix=(0xA0, 31), sizes=(0xD9, 0xDA, 0xDB))
        out += data
    elif isinstance(value, list):
        _pack_length(len(value), out, fix=(0x90, 15), sizes=(None, 0xDC, 0xDD))
        for item in value:
            _pack(item, out)
    elif isinstance(value, dict):
        _pack_length(len(value), out, fix=(0x80, 15), sizes=(None, 0xDE, 0xDF))
        for key in sorted(value, key=lambda k: k.encode("utf-8")):
            _pack(key, out)
            _pack(value[key], out)
    else:
        raise TypeError(f"no MessagePack form for {type(value).__name__}")


def _pack_int(value: int, out: bytearray) -> None:
    if 0 <= value <= 0x7F:
        out.append(value)
    elif -32 <= value < 0:
        out.append(value & 0xFF)
    elif value > 0:
        for marker, fmt, top in ((0xCC, ">B", 0xFF), (0xCD, ">H", 0xFFFF), (0xCE, ">I", 0xFFFFFFFF),
                                 (0xCF, ">Q", 0xFFFFFFFFFFFFFFFF)):
            if value <= top:
                out.append(marker)
                out += struct.pack(fmt, value)
                return
        raise OverflowError(f"{value} does not fit MessagePack's 64 bits")
    else:
        for marker, fmt, bottom in ((0xD0, ">b", -0x80), (0xD1, ">h", -0x8000), (0xD2, ">i", -0x80000000),
                                    (0xD3, ">q", -0x8000000000000000)):
            if value >= bottom:
                out.append(marker)
                out += struct.pack(fmt, value)
                return
        raise OverflowError(f"{value} does not fit MessagePack's 64 bits")


def _pack_length(n: int, out: bytearray, fix: tuple[int, int], sizes: tuple[int | None, int, int]) -> None:
    base, fix_max = fix
    if n <= fix_max:
        out.append(base | n)
    elif sizes[0] is not None and n <= 0xFF:
        out += bytes((sizes[0], n))
    elif n <= 0xFFFF:
        out.append(sizes[1])
        out += struct.pack(">H", n)
    else:
        out.append(sizes[2])
        out += struct.pack(">I", n)
