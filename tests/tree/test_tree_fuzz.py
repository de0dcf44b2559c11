"""Fuzzing the XML and YAML loaders: whatever the input, the only exception is our own TreeError.

Four tests x 2,500 generated inputs = 10,000: arbitrary text in each format's alphabet, and
mutations (characters inserted, deleted, replaced; lines duplicated or dropped) of valid trees
that exercise every part of each parser.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from chaser_bt.tree import Registry, TreeError, load_tree_text

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = 2500

XML_SEED = """<?xml version="1.0"?>
<root BTCPP_format="4" main_tree_to_execute="T" mission_inputs="alt;ok">
  <include path="missing.xml"/>
  <BehaviorTree ID="T">
    <ReactiveSequence name="guard">
      <Probe _while="ok &amp;&amp; alt &gt; 3"/>
      <Repeat num_cycles="2"><Target altitude_m="{alt}" offset_m="1;2;3" mode="RTL" reached_m="{r}"/></Repeat>
      <SubTree ID="Sub" _autoremap="true" x="4"/>
      <Sequence><Action ID="SetBlackboard" value="[1, 2]" output_key="k"/></Sequence>
    </ReactiveSequence>
  </BehaviorTree>
  <BehaviorTree ID="Sub"><Parallel success_count="-1"><Wait duration_s="{x}"/><AlwaysSuccess/></Parallel></BehaviorTree>
</root>
"""

YAML_SEED = """version: 1
main: T
inputs: [alt, ok]
includes: [missing.yaml]
trees:
  T:
    ReactiveSequence:
      name: guard
      children:
        - Probe: {_while: "ok && alt > 3"}
        - Repeat: {num_cycles: 2, child: {Target: {altitude_m: "{alt}", offset_m: [1, 2, 3], mode: RTL, reached_m: "{r}"}}}
        - SubTree: {ID: Sub, _autoremap: true, x: 4}
        - Sequence: {children: [SetBlackboard: {value: [1, 2], output_key: k}]}
  Sub:
    Parallel:
      success_count: -1
      children: [Wait: {duration_s: "{x}"}, AlwaysSuccess]
"""


def _mutations(seed: str, alphabet: str) -> st.SearchStrategy[str]:
    chars = st.sampled_from(alphabet)

    @st.composite
    def mutate(draw) -> str:
        text = seed
        for _ in range(draw(st.integers(1, 6))):
            kind = draw(st.sampled_from(["insert", "delete", "replace", "dup_line", "drop_line"]))
            i = draw(st.integers(0, max(len(text) - 1, 0)))
            if kind == "insert":
                text = text[:i] + draw(st.text(chars, min_size=1, max_size=4)) + text[i:]
            elif kind == "delete":
                text = text[:i] + text[i + draw(st.integers(1, 8)):]
            elif kind == "replace":
                text = text[:i] + draw(chars) + text[i + 1:]
            else:
                lines = text.splitlines(keepends=True)
                j = draw(st.integers(0, len(lines) - 1))
                lines[j:j + 1] = [lines[j]] * (2 if kind == "dup_line" else 0)
                text = "".join(lines)
        return text

    return mutate()


XML_ALPHABET = "<>/=\"'&;{}!?[]-_ abcTRSp0123456789\n\t\x00é"
YAML_ALPHABET = ":-{}[],'\"&*!|>#%@` abcTRSp0123456789\n\t\x00é"

_settings = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck))


def _load(text: str, fmt: str, registry: Registry, tmp_path: Path) -> None:
    try:
        load_tree_text(text, f"fuzz.{fmt}", registry, fmt=fmt, base_dir=tmp_path)
    except TreeError as e:
        assert e.problems, "a TreeError always lists its problems"
        for problem in e.problems:
            assert problem.line >= 1 and problem.column >= 1 and problem.message


@pytest.mark.slow
@_settings
@given(_mutations(XML_SEED, XML_ALPHABET))
def test_mutated_xml_raises_nothing_but_tree_error(registry, tmp_path, text):
    _load(text, "xml", registry, tmp_path)


@pytest.mark.slow
@_settings
@given(st.text(st.sampled_from(XML_ALPHABET), max_size=200) | st.text(max_size=100))
def test_arbitrary_xml_text_raises_nothing_but_tree_error(registry, tmp_path, text):
    _load(text, "xml", registry, tmp_path)


@pytest.mark.slow
@_settings
@given(_mutations(YAML_SEED, YAML_ALPHABET))
def test_mutated_yaml_raises_nothing_but_tree_error(registry, tmp_path, text):
    _load(text, "yaml", registry, tmp_path)


@pytest.mark.slow
@_settings
@given(st.text(st.sampled_from(YAML_ALPHABET), max_size=200) | st.text(max_size=100))
def test_arbitrary_yaml_text_raises_nothing_but_tree_error(registry, tmp_path, text):
    _load(text, "yaml", registry, tmp_path)


def test_the_seeds_themselves_only_miss_their_include(registry, tmp_path):
    for text, fmt in ((XML_SEED, "xml"), (YAML_SEED, "yaml")):
        with pytest.raises(TreeError) as raised:
            load_tree_text(text, f"seed.{fmt}", registry, fmt=fmt, base_dir=tmp_path)
        assert [p.message.split(" (")[0] for p in raised.value.problems] == [f"included file 'missing.{fmt}' not found"]


def test_nesting_built_to_exhaust_the_stack_is_a_problem_not_a_crash(registry, tmp_path):
    deep_xml = '<root BTCPP_format="4"><BehaviorTree ID="T">' + "<Inverter>" * 5000 + "<Probe/>" + "</Inverter>" * 5000 + "</BehaviorTree></root>"
    deep_yaml = "version: 1\ntrees:\n  T: " + "{Inverter: {child: " * 3000 + "Probe" + "}}" * 3000 + "\n"
    for text, fmt in ((deep_xml, "xml"), (deep_yaml, "yaml")):
        with pytest.raises(TreeError, match="nest"):
            load_tree_text(text, f"deep.{fmt}", registry, fmt=fmt, base_dir=tmp_path)
