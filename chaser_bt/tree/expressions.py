"""BehaviorTree.CPP 4.10's scripting language: ``Script`` nodes, ``ScriptCondition``, pre- and post-conditions.

A script is statements separated by ``;``; its value is the last one's. Written exactly as in
BT.CPP (``script_parser.cpp``, ``scripting/operators.hpp``), with BT.CPP's binding powers, loosest
first: assignment (``:=`` creates an entry, ``=`` needs an existing one, ``+= -= *= /=``), the
ternary ``c ? a : b``, ``||``, ``&&``, comparisons (chainable: ``a < b < c``), ``| ^``, ``&``,
``+ - ..`` (``..`` concatenates), ``* /``, then the prefixes ``- ! ~``. Operands: integers
(``12``, ``0x1F``), reals, ``'text'`` or ``"text"``, ``true``/``false``, blackboard entries
(``name``; ``@name`` is the root blackboard) and scripting enums (names the registry maps to
integers).

Values follow BT.CPP's ``Any``: an integer literal is an int, arithmetic, logic and comparisons
give floats (``true`` is 1.0), ``/`` divides as doubles, ``&&``/``||`` evaluate both sides, ``==``
between numbers allows a float epsilon. Text meets a number by BT.CPP's ``StringToDouble``
(``'true'`` is 1, ``'false'`` 0, a scripting enum's name its value, else the number at the start:
``'3abc' == 3``); ``..`` writes a float as ``std::to_string`` does (``0.500000``). An assignment
keeps the entry's type as ``Any::copyInto`` does: an int entry stays an int (``x -= 0.5`` on one
raises), text into a number entry is converted. A blackboard enum (a behaviour's Python enum)
compares equal to its member name (``mode == 'RTL'``). Evaluating an entry that has no value, or
mixing types BT.CPP refuses, raises :class:`ExpressionError` (BT.CPP throws).

Parsing happens at validation (a malformed script is a tree problem with its position);
evaluation at tick time against an :class:`Environment` the caller provides, so this module knows
nothing of py_trees.
"""

from __future__ import annotations

import enum
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

__all__ = [
    "Environment",
    "Expression",
    "ExpressionError",
    "parse_expression",
    "truth",
    "number_text",
    "double_text",
    "to_text",
    "parse_double_prefix",
    "parse_int_prefix",
    "copy_into",
]


class ExpressionError(ValueError):
    """A malformed script (at parse time) or one that cannot be evaluated (at tick time)."""


class Environment(Protocol):
    """Where a script's names live: ``get`` raises KeyError for an entry with no value.

    ``has`` is true for an entry that exists, even without a value (BT.CPP creates the entry of
    every port wired to ``{key}`` when the tree loads). An environment may also offer
    ``converter(name)``: how the entry's declaring port reads text (BT.CPP's ``convertFromString``
    of the port's type), or None for an entry no typed port declares.
    """

    def get(self, name: str) -> Any: ...

    def has(self, name: str) -> bool: ...

    def set(self, name: str, value: Any) -> None: ...


_TOKEN = re.compile(
    r"\s*(?:"
    r"(?P<number>0[xX][0-9a-fA-F]+|\d+\.\d*(?:[eE][+-]?\d+)?|\d+(?:[eE][+-]?\d+)?)"
    r"|(?P<string>'[^']*'|\"[^\"]*\")"
    r"|(?P<name>@?[A-Za-z_][A-Za-z0-9_]*)"
    r"|(?P<op>:=|\+=|-=|\*=|/=|&&|\|\||==|!=|<=|>=|\.\.|[-+*/<>!~&|^?:()=;])"
    r")"
)

