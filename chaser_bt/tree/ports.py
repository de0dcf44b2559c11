"""Port declarations on py_trees' typed ports, plus BT.CPP's blackboard-reference and literal rules.

A behaviour declares its ports once, the py_trees way (``INPUT_PORTS`` / ``OUTPUT_PORTS`` on a
:class:`py_trees.ports.BehaviourWithPorts`), and the loader checks every tree against those
declarations before anything flies. :class:`Port` adds one thing py_trees lacks: BT.CPP's
default remapping, the blackboard key a port uses when a tree leaves it unwired (e.g. the
vehicle state every flight behaviour reads from ``/vehicle/state``).

A port's value in a tree is either a literal or a blackboard reference written ``{key}``
exactly as in BehaviorTree.CPP (``{@key}`` is the root blackboard from inside a subtree,
``{=}`` a key named like the port). Literal strings go through py_trees'
``convert_str_to_type`` so the YAML and the BT.CPP-XML loaders convert text the same way.

A port may also bound its values (``minimum``, ``maximum``, ``above`` for a strict lower bound;
on a list port, bounds apply to each item) and fix a list's ``length``. The validator checks every
literal against them, so a tree that validates does not fail in the air on a negative duration or
a two-number waypoint; a default must satisfy its own port's bounds. A number must be finite
(``inf``, ``1e400`` and ``nan`` are refused) on every port, unless the port says ``infinite=True``
(then ``inf`` is allowed, ``nan`` still not).
"""

from __future__ import annotations

import enum
import json
import math
import re
import types
import typing
from dataclasses import dataclass
from typing import Any

import py_trees.ports
import yaml
from py_trees.ports_utils import convert_str_to_type, is_instance_of_type

from chaser_bt.tree.expressions import ExpressionError, parse_double_prefix, parse_int_prefix, to_text

__all__ = [
    "Port",
    "input_port",
    "output_port",
    "LiteralError",
    "coerce_literal",
    "finite_violation",
    "literal_from_text",
    "literal_text",
    "has_literal_form",
    "type_name",
    "parse_reference",
    "is_reference_text",
    "SAME_AS_PORT",
    "ANY_TYPE",
    "btcpp_type",
    "convert_from_string",
    "btcpp_cast",
    "BtcppInputs",
]

#: ``{=}``: BT.CPP v4's shorthand for "the key named like this port".
SAME_AS_PORT = "="

_SEGMENT = r"[A-Za-z_][A-Za-z0-9_]*"
_KEY = re.compile(rf"@?{_SEGMENT}(?:/{_SEGMENT})*")


@dataclass(frozen=True)
class Port(py_trees.ports.PortInformation):
    """py_trees' PortInformation plus BT.CPP's default remapping and bounds on the values.

    Args:
        default_key: the blackboard key the port uses when a tree does not wire it, e.g.
            ``"/vehicle/state"``; absolute keys start with ``/``, others are relative to the
            subtree's blackboard scope.
        minimum: the least value allowed (each item's, for a list port).
        maximum: the greatest value allowed.
        above: values must be strictly greater than this (an altitude: ``above=0``).
        length: a list port's exact number of items (a 3-vector: ``length=3``).
        infinite: ``inf`` (and ``-inf``) are values this port takes; by default a number must be finite.
        btcpp_type: the C++ type BT.CPP declares the port with, where the Python type does not say
            it (``"unsigned"`` for a ``msec``, ``"AnyTypeAllowed"`` for an untyped port); see
            :func:`btcpp_type`.
    """

    default_key: str | None = None
    minimum: float | None = None
    maximum: float | None = None
    above: float | None = None
    length: int | None = None
    infinite: bool = False
    btcpp_type: str | None = None

    @property
    def constraint(self) -> str:
        """The allowed values as a person reads them (``>= 0``, ``0..100``, ``3 items``), or ``""``."""
        bounds = []
        if self.minimum is not None and self.maximum is not None:
            bounds.append(f"{_number(self.minimum)}..{_number(self.maximum)}")
        else:
            if self.minimum is not None:
                bounds.append(f">= {_number(self.minimum)}")
            if self.maximum is not None:
                bounds.append(f"<= {_number(self.maximum)}")
        if self.above is not None:
            bounds.insert(0, f"> {_number(self.above)}")
        text = " and ".join(bounds)
        if self.length is not None:
            return f"{self.length} items" + (f", each {text}" if text else "")
        return text

    def violation(self, value: Any) -> str | None:
        """Why ``value`` (already of the port's type) breaks the port's bounds, or None when it keeps them."""
        if isinstance(value, list):
            if self.length is not None and len(value) != self.length:
                return f"needs {self.constraint}, got {len(value)}: {value!r}"
            items = value
        else:
            items = [value]
        if not self.infinite and any(isinstance(item, float) and math.isinf(item) for item in items):
            return finite_violation(value, allow_infinite=False)  # its own words: "too large for a float"
        for item in items:
            if not _is_number(item):
                continue
            if (
                (self.minimum is not None and not item >= self.minimum)
                or (self.maximum is not None and not item <= self.maximum)
                or (self.above is not None and not item > self.above)
            ):
                return f"must be {self.constraint}, got {_number(item) if item is value else repr(value)}"
        return finite_violation(value, allow_infinite=self.infinite)

    @property
    def satisfied_without_wiring(self) -> bool:
        """Whether a tree may leave this port out (it is optional, has a default or a default key)."""
        return not self.required or self.has_default or self.default_key is not None


