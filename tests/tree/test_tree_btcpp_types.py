"""BT.CPP 4.10's values, types and conversions, unit by unit (the conformance traces check them against BT.CPP itself).

``..`` writes a double as ``std::to_string`` does, text meets a number through ``StringToDouble``,
an assignment keeps the entry's type (``Any::copyInto``), a typed port converts what it reads
(``getInput<T>``), a port wired to ``{key}`` creates the entry when the tree loads, and two ports
may not give one entry different types.
"""

from __future__ import annotations

import py_trees
import pytest

from chaser_bt.clock import ManualClock
from chaser_bt.tree import Registry, load_tree_text, reset_blackboard, validate_tree_text
from chaser_bt.tree.expressions import ExpressionError, parse_expression
from chaser_bt.tree.ports import btcpp_cast, coerce_literal, convert_from_string

Blackboard = py_trees.blackboard.Blackboard


class Env(dict):
    """A script environment over a dict, with entries declared by ports (``declared``: name -> converter)."""

    def __init__(self, declared=None, **values):
        super().__init__(values)
        self.declared = declared or {}

    def get(self, name):
        return self[name]

    def has(self, name):
        return name in self or name in self.declared

    def set(self, name, value):
        self[name] = value

    def converter(self, name):
        return self.declared.get(name)


def run(code: str, env: Env | None = None, enums=None):
    env = Env() if env is None else env
    return parse_expression(code, enums).run(env), env


@pytest.mark.parametrize(
    ("code", "expected"),
    [
        ("0.5 .. ''", "0.500000"),
        ("3 .. ''", "3"),
        ("(1 + 1) .. ''", "2.000000"),
        ("'a' .. 2.5", "a2.500000"),
        ("'true' == 1", 1.0),
        ("'false' == 0", 1.0),
        ("'3abc' == 3", 1.0),
        ("'10' > '9'", 0.0),  # two texts compare as text
        ("'RED' == 1", 1.0),
        ("3 ? 'y' : 'n'", "y"),
        ("'0' ? 'y' : 'n'", "n"),
        ("~2.5", -3.0),
    ],
)
def test_values_as_btcpp_computes_them(code, expected):
    assert run(code, enums={"RED": 1})[0] == expected


@pytest.mark.parametrize("code", ["'true' ? 1 : 2", "'' ? 1 : 2", "'abc' == 1", "1 .. 2 == 1", "r := 1 .. 2"])
def test_what_btcpp_throws_on_raises(code):
    with pytest.raises(ExpressionError):
        run(code)


def test_number_dot_dot_number_is_harmless_as_a_statement():
    run("1 .. 2")


@pytest.mark.parametrize(
    ("code", "x"),
    [
        ("x := 3; x += 1", 4),
        ("x := 4; x /= 2", 2),
        ("x := 3; x = 2.0", 2),
        ("x := 3; x = '5'", 5.0),  # StringToDouble: the entry becomes a double, as in BT.CPP
        ("x := 2.5; x = 'true'", 1.0),
        ("x := 'ab'; x += 'c'", "abc"),
    ],
)
def test_assignments_keep_the_entry_type(code, x):
    value = run(code)[1]["x"]
    assert value == x and type(value) is type(x)


@pytest.mark.parametrize("code", ["x := 3; x -= 0.5", "x := 3; x = 2.5", "x := 3; x /= 0", "x := 'ab'; x = 3",
                                  "x := 3; x += 'a'"])
def test_assignments_btcpp_refuses_raise(code):
    with pytest.raises(ExpressionError):
        run(code)


def test_a_declared_entry_exists_before_it_is_written_and_converts_text():
    env = Env(declared={"n": lambda text: convert_from_string(text, int)})
    run("n = '7'", env)
    assert env["n"] == 7 and type(env["n"]) is int
    with pytest.raises(ExpressionError, match="doesn't exist"):
        run("m = 1", env)


@pytest.mark.parametrize(
    ("text", "data_type", "value"),
    [("2.5", int, 2), ("2abc", int, 2), ("-3", int, -3), ("1e3", float, 1000.0), ("TRUE", bool, True),
     ("0", bool, False), ("4;5", list[int], [4, 5]), ("", list[int], []), ("a;b", list[str], ["a", "b"])],
)
def test_convert_from_string_as_btcpp(text, data_type, value):
    assert convert_from_string(text, data_type) == value


@pytest.mark.parametrize(("text", "data_type"), [("+2", int), (" 2", int), ("abc", float), ("yes", bool), ("-1", "unsigned")])
def test_convert_from_string_refuses_what_btcpp_refuses(text, data_type):
    with pytest.raises(ExpressionError):
        convert_from_string(text, int if data_type == "unsigned" else data_type, "unsigned" if data_type == "unsigned" else None)


