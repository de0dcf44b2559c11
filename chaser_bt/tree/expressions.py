"""BehaviorTree.CPP 4.10's scripting language: ``Script`` nodes, ``ScriptCondition``, pre- and post-conditions.

A script is statements separated by ``;``; its value is the last one's. Written exactly as in
BT.CPP (``script_parser.cpp``, ``scripting/operators.hpp``), with BT.CPP's binding powers, loosest
first: assignment (``:=`` creates an entry, ``=`` needs an existing one, ``+= -= *= /=``), the
ternary ``c ? a : b``, ``||``, ``&&``, comparisons (chainable: ``a < b < c``), ``| ^``, ``&``,
``+ - ..`` (``..`` concatenates), ``* /``, then the prefixes ``- ! ~``. Operands: integers
(``12``, ``0x1F``), reals, ``'text'`` or ``"text"``, ``true``/``false``, blackboard entries
(``name``; ``@name`` is the root blackboard) and scripting enums (names the registry maps to
integers).

Values follow BT.CPP's: arithmetic, logic and comparisons give floats (``true`` is 1.0), ``/``
divides as doubles, ``&&``/``||`` evaluate both sides, ``==`` between numbers allows a float
epsilon, a string meets a number by conversion. A blackboard enum (a behaviour's Python enum)
compares equal to its member name (``mode == 'RTL'``). Evaluating an entry that has no value, or
mixing types BT.CPP refuses, raises :class:`ExpressionError` (BT.CPP throws).

Parsing happens at validation (a malformed script is a tree problem with its position);
evaluation at tick time against an :class:`Environment` the caller provides, so this module knows
nothing of py_trees.
"""

from __future__ import annotations

import enum
import math
import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

__all__ = ["Environment", "Expression", "ExpressionError", "parse_expression", "truth", "number_text"]


class ExpressionError(ValueError):
    """A malformed script (at parse time) or one that cannot be evaluated (at tick time)."""


class Environment(Protocol):
    """Where a script's names live: ``get`` raises KeyError for an entry with no value."""

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

    def run(self, env: Environment) -> Any:
        """Execute the script against ``env`` and return the last statement's value."""
        return _evaluate(self.root, env)

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
    return Expression(text, root, tuple(dict.fromkeys(parser.variables)), tuple(dict.fromkeys(parser.assigned)))


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


def _number(value: Any) -> float | None:
    if isinstance(value, (bool, int, float)):
        return float(value)
    return None


def number_text(value: float) -> str:
    """A number as BT.CPP writes it into a string: shortest form, no trailing ``.0``."""
    if value.is_integer() and abs(value) < 1e16:
        return str(int(value))
    return repr(value)


def _text(value: Any) -> str:
    if isinstance(value, enum.Enum):
        return value.name
    number = _number(value)
    return number_text(number) if number is not None else str(value)


def _string_number(value: str) -> float:
    try:
        return float(value)
    except ValueError:
        raise ExpressionError(f"cannot read {value!r} as a number") from None


def truth(value: Any) -> bool:
    """BT.CPP's ``cast<bool>()``: a real is true when non-zero, an integer must be 0 or 1; 'true'/'false' as text."""
    if isinstance(value, int) and not isinstance(value, bool) and value not in (0, 1):
        raise ExpressionError(f"{value!r} is not castable to bool (an integer must be 0 or 1)")
    number = _number(value)
    if number is not None:
        return number != 0.0
    if isinstance(value, str) and value.strip().lower() in ("true", "false", "1", "0"):
        return value.strip().lower() in ("true", "1")
    raise ExpressionError(f"{value!r} is not a truth value")


def _comparable(value: Any) -> Any:
    if isinstance(value, enum.Enum):
        return value.name
    number = _number(value)
    return value if number is None else number


_ORDER = {"==": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}