def input_port(
    data_type: Any,
    description: str,
    *,
    default: Any = None,
    default_key: str | None = None,
    required: bool = True,
    minimum: float | None = None,
    maximum: float | None = None,
    above: float | None = None,
    length: int | None = None,
    infinite: bool = False,
    btcpp_type: str | None = None,
) -> Port:
    """Declare an input port; a default is coerced like a tree literal (``[0, 0, 0]`` for ``list[float]``).

    ``minimum``, ``maximum``, ``above`` and ``length`` bound the port's values, ``infinite`` lets it
    take ``inf`` (see :class:`Port`).

    Raises:
        ValueError: the default breaks the port's own bounds.
    """
    if default is not None:
        default = coerce_literal(default, data_type)
    port = Port(
        data_type=data_type,
        required=required,
        description=description,
        default_value=default,
        default_key=default_key,
        minimum=minimum,
        maximum=maximum,
        above=above,
        length=length,
        infinite=infinite,
        btcpp_type=btcpp_type,
    )
    problem = port.violation(default) if default is not None else None
    if problem is not None:
        raise ValueError(f"default of port {description!r}: {problem}")
    return port


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def finite_violation(value: Any, allow_infinite: bool = False) -> str | None:
    """Why ``value`` (a literal, or a list of them, at any depth) is not a finite number where it is one, or None.

    ``nan`` is never a value; ``inf`` (``1e400`` reads as inf) only where ``allow_infinite``.
    """
    if isinstance(value, (list, tuple)):
        for item in value:
            problem = finite_violation(item, allow_infinite)
            if problem is not None:
                return f"{problem} (in {value!r})"
        return None
    if isinstance(value, float) and not math.isfinite(value):
        if math.isnan(value):
            return "must be a number, got nan"
        if not allow_infinite:
            return f"must be a finite number, got {value} (a value too large for a float reads as inf)"
    return None


def _number(value: float) -> str:
    """``0`` rather than ``0.0``, ``-1e+308`` rather than its 309 digits: numbers read as a person writes them."""
    if isinstance(value, int):
        return str(value) if abs(value) < 10**20 else f"an integer of {len(str(abs(value)))} digits"
    if abs(value) >= 1e16:
        return f"{value:g}"
    return str(int(value)) if float(value).is_integer() else str(value)


def output_port(
    data_type: Any, description: str, *, default_key: str | None = None, btcpp_type: str | None = None
) -> Port:
    """Declare an output port; trees need not wire outputs (BT.CPP), unwired ones write a private key."""
    return Port(
        data_type=data_type, required=False, description=description, default_key=default_key, btcpp_type=btcpp_type
    )


def is_reference_text(value: Any) -> bool:
    """Whether ``value`` is a string that tries to be a ``{key}`` reference (has a brace)."""
    return isinstance(value, str) and ("{" in value or "}" in value)


def parse_reference(value: str) -> str:
    """Return the key inside a ``{key}`` reference.

    Raises:
        ValueError: the braces do not enclose exactly one well-formed key.
    """
    if not (value.startswith("{") and value.endswith("}")) or value.count("{") != 1 or value.count("}") != 1:
        raise ValueError(f"malformed blackboard reference {value!r}: write exactly '{{key}}'")
    key = value[1:-1].strip()
    if key == SAME_AS_PORT:
        return key
    if not _KEY.fullmatch(key):
        raise ValueError(
            f"malformed blackboard reference {value!r}: a key is letters, digits and '_', "
            "with '/' between namespaces and an optional leading '@' for the root blackboard"
        )
    return key