_ASSIGNMENTS = (":=", "=", "+=", "-=", "*=", "/=")
_COMPARISONS = ("==", "!=", "<", "<=", ">", ">=")
#: BT.CPP's left binding powers (``script_parser.cpp``); higher binds tighter.
_BINDING: dict[str, int] = {
    **dict.fromkeys(_ASSIGNMENTS, 2),
    "?": 4,
    "||": 6,
    "&&": 8,
    **dict.fromkeys(_COMPARISONS, 10),
    "|": 12,
    "^": 12,
    "&": 14,
    "+": 16,
    "-": 16,
    "..": 16,
    "*": 18,
    "/": 18,
}
_PREFIX_BINDING = 20
_EPSILON = 1.1920928955078125e-07  # numeric_limits<float>::epsilon(), BT.CPP's tolerance for ==


@dataclass(frozen=True)
class _Node:
    kind: str  # const | var | neg | not | ~ | binary op | cmp | ?: | assign | seq
    value: Any = None
    children: tuple[_Node, ...] = ()


@dataclass(frozen=True)
class Expression:
    """A parsed script. ``variables``: the names it reads or writes, in order of appearance; ``assigned``: those it writes."""

    text: str
    root: _Node
    variables: tuple[str, ...]
    assigned: tuple[str, ...] = ()
    #: The scripting enums it was parsed with: text compared with a number may name one (``'RED' == 1``).
    enums: Mapping[str, int] = field(default_factory=dict, compare=False, repr=False)

    def run(self, env: Environment) -> Any:
        """Execute the script against ``env`` and return the last statement's value."""
        return _Evaluator(env, self.enums).evaluate(self.root)

    def evaluate(self, lookup: Callable[[str], Any]) -> bool:
        """The script's truth, with read-only variables from ``lookup(name)`` (KeyError: no value)."""
        return truth(self.run(_ReadOnly(lookup)))

    def evaluate_with(self, values: Mapping[str, Any]) -> bool:
        """:meth:`evaluate` with the variables' values given as a mapping."""
        return self.evaluate(values.__getitem__)


class _ReadOnly:
    def __init__(self, lookup: Callable[[str], Any]) -> None:
        self.lookup = lookup

    def get(self, name: str) -> Any:
        return self.lookup(name)

    def has(self, name: str) -> bool:
        try:
            self.lookup(name)
        except KeyError:
            return False
        return True

    def set(self, name: str, value: Any) -> None:
        raise ExpressionError(f"cannot assign '{name}' here: this expression only reads the blackboard")


def parse_expression(text: str, enums: Mapping[str, int] | None = None) -> Expression:
    """Parse a BT.CPP script; names in ``enums`` are the scripting enums' integer constants.

    Raises:
        ExpressionError: naming the offending token and its 1-based column.
    """
    tokens = _tokenize(text)
    parser = _Parser(text, tokens, dict(enums or {}))
    root = parser.statements()
    return Expression(
        text, root, tuple(dict.fromkeys(parser.variables)), tuple(dict.fromkeys(parser.assigned)), dict(enums or {})
    )


def _tokenize(text: str) -> list[tuple[str, Any, int]]:
    tokens: list[tuple[str, Any, int]] = []
    position = 0
    stripped_end = len(text.rstrip())
    while position < stripped_end:
        match = _TOKEN.match(text, position)
        if match is None or match.end() == position:
            column = len(text) - len(text[position:].lstrip()) + 1
            raise ExpressionError(f"cannot read {text[column - 1:column + 9]!r} at column {column} in {text!r}")
        kind = match.lastgroup
        assert kind is not None
        value: Any = match.group(kind)
        column = match.start(kind) + 1
        if kind == "number":
            if len(value) > 400:  # longer than any float (int() refuses past 4300 digits anyway)
                raise ExpressionError(f"number at column {column} has {len(value)} digits: too large")
            if value[:2] in ("0x", "0X"):
                value = int(value, 16)
            elif re.fullmatch(r"\d+", value):
                value = int(value)
            else:
                value = float(value)
                if not math.isfinite(value):  # 1e400: a literal in a tree is a finite number (chaser_bt.tree.ports)
                    raise ExpressionError(f"number {match.group(kind)!r} at column {column} is too large for a float "
                                          f"in {text!r}")
        elif kind == "string":
            value = value[1:-1]
        elif kind == "name" and value in ("true", "false"):
            kind, value = "const", 1.0 if value == "true" else 0.0
        tokens.append((kind, value, column))
        position = match.end()
    if not any(t[1] != ";" for t in tokens):
        raise ExpressionError("empty expression")
    return tokens