def _compare(op: str, a: Any, b: Any) -> bool:
    a, b = _comparable(a), _comparable(b)
    word = "compare" if op in ("==", "!=") else "order"
    try:
        if isinstance(a, str) and isinstance(b, float):
            a = float(a)
        elif isinstance(b, str) and isinstance(a, float):
            b = float(b)
    except ValueError:
        raise ExpressionError(f"cannot {word} {a!r} with {b!r}") from None
    if isinstance(a, float) and isinstance(b, float):
        if op in ("==", "!="):
            return (abs(a - b) <= _EPSILON) == (op == "==")
    elif not (isinstance(a, str) and isinstance(b, str)):
        raise ExpressionError(f"cannot {word} {a!r} with {b!r}")
    return bool(_ORDER[op](a, b))


def _integer(value: float) -> int:
    if not value.is_integer():
        raise ExpressionError("binary operators are not allowed if one of the operands is not an integer")
    return int(value)


def _binary(op: str, a: Any, b: Any) -> Any:
    x, y = _number(a), _number(b)
    if x is not None and y is not None:
        if op == "+":
            return x + y
        if op == "-":
            return x - y
        if op == "*":
            return x * y
        if op == "/":
            if y == 0.0:
                return math.nan if x == 0.0 else math.copysign(math.inf, x) * math.copysign(1.0, y)
            return x / y
        if op in ("&", "|", "^"):
            i, j = _integer(x), _integer(y)
            return float({"&": i & j, "|": i | j, "^": i ^ j}[op])
        if op in ("&&", "||"):
            left, right = truth(a), truth(b)  # both cast, as BT.CPP does
            return float(left and right) if op == "&&" else float(left or right)
    if isinstance(a, str) and isinstance(b, str) and op == "+":
        return a + b
    if op == ".." and (isinstance(a, str) or isinstance(b, str)) and (x is not None or isinstance(a, str)) and (
        y is not None or isinstance(b, str)
    ):
        return _text(a) + _text(b)
    raise ExpressionError(f"operation {op!r} not permitted between {a!r} and {b!r}")


def _evaluate(node: _Node, env: Environment) -> Any:
    kind = node.kind
    if kind == "const":
        return node.value
    if kind == "var":
        try:
            return env.get(node.value)
        except KeyError:
            raise ExpressionError(f"blackboard entry '{node.value}' has no value yet (Variable not found)") from None
    if kind == "seq":
        value = None
        for child in node.children:
            value = _evaluate(child, env)
        return value
    if kind == "assign":
        return _assign(node, env)
    if kind == "?:":
        condition = _evaluate(node.children[0], env)
        chosen = (isinstance(condition, str) and condition != "") or (
            not isinstance(condition, str) and truth(condition)
        )
        return _evaluate(node.children[1 if chosen else 2], env)
    if kind == "cmp":
        values = [_evaluate(child, env) for child in node.children]
        return 1.0 if all(_compare(op, values[i], values[i + 1]) for i, op in enumerate(node.value)) else 0.0
    if kind in ("neg", "not", "~"):
        value = _evaluate(node.children[0], env)
        number = _number(value)
        if number is None:
            raise ExpressionError(f"invalid operator for {value!r}")
        if kind == "neg":
            return -number
        if kind == "not":
            return float(number == 0.0)
        return float(~_integer(number))
    a, b = (_evaluate(child, env) for child in node.children)
    return _binary(kind, a, b)


def _assign(node: _Node, env: Environment) -> Any:
    op = node.value
    name = node.children[0].value
    exists = env.has(name)
    if not exists and op != ":=":
        raise ExpressionError(
            f"the blackboard entry [{name}] doesn't exist, yet: use the operator [:=] instead of [{op}] to create it"
        )
    value = _evaluate(node.children[1], env)
    if op in (":=", "="):
        if exists:
            current = env.get(name)
            if isinstance(value, str) and _number(current) is not None and not isinstance(current, str):
                value = _string_number(value)
        env.set(name, value)
        return value
    current = env.get(name)
    if _number(value) is not None:
        if _number(current) is None:
            raise ExpressionError(f"this assignment operator can't be used with a non-numeric entry [{name}]")
        result = _binary(op[0], current, value)
    elif isinstance(value, str) and isinstance(current, str) and op == "+=":
        result = current + value
    else:
        raise ExpressionError(f"operator {op!r} not permitted between {current!r} and {value!r}")
    env.set(name, result)
    return result