class LiteralError(ValueError):
    """A literal that does not fit a port's type."""


def type_name(data_type: Any) -> str:
    """A short readable name for a port type: ``float``, ``list[float]``, ``FlightMode``."""
    if data_type is object or data_type is Any:
        return "any"
    if typing.get_origin(data_type) is not None:
        return str(data_type).replace("typing.", "")
    return getattr(data_type, "__name__", str(data_type))


def has_literal_form(data_type: Any) -> bool:
    """Whether a tree can give this type as a literal (scalars, enums, lists and unions of them)."""
    origin = typing.get_origin(data_type)
    if origin in (typing.Union, types.UnionType):
        return all(has_literal_form(a) for a in typing.get_args(data_type) if a is not type(None))
    if origin is list:
        args = typing.get_args(data_type)
        return not args or has_literal_form(args[0])
    if data_type in (object, Any, str, int, float, bool, list):
        return True
    return _is_enum(data_type)


def coerce_literal(value: Any, data_type: Any) -> Any:
    """Turn a tree literal into a value of ``data_type``, or raise :class:`LiteralError`.

    Ints are accepted for floats (also inside ``list[float]``), bools are not numbers,
    strings go through py_trees' ``convert_str_to_type``.
    """
    if value is None:
        raise LiteralError("null is not a value: leave the port out to use its default")
    if data_type is object or data_type is Any:
        return value
    origin = typing.get_origin(data_type)
    if origin in (typing.Union, types.UnionType):
        for member in typing.get_args(data_type):
            if member is type(None):
                continue
            try:
                return coerce_literal(value, member)
            except LiteralError:
                continue
        raise LiteralError(_mismatch(value, data_type))
    if isinstance(value, str):
        return _from_string(value, data_type)
    if origin is list or data_type is list:
        return _coerce_list(value, data_type)
    if data_type is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                return float(value)
            except OverflowError:  # an int past the float range: inf, which the port's finiteness check refuses
                return math.inf if value > 0 else -math.inf
    elif data_type is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif data_type is bool:
        if isinstance(value, bool):
            return value
    elif _is_enum(data_type):
        if isinstance(value, data_type):
            return value
        for member in data_type:
            if member.value == value and type(member.value) is type(value):
                return member
    elif isinstance(data_type, type) and isinstance(value, data_type):
        return value
    raise LiteralError(_mismatch(value, data_type))


def _coerce_list(value: Any, data_type: Any) -> list[Any]:
    if not isinstance(value, list):
        raise LiteralError(_mismatch(value, data_type))
    args = typing.get_args(data_type)
    inner = args[0] if args else object
    items = []
    for index, item in enumerate(value):
        try:
            items.append(coerce_literal(item, inner))
        except LiteralError as e:
            raise LiteralError(f"item {index}: {e}") from None
    return items


#: The texts BT.CPP's ``convertFromString`` reads whole, for a literal: an int, a double (what
#: ``std::from_chars`` takes: no ``+``, no blanks), a bool. BT.CPP also reads a number at the start
#: of longer text (``2.5`` or ``2abc`` as the int 2); a tree here must say exactly what it means.
_LITERAL_FORMS = {
    int: re.compile(r"-?\d+"),
    float: re.compile(r"-?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)", re.IGNORECASE),
    bool: re.compile(r"[01]|true|false|True|False|TRUE|FALSE"),
}


def _from_string(value: str, data_type: Any) -> Any:
    if data_type is str:
        return value
    form = _LITERAL_FORMS.get(data_type)
    if form is not None:
        if not form.fullmatch(value):
            raise LiteralError(_mismatch(value, data_type))
        if data_type is bool:
            return value in ("1", "true", "True", "TRUE")
        return data_type(value)  # 1e400 is inf, which the port's finiteness check refuses in its own words
    try:
        ok, converted = convert_str_to_type(value, data_type)
    except (ValueError, TypeError, ImportError, AttributeError):
        ok, converted = False, value
    if ok:
        try:
            if is_instance_of_type(converted, data_type):
                return converted
        except NotImplementedError:  # py_trees cannot check this generic type: report a mismatch
            pass
    raise LiteralError(_mismatch(value, data_type))