class _Parser:
    """Pratt parsing with BT.CPP's binding powers."""

    def __init__(self, text: str, tokens: list[tuple[str, Any, int]], enums: dict[str, int]) -> None:
        self.text = text
        self.tokens = tokens
        self.enums = enums
        self.index = 0
        self.variables: list[str] = []
        self.assigned: list[str] = []

    def peek(self) -> tuple[str, Any, int] | None:
        return self.tokens[self.index] if self.index < len(self.tokens) else None

    def peek_op(self) -> str | None:
        token = self.peek()
        return token[1] if token is not None and token[0] == "op" else None

    def statements(self) -> _Node:
        statements = []
        while self.peek() is not None:
            if self.peek_op() == ";":
                self.index += 1
                continue
            statements.append(self.expression(0))
            token = self.peek()
            if token is not None and token[1] != ";":
                raise ExpressionError(f"unexpected {token[1]!r} at column {token[2]} in {self.text!r}")
        return statements[0] if len(statements) == 1 else _Node("seq", children=tuple(statements))

    def expression(self, min_binding: int) -> _Node:
        left = self.prefix()
        while True:
            op = self.peek_op()
            binding = _BINDING.get(op, -1) if op is not None else -1
            if binding < 0 or binding < min_binding:
                return left
            column = self.tokens[self.index][2]
            self.index += 1
            if op in _ASSIGNMENTS:
                if left.kind != "var":
                    raise ExpressionError(f"{op!r} at column {column} needs a blackboard entry on its left in {self.text!r}")
                self.assigned.append(left.value)
                return _Node("assign", op, (left, self.expression(0)))
            if op == "?":
                then = self.expression(0)
                if self.peek_op() != ":":
                    raise ExpressionError(f"expected ':' in the ternary at column {column} in {self.text!r}")
                self.index += 1
                return _Node("?:", children=(left, then, self.expression(4)))
            if op in _COMPARISONS:
                ops, operands = [op], [left, self.expression(binding + 1)]
                while self.peek_op() in _COMPARISONS:
                    ops.append(self.peek_op())
                    self.index += 1
                    operands.append(self.expression(binding + 1))
                left = _Node("cmp", tuple(ops), tuple(operands))
                continue
            left = _Node(op, children=(left, self.expression(binding + 1)))

    def prefix(self) -> _Node:
        token = self.peek()
        if token is None:
            raise ExpressionError(f"{self.text!r} ends where a value was expected")
        kind, value, column = token
        self.index += 1
        if kind == "op" and value in ("-", "!", "~"):
            return _Node({"-": "neg", "!": "not", "~": "~"}[value], children=(self.expression(_PREFIX_BINDING),))
        if kind == "op" and value == "(":
            inner = self.expression(0)
            if self.peek_op() != ")":
                raise ExpressionError(f"'(' at column {column} is never closed in {self.text!r}")
            self.index += 1
            return inner
        if kind in ("number", "string", "const"):
            return _Node("const", value)
        if kind == "name":
            if value in self.enums:
                return _Node("const", float(self.enums[value]))
            self.variables.append(value)
            return _Node("var", value)
        raise ExpressionError(f"unexpected {value!r} at column {column} in {self.text!r}")


# ---------------------------------------------------------------------------------------- values
#
# A value is what BT.CPP's ``Any`` holds: an int (``int64_t``; a bool is one too, that prints as
# true/false), a float (``double``), a str, or BT.CPP's empty Any (:data:`_EMPTY`, what
# ``number .. number`` gives). A Python enum or list a behaviour wrote is none of these: it takes part
# only where chaser-bt extends BT.CPP (an enum equals its member name).


class _Empty:
    """BT.CPP's empty ``Any``: the value of ``1 .. 2``, harmless unless something reads it."""

    def __repr__(self) -> str:
        return "<empty>"


