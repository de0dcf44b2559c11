"""Writes the generated conformance trees: BT.CPP 4.10's scripting, types and conversions, case by case.

    .venv/bin/python tests/tree/conformance/generate.py          # (re)write trees/2NN_gen_*.xml
    .venv/bin/python tests/tree/conformance/generate.py --check  # exit 1 when they are not current

Each case is one small tree (mostly a single ``Script``) whose trace shows a value, a type (``..``
writes an int as ``3``, a double as ``3.000000``) or an exception. The cases cover every script
operator against the value types (int, double, bool, text, numeric-looking text), assignments
into entries of each type, ports reading blackboard values of another type, literals, the
blackboard's type locking when a tree loads, and when ports are read. Their goldens are recorded
from BehaviorTree.CPP 4.10.0 by ``regenerate.sh`` like every other tree; ``test_tree_conformance.py``
compares chaser-bt's traces with them and says, for the few that differ, why.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

HERE = Path(__file__).parent
TREES = HERE / "trees"
FIRST_NUMBER = 201
PATTERN = "*_gen_*.xml"


@dataclass(frozen=True)
class Case:
    name: str
    what: str
    body: str
    bb: str = "r"
    ticks: int = 1
    extra: str = ""


def script(code: str) -> str:
    return f"<Script code={quoteattr(code)}/>"


def seq(*children: str) -> str:
    return "<Sequence>" + "".join(children) + "</Sequence>"


def leaf(name: str = "A", results: str = "S") -> str:
    return f'<Scripted name="{name}" results="{results}"/>'


#: Operands by kind: int, double, whole double, bool (``true`` is the double 1), text, numeric text,
#: the text 'true', the text 'false', text starting with a number, zero, the empty text.
OPERANDS = {
    "int": "3", "double": "2.5", "whole": "2.0", "bool": "true", "text": "'ab'", "numtext": "'3'",
    "truetext": "'true'", "falsetext": "'false'", "numprefix": "'3abc'", "zero": "0", "empty": "''",
}
OPERATOR_NAMES = {
    "+": "plus", "-": "minus", "*": "times", "/": "div", "..": "concat", "&": "bitand", "|": "bitor",
    "^": "bitxor", "&&": "and", "||": "or", "==": "eq", "!=": "ne", "<": "lt", "<=": "le", ">": "gt", ">=": "ge",
}
#: Which operand pairs each binary operator meets (every operator meets several type pairs; the
#: arithmetic and comparison paths, where the types matter most, meet the most).
PAIRS = {
    "+": ["int int", "int double", "text text", "numtext numtext", "text int", "numtext int", "truetext bool"],
    "-": ["int int", "double double", "text text", "numtext int"],
    "*": ["int double", "numtext int"],
    "/": ["int int", "int zero", "zero zero", "double int"],
    "..": ["int int", "int text", "double text", "text double", "whole text", "bool text", "text text",
           "numtext double", "truetext int"],
    "&": ["int int", "int whole", "int double", "int bool"],
    "|": ["int int"],
    "^": ["int text"],
    "&&": ["bool bool", "int int", "zero int", "double bool", "truetext bool"],
    "||": ["zero zero"],
    "==": ["int int", "int double", "whole int", "numtext int", "int numtext", "truetext int", "truetext bool",
           "falsetext zero", "text text", "text numtext", "text int", "numprefix int", "empty zero"],
    "!=": ["int int", "text text", "truetext bool"],
    "<": ["double int", "text text", "numtext int", "truetext int", "text int"],
    "<=": ["int whole"],
    ">": ["numtext numtext"],
    ">=": ["double numtext"],
}


def operator_cases() -> list[Case]:
    cases = []
    for op, pairs in PAIRS.items():
        for pair in pairs:
            a, b = pair.split()
            code = f"r := {OPERANDS[a]} {op} {OPERANDS[b]}"
            cases.append(Case(f"op_{OPERATOR_NAMES[op]}_{a}_{b}", code, script(code)))
    for op, name, kinds in (("-", "neg", ["int", "double", "text", "zero"]), ("!", "not", ["int", "double", "text"]),
                            ("~", "complement", ["int", "double", "text"])):
        for kind in kinds:
            code = f"r := {op}{OPERANDS[kind]}"
            cases.append(Case(f"unary_{name}_{kind}", code, script(code)))
    for kind in ("int", "zero", "numtext", "text", "empty", "truetext"):
        code = f"r := {OPERANDS[kind]} ? 'yes' : 'no'"
        cases.append(Case(f"ternary_{kind}", code, script(code)))
    # A bool on the blackboard is an integer that prints true/false (LoopBool writes one).
    for op, other in (("+", "int"), ("..", "text"), ("==", "int"), ("==", "truetext"), ("&&", "int")):
        code = f"r := b {op} {OPERANDS[other]}"
        body = f'<LoopBool queue="true" value="{{b}}">{script(code)}</LoopBool>'
        cases.append(Case(f"bbbool_{OPERATOR_NAMES[op]}_{other}", f"b is the bool true; {code}", body, "r,b"))
    return cases


#: Entries of each type, as a script creates them.
ENTRIES = {"int": "x := 3", "double": "x := 2.5", "text": "x := 'ab'", "computed": "x := 1 + 1"}
ASSIGNMENTS = [
    ("int", "=", "double"), ("int", "=", "whole"), ("int", "=", "numtext"), ("int", "=", "truetext"),
    ("int", ":=", "double"), ("double", "=", "int"), ("double", "=", "numprefix"), ("text", "=", "int"),
    ("text", ":=", "numtext"), ("computed", "=", "int"), ("int", "+=", "int"), ("int", "+=", "double"),
    ("double", "+=", "int"), ("text", "+=", "text"), ("text", "+=", "int"), ("int", "+=", "text"),
    ("int", "-=", "whole"), ("int", "-=", "double"), ("double", "*=", "double"), ("int", "*=", "int"),
    ("int", "/=", "int"), ("int", "/=", "whole"), ("int", "/=", "zero"), ("computed", "/=", "int"),
]
ASSIGNMENT_NAMES = {"=": "set", ":=": "create", "+=": "add", "-=": "sub", "*=": "mul", "/=": "div"}


def assignment_cases() -> list[Case]:
    cases = []
    for entry, op, value in ASSIGNMENTS:
        code = f"{ENTRIES[entry]}; x {op} {OPERANDS[value]}; r := x .. ''"
        cases.append(Case(f"assign_{entry}_{ASSIGNMENT_NAMES[op]}_{value}", code, script(code), "x,r"))
    return cases


REPEAT = '<Repeat num_cycles="{n}">' + leaf() + "</Repeat>"


def declared_cases() -> list[Case]:
    """An entry a port wires to ``{key}`` exists from the moment the tree loads, typed by that port."""
    rs = "r := v .. ''"
    return [
        Case("declared_set_before_write", "n = 2 before the Repeat whose num_cycles is {n}",
             seq(script("n = 2"), REPEAT), "n", 3),
        Case("declared_set_text_converts", "n = '2': the int port's converter makes it the int 2",
             seq(script("n = '2'; r := n .. ''"), REPEAT), "n,r", 2),
        Case("declared_set_fraction_then_read", "n = 2.5 is stored; the int port cannot read it",
             seq(script("n = 2.5"), REPEAT), "n"),
        Case("declared_output_int", "v = 7 before LoopInt writes v",
             seq(script(f"v = 7; {rs}"), f'<LoopInt queue="1" value="{{v}}">{leaf()}</LoopInt>'), "v,r"),
        Case("declared_output_double_text", "v = '7' into LoopDouble's value: the double 7",
             seq(script(f"v = '7'; {rs}"), f'<LoopDouble queue="1" value="{{v}}">{leaf()}</LoopDouble>'), "v,r"),
        Case("declared_output_bool_text", "v = 'true' into LoopBool's value: the bool true",
             seq(script(f"v = 'true'; {rs}"), f'<LoopBool queue="1" value="{{v}}">{leaf()}</LoopBool>'), "v,r"),
        Case("declared_output_string_int_then_write", "v = 7 into LoopString's value, then the loop writes text",
             seq(script(f"v = 7; {rs}"), f'<LoopString queue="1" value="{{v}}">{leaf()}</LoopString>'), "v,r"),
        Case("declared_double_keeps_int", "LoopDouble's 1.0 into an entry holding the int 3 stays an int",
             seq(script("v = 3"), f'<LoopDouble queue="1" value="{{v}}">{script(rs)}</LoopDouble>'), "v,r"),
        Case("declared_int_then_text", "n := 2; n = '5' with the int port's converter: the int 5",
             seq(script("n := 2; n = '5'; r := n .. ''"), REPEAT), "n,r"),
        Case("undeclared_int_then_text", "the same without a port: StringToDouble, the double 5",
             script("n := 2; n = '5'; r := n .. ''"), "n,r"),
        Case("declared_read_before_write", "reading a declared entry before anything writes it",
             seq(script("r := n"), REPEAT), "n,r"),
        Case("declared_add_before_write", "n += 1 on a declared entry with no value", seq(script("n += 1"), REPEAT), "n"),
        Case("declared_text_port_int", "n = 1, then a text port reads it (std::to_string)",
             seq(script("n = 1"), '<Scripted name="A" results="{n}"/>'), "n"),
        Case("declared_unset_then_set", "UnsetBlackboard removes a declared entry; then n = 2",
             seq('<UnsetBlackboard key="n"/>', script("n = 2"), REPEAT), "n"),
    ]


#: Values a Script gives an entry that a typed port then reads.
PORT_VALUES = {
    "int": "3", "whole": "2.0", "fraction": "2.5", "text": "'2'", "fractext": "'2.5'", "prefixtext": "'2abc'",
    "truetext": "'true'", "bool": "true", "negative": "-1",
}


def port_cases() -> list[Case]:
    cases = []

    def add(node: str, value: str, body: str, ticks: int, bb: str = "n") -> None:
        code = f"n := {PORT_VALUES[value]}"
        cases.append(Case(f"port_{node}_{value}", f"{code}, read by {node}", seq(script(code), body), bb, ticks))

    for value in ("whole", "fraction", "text", "fractext", "prefixtext", "truetext", "bool", "negative"):
        add("repeat", value, REPEAT, 3)
    for value in ("whole", "text"):
        add("retry", value, '<RetryUntilSuccessful num_attempts="{n}">' + leaf("A", "F") + "</RetryUntilSuccessful>", 3)
    for value in ("whole", "text", "negative"):
        add("timeout", value, '<Timeout msec="{n}">' + leaf() + "</Timeout>", 1)
    for value in ("whole", "text"):
        add("sleep", value, '<Sleep msec="{n}"/>', 1)
    for value in ("int", "fraction", "text", "truetext"):
        add("runonce", value, '<RunOnce then_skip="{n}">' + leaf() + "</RunOnce>", 2)
    for value in ("int", "whole", "text"):
        add("switch", value, '<Switch2 variable="{n}" case_1="2" case_2="3">' + leaf("A") + leaf("B") + leaf("C")
            + "</Switch2>", 1)
    for value in ("whole", "text", "bool"):
        add("parallel", value, '<Parallel success_count="{n}">' + leaf("A") + leaf("B") + leaf("C") + "</Parallel>", 1)
    # Loops over a blackboard entry: a list, or text BT.CPP splits on ';'.
    for loop, queue in (("LoopInt", "'4;5'"), ("LoopDouble", "'1.5;2'"), ("LoopString", "'a;b'"),
                        ("LoopBool", "'true;0'"), ("LoopInt", "''"), ("LoopInt", "4")):
        name = {"'4;5'": "text", "'1.5;2'": "text", "'a;b'": "text", "'true;0'": "text", "''": "empty", "4": "int"}[queue]
        append = script("r := r .. v .. ' '")
        body = seq(script(f"q := {queue}; r := ''"), f'<{loop} queue="{{q}}" value="{{v}}">{append}</{loop}>')
        cases.append(Case(f"loop_{loop[4:].lower()}_queue_{name}", f"{loop} over q := {queue}", body, "r,q", 4))
    # Literals: BT.CPP reads the number at the start of the text; chaser-bt needs the whole text to be one.
    for name, text in (("whole", "2.0"), ("fraction", "2.5"), ("prefix", "2abc"), ("hex", "0x2"), ("plus", "+2"),
                       ("space", " 2")):
        cases.append(Case(f"literal_repeat_{name}", f'num_cycles="{text}"',
                          f'<Repeat num_cycles="{text}">{leaf()}</Repeat>', "", 3))
    for name, text in (("TRUE", "TRUE"), ("one", "1"), ("yes", "yes")):
        cases.append(Case(f"literal_runonce_{name}", f'then_skip="{text}"',
                          f'<RunOnce then_skip="{text}">{leaf()}</RunOnce>', "", 2))
    return cases


SWITCH_K = '<Switch2 variable="{k}" case_1="1" case_2="2">' + leaf("B") + leaf("C") + leaf("D") + "</Switch2>"


def lock_cases() -> list[Case]:
    """The first port wired to an entry gives its type; BT.CPP refuses another type later."""
    sub = '\n  <BehaviorTree ID="Sub">{}</BehaviorTree>'
    return [
        Case("lock_int_output_then_text_input", "LoopInt's value (int) then Switch2's variable (std::string)",
             seq(f'<LoopInt queue="1" value="{{k}}">{leaf()}</LoopInt>', SWITCH_K), "k"),
        Case("lock_text_input_then_int_output", "Switch2's variable (std::string) then LoopInt's value (int)",
             seq(SWITCH_K, f'<LoopInt queue="1" value="{{k}}">{leaf()}</LoopInt>'), "k"),
        Case("lock_int_then_unsigned", "Repeat's num_cycles (int) then Timeout's msec (unsigned)",
             seq(script("n := 1"), REPEAT, f'<Timeout msec="{{n}}">{leaf()}</Timeout>'), "n"),
        Case("lock_int_then_double", "LoopInt's value then LoopDouble's value",
             seq(f'<LoopInt queue="1" value="{{k}}">{leaf()}</LoopInt>',
                 f'<LoopDouble queue="1" value="{{k}}">{leaf()}</LoopDouble>'), "k"),
        Case("lock_int_then_int", "Repeat's num_cycles then RetryUntilSuccessful's num_attempts (both int)",
             seq(script("k := 1"), '<Repeat num_cycles="{k}">' + leaf() + "</Repeat>",
                 '<RetryUntilSuccessful num_attempts="{k}">' + leaf("B") + "</RetryUntilSuccessful>"), "k"),
        Case("lock_int_then_leaf_text", "LoopInt's value then a leaf's text port",
             seq(f'<LoopInt queue="1" value="{{k}}">{leaf()}</LoopInt>', '<Scripted name="B" results="{k}"/>'), "k"),
        Case("lock_status_then_text", "Precondition's else (NodeStatus) then a text port",
             seq(f'<Precondition if="true" else="{{k}}">{leaf()}</Precondition>', '<Scripted name="B" results="{k}"/>'),
             "k"),
        Case("lock_untyped_first", "LoopInt's queue (any type) then Repeat's num_cycles",
             seq(script("k := 1"), f'<LoopInt queue="{{k}}" value="{{v}}">{leaf()}</LoopInt>',
                 '<Repeat num_cycles="{k}">' + leaf("B") + "</Repeat>"), "k"),
        Case("lock_through_subtree_remap", "LoopInt's value, then a subtree's Switch2 on the remapped entry",
             seq(f'<LoopInt queue="1" value="{{k}}">{leaf()}</LoopInt>', '<SubTree ID="Sub" k="{k}"/>'), "k",
             extra=sub.format(SWITCH_K)),
        Case("lock_subtree_literal_unsigned", "SubTree n=\"3\" (an int entry) read by Timeout's msec (unsigned)",
             '<SubTree ID="Sub" n="3"/>', "", extra=sub.format(f'<Timeout msec="{{n}}">{leaf()}</Timeout>')),
        Case("lock_subtree_literal_int", "SubTree n=\"2\" read by Repeat's num_cycles (int)",
             '<SubTree ID="Sub" n="2"/>', "", 3, extra=sub.format(REPEAT)),
        Case("lock_subtree_literal_double", "SubTree n=\"2.0\" (a double entry) read by Repeat's num_cycles",
             '<SubTree ID="Sub" n="2.0"/>', "", 3, extra=sub.format(REPEAT)),
        Case("lock_subtree_literal_text_queue", "SubTree q=\"2;3\" (text) read by LoopInt's queue",
             '<SubTree ID="Sub" q="2;3"/>', "", 3,
             extra=sub.format(f'<LoopInt queue="{{q}}" value="{{v}}">{leaf()}</LoopInt>')),
        Case("subtree_literal_types", "how SubTree literals arrive in a script: int, double, text",
             '<SubTree ID="Sub" a="3" b="2.5" c="true" d="0x1F" e="1e3" f="yes" g="-4"/>', "r",
             extra=sub.format(script("@r := a .. '|' .. b .. '|' .. c .. '|' .. d .. '|' .. e .. '|' .. f .. '|' .. g"))),
    ]


def timing_cases() -> list[Case]:
    """When ports are read: a count on every tick (Repeat; Retry after each attempt too), a timeout once."""
    return [
        Case("read_repeat_count_lowered", "the child lowers Repeat's count while it runs",
             seq(script("n := 5"), '<Repeat num_cycles="{n}">' + seq(leaf("A", "R,S"), script("n := 1")) + "</Repeat>"),
             "n", 4),
        Case("read_repeat_count_raised", "the running child raises Repeat's count: the next tick reads it",
             seq(script("n := 1"), '<Repeat num_cycles="{n}">' + seq(script("n := 3"), leaf("A", "R,S")) + "</Repeat>"),
             "n", 3),
        Case("read_retry_count_lowered", "the child lowers RetryUntilSuccessful's count",
             seq(script("n := 5"), '<RetryUntilSuccessful num_attempts="{n}">' + seq(script("n := 2"), leaf("A", "F"))
                 + "</RetryUntilSuccessful>"), "n", 5),
        Case("read_retry_count_after_attempt", "the count read again after each failed attempt",
             seq(script("n := 5; c := 0"), '<RetryUntilSuccessful num_attempts="{n}">'
                 + seq(script("c += 1; n := 1"), leaf("A", "R,F")) + "</RetryUntilSuccessful>"), "n,c", 5),
        Case("read_timeout_once", "Timeout reads msec when it starts, not again",
             seq(script("n := 100000"), '<Timeout msec="{n}">' + seq(script("n := 1"), leaf("A", "R")) + "</Timeout>"),
             "n", 3),
        Case("read_switch_every_tick", "Switch2 reads its variable on every tick",
             seq(script("v := 1"), '<Switch2 variable="{v}" case_1="1" case_2="2">' + seq(script("v := 2"), leaf("A", "R"))
                 + leaf("B", "R") + leaf("C") + "</Switch2>"), "v", 3),
        Case("read_runonce_then_skip", "RunOnce reads then_skip after its run",
             seq(script("t := false"), '<RunOnce then_skip="{t}">' + seq(script("t := true"), leaf()) + "</RunOnce>"),
             "t", 3),
        Case("read_loop_queue_once", "LoopInt converts text from the blackboard once per run",
             seq(script("q := '1;2;3'; r := ''"), '<LoopInt queue="{q}" value="{v}">' + script("r := r .. v; q := '9'")
                 + "</LoopInt>"), "r,q", 5),
    ]


def other_cases() -> list[Case]:
    model = ('\n  <BehaviorTree ID="Sub5"><Script code="out := v * 2"/></BehaviorTree>\n'
             '  <TreeNodesModel><SubTree ID="Sub5"><input_port name="v" default="{}"/></SubTree></TreeNodesModel>')
    cases = [
        Case("autoremap_ignores_model_default_key", "a model default {z} is not applied under _autoremap",
             seq(script("z := 3; v := 1"), '<SubTree ID="Sub5" _autoremap="true"/>'), "z,v,out",
             extra=model.format("{z}")),
        Case("autoremap_ignores_model_default_literal", "a model default 7 is not applied under _autoremap",
             seq(script("v := 1"), '<SubTree ID="Sub5" _autoremap="true"/>'), "v,out", extra=model.format("7")),
        Case("concat_numbers_statement", "1 .. 2 is an empty value, harmless as a statement", script("1 .. 2"), ""),
        Case("concat_numbers_condition", "1 .. 2 as a condition", '<ScriptCondition code="1 .. 2"/>', ""),
        Case("enum_name_text_compares", "'RED' == 1: text names a scripting enum", script("r := 'RED' == 1")),
        Case("enum_concat", "an enum is a double: RED .. ''", script("r := RED .. ''")),
        Case("enum_name_text_assigned", "x = 'GREEN' into a number entry", script("x := 5; x = 'GREEN'; r := x .. ''"),
             "x,r"),
    ]
    for name, code in (("truetext", "'true'"), ("onetext", "'1'"), ("int2", "2"), ("double", "0.5")):
        cases.append(Case(f"truth_scriptcondition_{name}", f"ScriptCondition {code}",
                          f"<ScriptCondition code={quoteattr(code)}/>", ""))
    for name, code in (("truetext", "'true'"), ("int2", "2")):
        cases.append(Case(f"truth_precondition_{name}", f"Precondition if={code}",
                          f'<Precondition if={quoteattr(code)} else="FAILURE">{leaf()}</Precondition>', ""))
        cases.append(Case(f"truth_skipif_{name}", f"_skipIf={code}", f'<Scripted name="A" _skipIf={quoteattr(code)}/>', ""))
    return cases


def all_cases() -> list[Case]:
    return [*operator_cases(), *assignment_cases(), *declared_cases(), *port_cases(), *lock_cases(),
            *timing_cases(), *other_cases()]


def render(case: Case) -> str:
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f"<!-- conformance ticks={case.ticks} period_ms=0 bb={case.bb} -->\n"
        f"<!-- generated by generate.py: {case.what.replace('--', '- -')} -->\n"
        '<root BTCPP_format="4" main_tree_to_execute="Main">\n'
        '  <BehaviorTree ID="Main">\n'
        f"    {case.body}\n"
        f"  </BehaviorTree>{case.extra}\n"
        "</root>\n"
    )


def generated() -> dict[str, str]:
    """File name -> content of every generated tree."""
    cases = all_cases()
    names = [case.name for case in cases]
    assert len(set(names)) == len(names), "two generated cases share a name"
    return {f"{FIRST_NUMBER + i}_gen_{case.name}.xml": render(case) for i, case in enumerate(cases)}


def main(argv: list[str]) -> int:
    wanted = generated()
    present = {path.name: path.read_text(encoding="utf-8") for path in TREES.glob(PATTERN)}
    if "--check" in argv:
        if present != wanted:
            print("generated trees are not current: run tests/tree/conformance/generate.py", file=sys.stderr)
            return 1
        return 0
    for name in present.keys() - wanted.keys():
        (TREES / name).unlink()
    for name, text in wanted.items():
        if present.get(name) != text:
            (TREES / name).write_text(text, encoding="utf-8")
    print(f"{len(wanted)} generated trees in {TREES}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