def _mismatch(value: Any, data_type: Any) -> str:
    message = f"expected {type_name(data_type)}, got {type(value).__name__} {value!r}"
    if _is_enum(data_type):
        message += f" (one of {', '.join(m.name for m in data_type)})"
    elif not has_literal_form(data_type):
        message += f" ({type_name(data_type)} has no literal form: wire it with a {{key}} reference)"
    return message


def _is_enum(data_type: Any) -> bool:
    return typing.get_origin(data_type) is None and isinstance(data_type, type) and issubclass(data_type, enum.Enum)


def _is_any(data_type: Any) -> bool:
    return data_type is object or data_type is Any


def literal_from_text(text: str, data_type: Any) -> Any:
    """Type attribute text (BT.CPP XML) by its port, or raise :class:`LiteralError`.

    Typed ports convert as any string literal does (``convert_str_to_type``); a port that takes
    any type reads the text as a YAML flow value (``3`` -> 3, ``[1, 2]`` -> [1, 2], ``'3'`` -> "3"),
    so a value means the same whether a tree was written in YAML or in XML.
    """
    if _is_any(data_type):
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError:
            return text
        return text if value is None or isinstance(value, dict) else value
    return coerce_literal(text, data_type)


def literal_text(value: Any, data_type: Any) -> str:
    """The attribute text for a literal, such that :func:`literal_from_text` gives the same value back.

    Raises:
        LiteralError: the value does not fit the port, or has no text form (a list item with
            ``;`` or ``,`` in it, a mapping).
    """
    if _is_any(data_type):
        if isinstance(value, enum.Enum):
            value = value.name
        text = yaml.safe_dump(value, default_flow_style=True, allow_unicode=True, width=math.inf)
        text = text.removesuffix("\n").removesuffix("\n...").strip()
        if isinstance(value, str) and ("\n" in text or literal_from_text(text, data_type) != value):
            text = json.dumps(value, ensure_ascii=False)  # a YAML double-quoted scalar keeps what plain text loses ("\xa0")
        if "\n" in text:
            raise LiteralError(f"{value!r} has no one-line text form")
        return text
    if isinstance(value, str) and not (typing.get_origin(data_type) is list or data_type is list):
        return value
    return _text(coerce_literal(value, data_type))


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, enum.Enum):
        return value.name
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, list):
        items = [_text(item) for item in value]
        if any(";" in item or "," in item or item != item.strip() or not item for item in items):
            raise LiteralError(f"list {value!r} has an item that a ';'-separated text cannot hold")
        return ";".join(items)
    return str(value)


# ------------------------------------------------------------------ BT.CPP's typed entries and conversions

#: ``btcpp_type`` of a port BT.CPP declares without a type (``BidirectionalPort("queue")``).
ANY_TYPE = "AnyTypeAllowed"

_CPP_SCALARS = {int: "int", float: "double", bool: "bool", str: "std::string"}
_INT_RANGES = {"int": (-(2**31), 2**31), "unsigned": (0, 2**32), "int64_t": (-(2**63), 2**63), "uint64_t": (0, 2**64)}


def btcpp_type(port: py_trees.ports.PortInformation) -> str | None:
    """The C++ type BT.CPP would give the port's blackboard entry, or None where it takes any type.

    ``int`` -> ``int``, ``float`` -> ``double``, ``bool``, ``str`` -> ``std::string``, a list ->
    ``std::vector<...>``, an enum by its name; a :class:`Port` may say otherwise (``btcpp_type``).
    Two ports that give one entry different types are what BT.CPP refuses when a tree loads.
    """
    explicit = getattr(port, "btcpp_type", None)
    if explicit is not None:
        return None if explicit == ANY_TYPE else explicit
    return _cpp_name(port.data_type)


def _cpp_name(data_type: Any) -> str | None:
    if _is_any(data_type):
        return None
    if data_type in _CPP_SCALARS:
        return _CPP_SCALARS[data_type]
    if typing.get_origin(data_type) is list:
        args = typing.get_args(data_type)
        return f"std::vector<{_cpp_name(args[0]) if args else 'Any'}>"
    return type_name(data_type)


