"""Properties of literal typing and of the YAML writer, checked with hypothesis."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from chaser_bt.tree.model import Location, NodeSpec, PortArg, TreeDocument, TreeSpec
from chaser_bt.tree.ports import LiteralError, coerce_literal, literal_from_text, literal_text
from chaser_bt.tree.yaml_format import dump_yaml, parse_yaml

numbers = st.one_of(st.integers(-10**9, 10**9), st.floats(allow_nan=False, allow_infinity=False))


@given(st.lists(numbers, max_size=8))
def test_any_list_of_numbers_becomes_a_list_of_equal_floats(values):
    coerced = coerce_literal(values, list[float])
    assert all(type(v) is float for v in coerced)
    assert coerced == [float(v) for v in values]


@given(st.booleans())
def test_a_bool_is_never_a_number(flag):
    for data_type in (float, int, list[float]):
        with pytest.raises(LiteralError):
            coerce_literal([flag] if data_type == list[float] else flag, data_type)


@given(st.floats(allow_nan=False))
def test_a_float_written_as_text_reads_back_exactly(x):
    assert coerce_literal(repr(x), float) == x


# Printable text: PyYAML folds control and line-separator characters such as U+0085 when it writes them.
_text = st.text(st.characters(blacklist_categories=("C", "Zl", "Zp")), max_size=10)
_ids = st.from_regex(r"[A-Z][A-Za-z]{0,8}", fullmatch=True)
_ports = st.dictionaries(
    st.from_regex(r"[a-z][a-z_]{0,8}", fullmatch=True).filter(lambda p: p not in {"name", "children", "child"}),
    st.one_of(numbers, st.booleans(), _text, st.lists(numbers, max_size=4),
              st.from_regex(r"\{[a-z]{1,6}\}", fullmatch=True)),
    max_size=3,
)
_here = Location("t.yaml", 1, 1)


def _node(node_id: str, name: str | None, ports: dict, children: list[NodeSpec]) -> NodeSpec:
    return NodeSpec(node_id, _here, name, {p: PortArg(v, _here) for p, v in ports.items()}, children)


_nodes = st.recursive(
    st.builds(_node, _ids, st.none() | _text.filter(bool), _ports, st.just([])),
    lambda children: st.builds(_node, _ids, st.none(), st.just({}), st.lists(children, min_size=1, max_size=3)),
    max_leaves=8,
)


@given(st.dictionaries(_ids, _nodes, min_size=1, max_size=3))
def test_writing_a_model_as_yaml_and_reading_it_back_gives_the_same_model(trees):
    specs = {tree_id: TreeSpec(tree_id, root, _here) for tree_id, root in trees.items()}
    document = TreeDocument("t.yaml", 1, next(iter(trees)), None, [], specs)
    again, problems = parse_yaml(dump_yaml(document), "t.yaml")
    assert problems == []
    assert again == document


@pytest.mark.parametrize("text", ["\xa0", "x\xa0", " lead", "yes", "3", "a: b", "two\nlines", "é"])
def test_a_string_on_an_any_typed_port_survives_its_text_form(text):
    """Found by the YAML -> XML -> YAML property: PyYAML writes a non-breaking space bare, and it read back as ''."""
    assert literal_from_text(literal_text(text, object), object) == text