_EMPTY = _Empty()
_INT64 = 2**63


def _is_number(value: Any) -> bool:
    """``Any::isNumber()``: an int, bool or float (a Python enum is not one, even an IntEnum)."""
    return isinstance(value, (bool, int, float)) and not isinstance(value, enum.Enum)


def _number(value: Any) -> float | None:
    return float(value) if _is_number(value) else None


def _not_empty(value: Any, side: str, op: str) -> Any:
    if value is _EMPTY:
        raise ExpressionError(f"the {side} operand of the operator [{op}] is not initialized")
    return value


def number_text(value: float) -> str:
    """A number as Switch cases compare it: shortest form, no trailing ``.0``."""
    if value.is_integer() and abs(value) < 1e16:
        return str(int(value))
    return repr(value)


def double_text(value: float) -> str:
    """``std::to_string(double)``: ``printf("%f")``, so 0.5 is ``0.500000`` (what ``..`` writes)."""
    if math.isnan(value):
        return "-nan" if math.copysign(1.0, value) < 0 else "nan"
    return "%f" % value


def to_text(value: Any) -> str:
    """``Any::cast<std::string>()``: a bool is ``1``/``0``, an int its digits, a float :func:`double_text`.

    A Python enum gives its member name (chaser-bt's extension).
    """
    if isinstance(value, str):
        return value
    if isinstance(value, enum.Enum):
        return value.name
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return double_text(value)
    raise ExpressionError(f"{value!r} has no text form")


_DOUBLE_PREFIX = re.compile(r"-?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)", re.IGNORECASE)
_INT_PREFIX = re.compile(r"-?\d+")


def parse_double_prefix(text: str) -> float:
    """``std::from_chars`` to a double: the longest number at the start (``'3abc'`` is 3); no sign
    ``+``, no blank before it; nothing readable, or a value past the double range, raises."""
    match = _DOUBLE_PREFIX.match(text)
    if match is None:
        raise ExpressionError(f"cannot read {text!r} as a number")
    number = match.group(0)
    value = float(number)
    if math.isinf(value) and "n" not in number.lower():
        raise ExpressionError(f"{text!r} is out of the range of a double")
    return value


def parse_int_prefix(text: str) -> int:
    """``std::from_chars`` to an int64: the digits at the start (``'2.5'`` is 2)."""
    match = _INT_PREFIX.match(text)
    if match is None or not -_INT64 <= int(match.group(0)) < _INT64:
        raise ExpressionError(f"cannot read {text!r} as an integer")
    return int(match.group(0))


def _string_to_double(text: str, enums: Mapping[str, int]) -> float:
    """BT.CPP's ``StringToDouble``: ``'true'``/``'false'``, a scripting enum's name, else a number."""
    if text == "true":
        return 1.0
    if text == "false":
        return 0.0
    if text in enums:
        return float(enums[text])
    return parse_double_prefix(text)


def _to_double(value: Any) -> float:
    """``Any::cast<double>()``: a number, or text read as a number (no true/false here)."""
    if _is_number(value):
        return float(value)
    if isinstance(value, str):
        return parse_double_prefix(value)
    if value is _EMPTY:
        raise ExpressionError("the value is empty")
    raise ExpressionError(f"{value!r} is not a number")


def _to_int64(value: Any, why: str) -> int:
    """``Any::cast<int64_t>()`` of a number: a float must be whole and in range."""
    if isinstance(value, float):
        if not (math.isfinite(value) and value.is_integer() and -_INT64 <= value < _INT64):
            raise ExpressionError(why)
        return int(value)
    return int(value)


def truth(value: Any) -> bool:
    """BT.CPP's ``cast<bool>()``: a float is true when non-zero, an int must be 0 or 1; text is no truth value."""
    if isinstance(value, bool):
        return value
    if isinstance(value, int) and not isinstance(value, enum.Enum):
        if value not in (0, 1):
            raise ExpressionError(f"{value!r} is not castable to bool (an integer must be 0 or 1)")
        return value == 1
    if isinstance(value, float):
        return value != 0.0
    raise ExpressionError(f"{value!r} is not a truth value (BT.CPP converts no text to bool here)")