def convert_from_string(text: str, data_type: Any, cpp: str | None = None) -> Any:
    """BT.CPP's ``convertFromString<T>`` for the port type: how BT.CPP reads text into a typed port.

    An integer is the digits at the start (``'2.5'`` is 2, ``'2abc'`` 2; ``'+2'`` and ``' 2'`` fail),
    a double likewise (``std::from_chars``), a bool is one of ``0 1 true false True False TRUE
    FALSE``, a list splits on ``;``. ``cpp`` is the port's :func:`btcpp_type` (``unsigned``...).

    Raises:
        ExpressionError: the text does not convert (BT.CPP throws).
    """
    if data_type is str or _is_any(data_type):
        return text
    if typing.get_origin(data_type) is list or data_type is list:
        args = typing.get_args(data_type)
        inner = args[0] if args else str
        parts = text.split(";")
        if parts and parts[-1] == "":
            parts.pop()  # BT.CPP's splitString: "" has no items, "a;" one
        return [convert_from_string(part, inner) for part in parts]
    if data_type is bool:
        if text in ("1", "true", "True", "TRUE"):
            return True
        if text in ("0", "false", "False", "FALSE"):
            return False
        raise ExpressionError(f"{text!r} is no bool (BT.CPP reads 0, 1, true, false, True, False, TRUE, FALSE)")
    if data_type is int:
        value = parse_int_prefix(text)
        low, high = _INT_RANGES.get(cpp or "int", _INT_RANGES["int"])
        if not low <= value < high:
            raise ExpressionError(f"{text!r} is out of the range of {cpp or 'int'}")
        return value
    if data_type is float:
        return parse_double_prefix(text)
    if _is_enum(data_type):
        member = data_type.__members__.get(text)
        if member is None:
            raise ExpressionError(f"{text!r} is no {data_type.__name__} (one of {', '.join(data_type.__members__)})")
        return member
    raise ExpressionError(f"BT.CPP has no conversion from text to {type_name(data_type)}")


def btcpp_cast(value: Any, data_type: Any, cpp: str | None = None) -> Any:
    """What BT.CPP's ``getInput<T>`` makes of a blackboard value: text through :func:`convert_from_string`,
    a number through ``Any::cast<T>`` (a whole double is an int, 0 and 1 are bools, a double is true
    when non-zero, a number as text is ``std::to_string``'s).

    Raises:
        ExpressionError: BT.CPP refuses the conversion (a fraction to an int, 2 to a bool...).
    """
    try:
        matches = is_instance_of_type(value, data_type)
    except NotImplementedError:
        matches = False
    if matches and not (data_type in (int, float) and isinstance(value, bool)):
        return value
    if isinstance(value, str):
        return convert_from_string(value, data_type, cpp)
    number = isinstance(value, (int, float)) and not isinstance(value, enum.Enum)
    if number and data_type is str:
        return to_text(value)
    if number and data_type is float:
        return float(value)
    if number and data_type is int:
        if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
            raise ExpressionError(f"{value!r} is not a whole number (BT.CPP: invalid floating point to integer conversion)")
        integer = int(value)
        low, high = _INT_RANGES.get(cpp or "int", _INT_RANGES["int"])
        if not low <= integer < high:
            raise ExpressionError(f"{value!r} is out of the range of {cpp or 'int'}")
        return integer
    if number and data_type is bool:
        if isinstance(value, float):
            return value != 0.0
        if value not in (0, 1):
            raise ExpressionError(f"{value!r} is no bool (an integer must be 0 or 1)")
        return bool(value)
    raise ExpressionError(f"BT.CPP cannot convert {value!r} to {type_name(data_type)}")


class BtcppInputs:
    """A mixin for a ports behaviour: ``get_input`` converts a blackboard value as BT.CPP's ``getInput<T>`` does.

    py_trees refuses a value of another type than the port's; BT.CPP converts: a Script's ``3.0``
    read by an ``int`` port is 3, ``'2'`` is 2, ``'4;5'`` read by a list port is ``[4, 5]``. What
    BT.CPP refuses (``2.5`` for an int) still raises TypeError.
    """

    def get_input(self, port_name: str, default: Any = None) -> Any:
        try:
            return super().get_input(port_name, default)  # type: ignore[misc]
        except TypeError:
            port = self.input_ports()[port_name]  # type: ignore[attr-defined]
            value = self.blackboard_client.get(port_name)  # type: ignore[attr-defined]
            try:
                return btcpp_cast(value, port.data_type, btcpp_type(port))
            except ExpressionError as e:
                raise TypeError(f"{self.name}: input port '{port_name}': {e}") from None  # type: ignore[attr-defined]