@pytest.mark.parametrize(
    ("value", "data_type", "expected"),
    [(2.0, int, 2), ("2", int, 2), (True, int, 1), (2.5, bool, True), (1, bool, True), (2.0, str, "2.000000"),
     (3, float, 3.0), ("1.5;2", list[float], [1.5, 2.0])],
)
def test_typed_ports_convert_what_they_read(value, data_type, expected):
    converted = btcpp_cast(value, data_type)
    assert converted == expected and type(converted) is type(expected)


@pytest.mark.parametrize(("value", "data_type"), [(2.5, int), (2, bool), ("true", int)])
def test_typed_ports_refuse_what_btcpp_refuses(value, data_type):
    with pytest.raises(ExpressionError):
        btcpp_cast(value, data_type)


@pytest.mark.parametrize(("text", "data_type"), [("+2", int), (" 2", int), ("2.0", int), ("yes", bool), ("on", bool)])
def test_literals_must_be_one_value_btcpp_reads(text, data_type):
    with pytest.raises(ValueError):
        coerce_literal(text, data_type)


def xml(body: str, extra: str = "") -> str:
    return (f'<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">{body}</BehaviorTree>'
            f"{extra}</root>")


def test_two_ports_giving_one_entry_different_types_is_a_problem():
    registry = Registry.with_control_nodes()
    int_then_text = xml('<Sequence><LoopInt queue="1" value="{k}"><AlwaysSuccess/></LoopInt>'
                        '<Switch2 variable="{k}" case_1="1" case_2="2"><AlwaysSuccess/><AlwaysSuccess/>'
                        "<AlwaysSuccess/></Switch2></Sequence>")
    problems = validate_tree_text(int_then_text, "t.xml", registry, fmt="xml")
    assert [p.message for p in problems if "declared it int" in p.message], problems
    text_then_int_output = xml('<Sequence><Switch2 variable="{k}" case_1="1" case_2="2"><AlwaysSuccess/>'
                               "<AlwaysSuccess/><AlwaysSuccess/></Switch2>"
                               '<LoopInt queue="1" value="{k}"><AlwaysSuccess/></LoopInt></Sequence>')
    problems = validate_tree_text(text_then_int_output, "t.xml", registry, fmt="xml")
    assert [p.message for p in problems if "throws at that write" in p.message], problems
    same = xml('<Sequence><Script code="k := 1"/><Repeat num_cycles="{k}"><AlwaysSuccess/></Repeat>'
               '<RetryUntilSuccessful num_attempts="{k}"><AlwaysSuccess/></RetryUntilSuccessful></Sequence>')
    assert validate_tree_text(same, "t.xml", registry, fmt="xml") == []
    unsigned = xml('<Sequence><Script code="k := 1"/><Repeat num_cycles="{k}"><AlwaysSuccess/></Repeat>'
                   '<Timeout msec="{k}"><AlwaysSuccess/></Timeout></Sequence>')
    assert validate_tree_text(unsigned, "t.xml", registry, fmt="xml")


def tick(text: str, ticks: int = 1):
    reset_blackboard()
    tree = load_tree_text(text, "t.xml", Registry.with_control_nodes(), fmt="xml")
    py_trees.trees.setup(tree.root, clock=ManualClock(0.0))
    for _ in range(ticks):
        tree.root.tick_once()
    return tree.root.status


def test_a_script_may_set_an_entry_a_port_declares_and_the_port_converts_it():
    text = xml('<Sequence><Script code="n = 2.0; a := 0"/><Repeat num_cycles="{n}"><Script code="a += 1"/></Repeat>'
               "</Sequence>")
    tick(text, 2)
    assert Blackboard.get("/n") == 2.0 and Blackboard.get("/a") == 2


def test_a_loop_reads_a_text_queue_from_the_blackboard():
    text = xml('<Sequence><Script code="q := \'4;5\'; s := 0"/>'
               '<LoopInt queue="{q}" value="{v}"><Script code="s += v"/></LoopInt></Sequence>')
    tick(text, 3)
    assert Blackboard.get("/s") == 9


def test_autoremap_ignores_the_model_default():
    text = xml('<Sequence><Script code="z := 3; v := 1"/><SubTree ID="Sub" _autoremap="true"/></Sequence>',
               '<BehaviorTree ID="Sub"><Script code="out := v * 2"/></BehaviorTree>'
               '<TreeNodesModel><SubTree ID="Sub"><input_port name="v" default="{z}"/></SubTree></TreeNodesModel>')
    tick(text)
    assert Blackboard.get("/out") == 2.0