def _comparable(value: Any) -> Any:
    return value.name if isinstance(value, enum.Enum) else value


def _holds(op: str, a: Any, b: Any) -> bool:
    """BT.CPP's ``SwitchImpl``: each test is written as the negation of its opposite (so NaN orders true)."""
    if op == "==":
        return abs(a - b) <= _EPSILON if isinstance(a, float) else a == b
    if op == "!=":
        return not (abs(a - b) <= _EPSILON if isinstance(a, float) else a == b)
    if op == "<":
        return not a >= b
    if op == ">":
        return not a <= b
    if op == "<=":
        return not a > b
    return not a < b


def _compare(op: str, a: Any, b: Any, enums: Mapping[str, int]) -> bool:
    _not_empty(a, "left", op)
    _not_empty(b, "right", op)
    a, b = _comparable(a), _comparable(b)
    if _is_number(a) and _is_number(b):
        return _holds(op, float(a), float(b))
    if isinstance(a, str) and isinstance(b, str):
        return _holds(op, a, b)
    word = "compare" if op in ("==", "!=") else "order"
    try:
        if isinstance(a, str) and _is_number(b):
            return _holds(op, _string_to_double(a, enums), float(b))
        if _is_number(a) and isinstance(b, str):
            return _holds(op, float(a), _string_to_double(b, enums))
    except ExpressionError as e:
        raise ExpressionError(f"cannot {word} {a!r} with {b!r}: {e}") from None
    raise ExpressionError(f"cannot {word} {a!r} with {b!r}: BT.CPP can't mix these types in a comparison")


def _binary(op: str, a: Any, b: Any) -> Any:
    _not_empty(a, "left", op)
    _not_empty(b, "right", op)
    if _is_number(a) and _is_number(b):
        x, y = float(a), float(b)
        if op == "+":
            return x + y
        if op == "-":
            return x - y
        if op == "*":
            return x * y
        if op == "/":
            if y == 0.0:
                if x == 0.0 or math.isnan(x):
                    return -math.nan if x == 0.0 else x  # x86's 0.0/0.0 is the negative quiet NaN
                return math.copysign(math.inf, x) * math.copysign(1.0, y)
            return x / y
        if op in ("&", "|", "^"):
            why = "binary operators are not allowed if one of the operands is not an integer"
            i, j = _to_int64(a, why), _to_int64(b, why)
            return float({"&": i & j, "|": i | j, "^": i ^ j}[op])
        if op in ("&&", "||"):
            try:
                left, right = truth(a), truth(b)  # both cast, as BT.CPP does
            except ExpressionError:
                raise ExpressionError("logic operators are not allowed if one of the operands is not castable to bool") from None
            return float(left and right) if op == "&&" else float(left or right)
        return _EMPTY  # number .. number: BT.CPP's switch falls through to an empty Any
    if isinstance(a, str) and isinstance(b, str) and op == "+":
        return a + b
    if op == ".." and (isinstance(a, str) or isinstance(b, str)) and (isinstance(a, str) or _is_number(a)) and (
        isinstance(b, str) or _is_number(b)
    ):
        return to_text(a) + to_text(b)
    raise ExpressionError(f"operation {op!r} not permitted between {a!r} and {b!r}")


def _unary(kind: str, value: Any) -> float:
    if not _is_number(value):
        raise ExpressionError(f"invalid operator for {value!r}")
    number = float(value)
    if kind == "neg":
        return -number
    if kind == "not":
        return float(not number)
    if not -_INT64 <= number < _INT64 or math.isnan(number):
        raise ExpressionError("number out of range for bitwise operation")
    return float(~int(number))  # static_cast<int64_t> truncates: ~2.5 is -3


