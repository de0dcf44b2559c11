"""Blackboard expressions for BT.CPP v4 pre-conditions (``_while="battery_pct > 30 && !rtl"``).

The subset of BehaviorTree.CPP's scripting language a *condition* needs: numbers, ``'text'`` or
``"text"``, ``true``/``false``, blackboard keys (``name``; ``@name`` is the root blackboard),
``!`` and unary ``-``, ``* /``, ``+ -``, ``< <= > >=``, ``== !=``, ``&&``, ``||`` and parentheses,
with C's precedence. Assignments (``:=``) belong to BT.CPP's post-condition scripts and are refused.

Parsing happens at validation (a malformed expression is a tree problem with its position),
evaluation at tick time against values looked up by the caller, so this module knows nothing
of py_trees. Numbers compare as floats, as in BT.CPP; a blackboard enum compares equal to the
string of its member name (``mode == 'RTL'``).
"""

from __future__ import annotations

import enum
import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["Expression", "ExpressionError", "parse_expression"]


class ExpressionError(ValueError):
    """A malformed expression (at parse time) or one that cannot be evaluated (at tick time)."""


_TOKEN = re.compile(
    r"\s*(?:"
    r"(?P<number>\d+\.\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|\d+(?:[eE][+-]?\d+)?)"
    r"|(?P<string>'[^']*'|\"[^\"]*\")"
    r"|(?P<name>@?[A-Za-z_][A-Za-z0-9_]*)"
    r"|(?P<op>&&|\|\||==|!=|<=|>=|:=|[-+*/<>!()=])"
    r")"
)

_BINARY: dict[str, tuple[int, Callable[[Any, Any], Any]]] = {
    "||": (1, lambda a, b: _truth(a) or _truth(b)),
    "&&": (2, lambda a, b: _truth(a) and _truth(b)),
    "==": (3, lambda a, b: _equal(a, b)),
    "!=": (3, lambda a, b: not _equal(a, b)),
    "<": (4, lambda a, b: _order(operator.lt, a, b)),
    "<=": (4, lambda a, b: _order(operator.le, a, b)),
    ">": (4, lambda a, b: _order(operator.gt, a, b)),
    ">=": (4, lambda a, b: _order(operator.ge, a, b)),
    "+": (5, lambda a, b: _arith(operator.add, a, b)),
    "-": (5, lambda a, b: _arith(operator.sub, a, b)),
    "*": (6, lambda a, b: _arith(operator.mul, a, b)),
    "/": (6, lambda a, b: _arith(operator.truediv, a, b)),
}


@dataclass(frozen=True)
class _Node:
    kind: str  # "const" | "var" | "not" | "neg" | binary operator
    value: Any = None
    left: _Node | None = None
    right: _Node | None = None


@dataclass(frozen=True)
class Expression:
    """A parsed condition; ``variables`` are the blackboard names it reads, in order of appearance."""

    text: str
    root: _Node
    variables: tuple[str, ...]

    def evaluate(self, lookup: Callable[[str], Any]) -> bool:
        """The condition's truth with each variable's value from ``lookup(name)``.

        Raises:
            ExpressionError: a variable is missing (``lookup`` raised KeyError) or types do not fit.
        """
        return _truth(_evaluate(self.root, lookup))

    def evaluate_with(self, values: Mapping[str, Any]) -> bool:
        """:meth:`evaluate` with the variables' values given as a mapping."""
        return self.evaluate(values.__getitem__)


def parse_expression(text: str) -> Expression:
    """Parse a BT.CPP condition expression.

    Raises:
        ExpressionError: naming the offending token and its 1-based column.
    """
    tokens = _tokenize(text)
    parser = _Parser(text, tokens)
    root = parser.expression(0)
    if parser.index != len(tokens):
        kind, value, column = tokens[parser.index]
        raise ExpressionError(f"unexpected {value!r} at column {column} in {text!r}")
    return Expression(text, root, tuple(dict.fromkeys(parser.variables)))


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
            value = float(value)
        elif kind == "string":
            value = value[1:-1]
        elif kind == "name" and value in ("true", "false"):
            kind, value = "const", value == "true"
        elif kind == "op" and value in (":=", "="):
            raise ExpressionError(
                f"assignment {value!r} at column {column} in {text!r}: a condition only reads the blackboard"
            )
        tokens.append((kind, value, column))
        position = match.end()
    if not tokens:
        raise ExpressionError("empty expression")
    return tokens


