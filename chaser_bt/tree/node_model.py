"""Groot2's node model (``<TreeNodesModel>``), generated from the same port declarations the validator uses.

BehaviorTree.CPP writes it with ``writeTreeNodesModelXML``: one ``<Action|Condition|Control|Decorator
ID=...>`` per node, an ``<input_port>``/``<output_port>`` per port with ``name``, ``type``, ``default``
and the description as text, and node metadata under ``<MetadataFields>``. Groot2 loads it to know
our nodes and their ports, so it opens and edits chaser-bt trees (DESIGN §4; STYLE: the model is
generated, never written by hand). Types are Python's names (``float``, ``list[float]``,
``FlightMode``); a default blackboard key is written as BT.CPP's default remapping ``{@key}``, and
a port's bounds (``[>= 0]``) follow its description, the only place the format has for them.
"""

from __future__ import annotations

from typing import Any

from chaser_bt.tree.ports import LiteralError, Port, literal_text, type_name
from chaser_bt.tree.registry import NodeType, Registry
from chaser_bt.tree.xml_format import FORMAT_VERSION

__all__ = ["BTCPP_BUILTIN_NODES", "node_model_xml", "default_text"]

#: Nodes BehaviorTree.CPP itself registers. Groot2 knows them already and BT.CPP's
#: ``writeTreeNodesModelXML`` leaves them out unless asked (``include_builtin``); so do we.
BTCPP_BUILTIN_NODES = frozenset({
    "AlwaysFailure", "AlwaysSuccess", "Script", "ScriptCondition", "SetBlackboard", "UnsetBlackboard", "Sleep",
    "Sequence", "SequenceWithMemory", "SequenceStar", "AsyncSequence", "ReactiveSequence", "Fallback", "AsyncFallback",
    "ReactiveFallback", "Parallel", "ParallelAll", "IfThenElse", "WhileDoElse", "TryCatch", "Precondition", "Switch2", "Switch3", "Switch4", "Switch5", "Switch6",
    "Inverter", "ForceSuccess", "ForceFailure", "Repeat", "RetryUntilSuccessful", "KeepRunningUntilFailure",
    "Timeout", "Delay", "RunOnce", "SubTree", "LoopInt", "LoopDouble", "LoopBool", "LoopString",
    "SkipUnlessUpdated", "WaitValueUpdate", "WasEntryUpdated",
})


def node_model_xml(registry: Registry, *, include_builtin: bool = False) -> str:
    """A ``<root BTCPP_format="4"><TreeNodesModel>`` document listing the nodes in ``registry``.

    BT.CPP's built-in nodes are left out unless ``include_builtin``, as ``writeTreeNodesModelXML`` does.
    """
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', f'<root BTCPP_format="{FORMAT_VERSION}">', "  <TreeNodesModel>"]
    for node_id in registry.ids():
        if include_builtin or node_id not in BTCPP_BUILTIN_NODES:
            lines += _node(registry.get(node_id))
    lines += ["  </TreeNodesModel>", "</root>"]
    return "\n".join(lines) + "\n"


def _node(node: NodeType) -> list[str]:
    tag = node.kind.value
    lines = [f"    <{tag} ID={_quote(node.node_id)}>"]
    for direction, ports in (("input_port", node.input_ports), ("output_port", node.output_ports)):
        for name, port in ports.items():
            attrs = f"name={_quote(name)} type={_quote(type_name(port.data_type))}"
            default = default_text(port)
            if default is not None:
                attrs += f" default={_quote(default)}"
            lines.append(f"      <{direction} {attrs}>{_escape(_description(port))}</{direction}>")
    if node.description:
        lines += [
            "      <MetadataFields>",
            f"        <Metadata description={_quote(node.description)}/>",
            "      </MetadataFields>",
        ]
    lines.append(f"    </{tag}>")
    return lines


def default_text(port: Any) -> str | None:
    """A port's default as model text: its default remapping (``{key}``, ``{@key}``) or its default value; None: none."""
    if isinstance(port, Port) and port.default_key is not None:
        key = port.default_key
        return "{@" + key[1:] + "}" if key.startswith("/") else "{" + key + "}"
    if port.has_default:
        try:
            return literal_text(port.default_value, port.data_type)
        except LiteralError:
            return str(port.default_value)
    return None


def _description(port: Any) -> str:
    """The port's description, its bounds appended (``[>= 0]``): Groot2 shows the text, BT.CPP has no field for them."""
    text = port.description or ""
    if isinstance(port, Port) and port.constraint:
        text = f"{text} [{port.constraint}]" if text else f"[{port.constraint}]"
    return text


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def _quote(text: str) -> str:
    return '"' + _escape(text).replace('"', "&quot;").replace("\n", "&#10;") + '"'