class _Evaluator:
    def __init__(self, env: Environment, enums: Mapping[str, int]) -> None:
        self.env = env
        self.enums = enums

    def evaluate(self, node: _Node) -> Any:
        kind = node.kind
        if kind == "const":
            return node.value
        if kind == "var":
            try:
                return self.env.get(node.value)
            except KeyError:
                raise ExpressionError(f"blackboard entry '{node.value}' has no value yet (Variable not found)") from None
        if kind == "seq":
            value = None
            for child in node.children:
                value = self.evaluate(child)
            return value
        if kind == "assign":
            return self.assign(node)
        if kind == "?:":
            # BT.CPP: (isType<SimpleString>() && size) || cast<double>() != 0; a string's type is
            # std::string, never SimpleString, so text counts by its number ('3' true, 'abc' throws).
            chosen = _to_double(self.evaluate(node.children[0])) != 0.0
            return self.evaluate(node.children[1 if chosen else 2])
        if kind == "cmp":
            left = self.evaluate(node.children[0])
            for i, op in enumerate(node.value):
                right = self.evaluate(node.children[i + 1])
                if not _compare(op, left, right, self.enums):
                    return 0.0
                left = right
            return 1.0
        if kind in ("neg", "not", "~"):
            return _unary(kind, self.evaluate(node.children[0]))
        a, b = (self.evaluate(child) for child in node.children)
        return _binary(kind, a, b)

    def assign(self, node: _Node) -> Any:
        """BT.CPP's ``ExprAssignment``: the entry keeps its type where BT.CPP's ``copyInto`` does."""
        op = node.value
        name = node.children[0].value
        env = self.env
        exists = env.has(name)
        if not exists and op != ":=":
            raise ExpressionError(
                f"the blackboard entry [{name}] doesn't exist, yet: use the operator [:=] instead of [{op}] to create it"
            )
        value = _not_empty(self.evaluate(node.children[1]), "right", op)
        converter = getattr(env, "converter", None)
        convert = converter(name) if exists and converter is not None else None
        try:
            current = env.get(name) if exists else _EMPTY
        except KeyError:  # declared by a port, never written: BT.CPP's empty entry
            current = _EMPTY
        if op in (":=", "="):
            if current is _EMPTY:
                # The first value: a port-declared entry converts text with the port's converter.
                result = convert(value) if convert is not None and isinstance(value, str) else value
            elif isinstance(value, str) and not isinstance(current, str) and _is_scalar(current):
                result = convert(value) if convert is not None else _string_to_double(value, self.enums)
            else:
                result = copy_into(value, current)
            env.set(name, result)
            return result
        current = _not_empty(current, "left", op)
        if _is_number(value):
            if not _is_number(current):
                raise ExpressionError(f"operator {op!r} can't be used with the non-numeric entry [{name}]")
            result = copy_into(_binary(op[0], current, value), current)
        elif isinstance(value, str):
            if op != "+=":
                raise ExpressionError(f"operator {op!r} not supported for strings")
            result = copy_into(to_text(current) + value, current)
        else:
            result = current  # BT.CPP leaves the entry as it was
        env.set(name, result)
        return result


def _is_scalar(value: Any) -> bool:
    return isinstance(value, str) or _is_number(value)


def copy_into(value: Any, current: Any) -> Any:
    """BT.CPP's ``Any::copyInto``: the destination keeps its type (a number is cast, exactly), or it raises."""
    if current is _EMPTY:
        return value
    if not _is_scalar(current):
        return value  # a Python enum, list... a behaviour wrote: chaser-bt replaces it (BT.CPP has no such type)
    if isinstance(current, str):
        if isinstance(value, str):
            return value
    elif _is_number(value):
        if isinstance(current, bool):
            number = _to_int64(value, f"{value!r} cannot be stored in the bool entry")
            if number not in (0, 1):
                raise ExpressionError(f"{value!r} cannot be stored in a bool entry")
            return bool(number)
        if isinstance(current, int):
            return _to_int64(value, f"invalid floating point to integer conversion of {value!r}")
        return float(value)
    raise ExpressionError(f"a value {value!r} can't be stored in an entry holding {current!r}")