class _Parser:
    """Precedence climbing over the token list."""

    def __init__(self, text: str, tokens: list[tuple[str, Any, int]]) -> None:
        self.text = text
        self.tokens = tokens
        self.index = 0
        self.variables: list[str] = []

    def peek(self) -> tuple[str, Any, int] | None:
        return self.tokens[self.index] if self.index < len(self.tokens) else None

    def expression(self, min_precedence: int) -> _Node:
        left = self.unary()
        while True:
            token = self.peek()
            if token is None or token[0] != "op" or token[1] not in _BINARY:
                return left
            precedence = _BINARY[token[1]][0]
            if precedence <= min_precedence:
                return left
            self.index += 1
            right = self.expression(precedence)
            left = _Node(token[1], left=left, right=right)

    def unary(self) -> _Node:
        token = self.peek()
        if token is None:
            raise ExpressionError(f"{self.text!r} ends where a value was expected")
        kind, value, column = token
        self.index += 1
        if kind == "op" and value == "!":
            return _Node("not", left=self.unary())
        if kind == "op" and value == "-":
            return _Node("neg", left=self.unary())
        if kind == "op" and value == "(":
            inner = self.expression(0)
            closing = self.peek()
            if closing is None or closing[1] != ")":
                raise ExpressionError(f"'(' at column {column} is never closed in {self.text!r}")
            self.index += 1
            return inner
        if kind in ("number", "string", "const"):
            return _Node("const", value)
        if kind == "name":
            self.variables.append(value)
            return _Node("var", value)
        raise ExpressionError(f"unexpected {value!r} at column {column} in {self.text!r}")


def _evaluate(node: _Node, lookup: Callable[[str], Any]) -> Any:
    if node.kind == "const":
        return node.value
    if node.kind == "var":
        try:
            return lookup(node.value)
        except KeyError:
            raise ExpressionError(f"blackboard entry '{node.value}' has no value yet") from None
    assert node.left is not None
    if node.kind == "not":
        return not _truth(_evaluate(node.left, lookup))
    if node.kind == "neg":
        return _arith(operator.sub, 0.0, _evaluate(node.left, lookup))
    assert node.right is not None
    # && and || short-circuit, as in C and BT.CPP.
    if node.kind == "&&":
        return _truth(_evaluate(node.left, lookup)) and _truth(_evaluate(node.right, lookup))
    if node.kind == "||":
        return _truth(_evaluate(node.left, lookup)) or _truth(_evaluate(node.right, lookup))
    return _BINARY[node.kind][1](_evaluate(node.left, lookup), _evaluate(node.right, lookup))


def _number(value: Any) -> float | None:
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, (int, float)):
        return float(value)
    return None


def _truth(value: Any) -> bool:
    if isinstance(value, bool):
        return value
    number = _number(value)
    if number is not None:
        return number != 0.0
    raise ExpressionError(f"{value!r} is not a truth value")


def _comparable(value: Any) -> Any:
    if isinstance(value, enum.Enum):
        return value.name
    number = _number(value)
    return value if number is None else number


def _equal(a: Any, b: Any) -> bool:
    a, b = _comparable(a), _comparable(b)
    if isinstance(a, str) != isinstance(b, str):
        raise ExpressionError(f"cannot compare {a!r} with {b!r}")
    return bool(a == b)


def _order(op: Callable[[Any, Any], bool], a: Any, b: Any) -> bool:
    a, b = _comparable(a), _comparable(b)
    if not (isinstance(a, float) and isinstance(b, float)) and not (isinstance(a, str) and isinstance(b, str)):
        raise ExpressionError(f"cannot order {a!r} and {b!r}")
    return bool(op(a, b))


def _arith(op: Callable[[Any, Any], Any], a: Any, b: Any) -> Any:
    x, y = _number(a), _number(b)
    if x is None or y is None:
        if op is operator.add and isinstance(a, str) and isinstance(b, str):
            return a + b
        raise ExpressionError(f"cannot compute with {a!r} and {b!r}")
    try:
        return op(x, y)
    except ZeroDivisionError:
        raise ExpressionError("division by zero") from None
