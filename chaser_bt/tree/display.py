"""Unicode rendering of a mission tree with each node's port values, for ``chaser-bt show``.

The layout and symbols are py_trees' ``display.unicode_tree`` (``{-}`` sequence with memory,
``[-]`` reactive sequence, ``{o}``/``[o]`` the fallbacks, ``/_/`` parallel, ``-^-`` decorator,
``-->`` leaf); each line adds the node id when the instance is named differently, and its
ports as the tree gave them: literals as values, blackboard keys as ``{/key}``. Plain text,
no terminal escapes, so it reads the same in a log.
"""

from __future__ import annotations

import py_trees
from py_trees.common import Status

from chaser_bt.tree.control import Parallel
from chaser_bt.tree.loader import MissionTree
from chaser_bt.tree.ports import Port, type_name
from chaser_bt.tree.registry import Registry

__all__ = ["render_dot", "render_node_reference", "render_tree"]

_STATUS = {Status.SUCCESS: "✓", Status.FAILURE: "✕", Status.RUNNING: "*", Status.INVALID: "-"}


def render_tree(tree: MissionTree, show_status: bool = False) -> str:
    """The tree as indented lines; with ``show_status`` each node's last status and feedback too."""
    lines: list[str] = []
    _render(tree.root, tree, 0, show_status, lines)
    return "\n".join(lines) + "\n"


def _render(
    node: py_trees.behaviour.Behaviour, tree: MissionTree, depth: int, show_status: bool, lines: list[str]
) -> None:
    text = f"{'    ' * depth}{_symbol(node)} {node.name}"
    kind = type(node).__name__
    if kind != node.name:
        text += f" ({kind})"
    ports = tree.wiring.get(node.id, {})
    if ports:
        text += "  " + " ".join(f"{port}={value}" for port, value in ports.items())
    if show_status:
        text += f" [{_STATUS[node.status]}]"
        if node.feedback_message:
            text += f" -- {node.feedback_message}"
    lines.append(text)
    for child in node.children:
        _render(child, tree, depth + 1, show_status, lines)


def render_dot(tree: MissionTree) -> str:
    """The tree as Graphviz dot text (``dot -Tpng``), shaped as py_trees' ``display.dot_tree`` draws it.

    Composites are filled boxes, decorators ellipses, leaves plain text; each label holds the
    name, the node id when it differs, and the port values. Needs no pydot.
    """
    lines = [f"digraph {_dot_quote(tree.name)} {{", "  graph [ordering=out];", '  node [fontname="Helvetica", fontsize=10];']
    counter = iter(range(1 << 62))

    def visit(node: py_trees.behaviour.Behaviour) -> str:
        ident = f"n{next(counter)}"
        parts = [node.name] if type(node).__name__ == node.name else [node.name, f"({type(node).__name__})"]
        parts += [f"{port}={value}" for port, value in tree.wiring.get(node.id, {}).items()]
        if isinstance(node, py_trees.composites.Composite):
            shape = f'shape=box, style=filled, fillcolor="{_DOT_FILL.get(_symbol(node), "lightgrey")}"'
        elif isinstance(node, py_trees.decorators.Decorator):
            shape = 'shape=ellipse, style=filled, fillcolor="ghostwhite"'
        else:
            shape = "shape=plaintext"
        label = "\\n".join(_dot_escape(part) for part in parts)
        lines.append(f'  {ident} [label="{label}", {shape}];')
        for child in node.children:
            lines.append(f"  {ident} -> {visit(child)};")
        return ident

    visit(tree.root)
    lines.append("}")
    return "\n".join(lines) + "\n"


_DOT_FILL = {"{-}": "orange", "[-]": "orange", "{-m}": "orange", "{o}": "cyan", "[o]": "cyan", "/_/": "gold"}


def _dot_escape(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")


def _dot_quote(text: str) -> str:
    return '"' + _dot_escape(text) + '"'


def _symbol(node: py_trees.behaviour.Behaviour) -> str:
    symbol = getattr(node, "SYMBOL", None)
    if isinstance(symbol, str):
        return symbol
    if isinstance(node, (py_trees.composites.Parallel, Parallel)):
        return "/_/"
    if isinstance(node, py_trees.decorators.Decorator):
        return "-^-"
    if isinstance(node, py_trees.composites.Sequence):
        return "{-}" if node.memory else "[-]"
    if isinstance(node, py_trees.composites.Selector):
        return "{o}" if node.memory else "[o]"
    return "-->"


def render_node_reference(registry: Registry) -> str:
    """Every registered node with its kind, summary and ports, generated from their declarations."""
    blocks = []
    for node_id in sorted(registry.ids()):
        node = registry.get(node_id)
        lines = [f"{node_id} ({node.kind.name.lower()}): {node.description}"]
        for direction, ports in (("in ", node.input_ports), ("out", node.output_ports)):
            for name, port in ports.items():
                lines.append(f"    {direction} {name}: {type_name(port.data_type)}{_port_note(port)}  {port.description}")
        blocks.append("\n".join(lines))
    return "\n".join(blocks)


def _port_note(port) -> str:
    bounds = f" [{port.constraint}]" if isinstance(port, Port) and port.constraint else ""
    if isinstance(port, Port) and port.default_key:
        return f" = {{{port.default_key}}}{bounds}"
    if port.has_default:
        value = port.default_value
        return f" = {getattr(value, 'name', value)}{bounds}"
    return bounds if not port.required else f" (required){bounds}"

