"""The tree as BT.CPP's Groot2 publisher describes it: node uids, status order and the FULLTREE XML.

BT.CPP numbers nodes as it creates them, depth first from 1, a SubTree's nodes right after the
SubTree node (``Tree::getUID``); its ``tree.subtrees`` lists the main tree, then each SubTree
instance as it is met, and the STATUS payload walks subtree after subtree, each in creation order
(so uids are not ascending when there are subtrees). The XML is ``WriteTreeToXML(tree, true, true)``:
one ``<BehaviorTree ID _fullpath>`` per instance, every node with ``name`` (SubTree: ``ID`` and
``_fullpath``), ``_uid``, its input ports as written plus the defaults of those not written, output
ports, pre-conditions; then the ``<TreeNodesModel>`` of every registered node, built-ins included.
The node model is :func:`chaser_bt.tree.node_model.node_model_xml`'s, literals become text as
:func:`chaser_bt.tree.conversion.textual_document` writes them (so a YAML tree reads as its XML twin),
attributes are escaped by :mod:`chaser_bt.tree.xml_format`; only the tinyxml2 layout (4-space indent,
no declaration) is here.

A node with pre-conditions is one BT.CPP node but two py_trees behaviours here (the
:class:`~chaser_bt.tree.preconditions.Preconditions` wrapper around it): the wrapper carries the uid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import py_trees

from chaser_bt.tree import MissionTree, Registry, default_registry
from chaser_bt.tree.composites import ReactiveFallback, ReactiveSequence
from chaser_bt.tree.conversion import textual_document
from chaser_bt.tree.model import PRECONDITIONS, SUBTREE_ID, NodeSpec, TreeDocument, TreeSpec
from chaser_bt.tree.node_model import default_text
from chaser_bt.tree.node_model import node_model_xml
from chaser_bt.tree.ports import LiteralError, is_reference_text, literal_text
from chaser_bt.tree.registry import NodeKind
from chaser_bt.tree.validation import ResolvedNode
from chaser_bt.tree.xml_format import FORMAT_VERSION
from chaser_bt.tree.xml_format import attributes_text as xml_attributes

__all__ = ["MonitoredNode", "MonitoredTree", "describe_tree"]

_INDENT = "    "  # tinyxml2's XMLPrinter


@dataclass(frozen=True)
class MonitoredNode:
    """One BT.CPP node: its uid, the behaviour whose status it shows, and its parent's uid (None: root).

    ``inner`` is the node itself under a pre-conditions wrapper (else ``behaviour``): ticked only when
    the node really runs. ``control``: a control node or decorator (BT.CPP sets these RUNNING as
    their tick starts). ``resets_finished``: a reactive control node or a decorator (while one runs,
    BT.CPP resets every child of it that is not running).
    """

    uid: int
    behaviour: py_trees.behaviour.Behaviour
    parent: int | None
    inner: py_trees.behaviour.Behaviour
    control: bool
    resets_finished: bool = False


@dataclass(frozen=True)
class MonitoredTree:
    """The FULLTREE XML, the nodes in STATUS order, the main tree's ID and the blackboard scopes by BT.CPP's names.

    ``scopes``: subtree name (the main tree's ID, else the instance path) -> {entry: absolute key},
    an entry for every blackboard key a port is wired to, in the scope that owns it.
    """

    xml: str
    nodes: tuple[MonitoredNode, ...]
    main: str = ""
    scopes: dict[str, dict[str, str]] = field(default_factory=dict)


@dataclass
class _Element:
    tag: str
    attrs: dict[str, str]
    children: list[_Element] = field(default_factory=list)


@dataclass
class _Subtree:
    tree_id: str
    instance_name: str
    namespace: str
    element: _Element
    nodes: list[MonitoredNode] = field(default_factory=list)


def describe_tree(tree: MissionTree, registry: Registry | None = None) -> MonitoredTree:
    """Number ``tree``'s nodes as BT.CPP would and write its FULLTREE XML.

    ``registry`` (default: :func:`default_registry`) is what the TreeNodesModel lists.

    Raises:
        ValueError: the tree was not built by :func:`chaser_bt.tree.load_tree` (no resolved nodes).
    """
    if tree.resolved is None:
        raise ValueError("the tree has no resolved nodes: load it with chaser_bt.tree.load_tree")
    registry = registry if registry is not None else default_registry()
    builder = _Builder(_textual_specs(tree.name, tree.resolved, registry))
    builder.subtree(tree.name, "", tree.resolved, tree.root, None)
    lines = [f"<root{xml_attributes({'BTCPP_format': FORMAT_VERSION})}>"]
    for sub in builder.subtrees:
        _write(sub.element, 1, lines)
    lines += _model_lines(registry)
    lines.append("</root>")
    nodes = tuple(node for sub in builder.subtrees for node in sub.nodes)
    return MonitoredTree("\n".join(lines) + "\n", nodes, tree.name, _scopes(builder.subtrees, builder.keys))


def _scopes(subtrees: list[_Subtree], keys: set[str]) -> dict[str, dict[str, str]]:
    """Each wired key in the deepest subtree scope that holds it, named as in that scope."""
    scopes: dict[str, dict[str, str]] = {sub.instance_name or sub.tree_id: {} for sub in subtrees}
    for key in sorted(keys):
        owner = max((sub for sub in subtrees if sub.namespace == "/" or key.startswith(sub.namespace + "/")),
                    key=lambda sub: len(sub.namespace), default=None)
        if owner is not None:
            scopes[owner.instance_name or owner.tree_id][key[len(owner.namespace.rstrip("/")) + 1:]] = key
    return scopes


def _textual_specs(main: str, root: ResolvedNode, registry: Registry) -> dict[int, NodeSpec]:
    """id(node as written) -> the same node with its literals as BT.CPP attribute text.

    :func:`~chaser_bt.tree.conversion.textual_document` does the typing (a SubTree's literal by the
    ports that read it), on a document of the trees ``root`` instantiates.
    """
    trees: dict[str, TreeSpec] = {}
    pending = [(main, root)]
    while pending:
        tree_id, top = pending.pop()
        assert top.spec is not None
        if tree_id in trees:
            continue
        trees[tree_id] = TreeSpec(tree_id, top.spec, top.spec.location)
        stack = [top]
        while stack:
            node = stack.pop()
            if node.spec is not None and node.spec.subtree is not None and node.children:
                pending.append((node.spec.subtree.tree_id, node.children[0]))
            else:
                stack.extend(node.children)
    textual = textual_document(TreeDocument(source="", trees=trees), registry)
    return {id(a): b for tree_id, spec in trees.items() for a, b in zip(_walk(spec.root), _walk(textual.trees[tree_id].root))}


def _walk(node: NodeSpec | None) -> list[NodeSpec]:
    out, stack = [], [node] if node is not None else []
    while stack:
        current = stack.pop()
        out.append(current)
        stack.extend(reversed(current.children))
    return out


class _Builder:
    def __init__(self, texts: dict[int, NodeSpec]) -> None:
        self.subtrees: list[_Subtree] = []
        self.uid = 0
        self.texts = texts
        self.keys: set[str] = set()

    def subtree(
        self, tree_id: str, instance: str, resolved: ResolvedNode, behaviour: py_trees.behaviour.Behaviour,
        parent: int | None,
    ) -> None:
        element = _Element("BehaviorTree", {"ID": tree_id, "_fullpath": instance})
        sub = _Subtree(tree_id, instance, resolved.namespace, element)
        self.subtrees.append(sub)
        self.node(resolved, behaviour, sub, sub.element, parent, instance + "/" if instance else "")

    def node(
        self, resolved: ResolvedNode, behaviour: py_trees.behaviour.Behaviour, sub: _Subtree,
        parent_element: _Element, parent: int | None, prefix: str,
    ) -> None:
        self.uid += 1
        uid = self.uid
        inner = behaviour.decorated if resolved.conditions else behaviour
        control = resolved.node_type.kind in (NodeKind.CONTROL, NodeKind.DECORATOR)
        resets = resolved.node_type.kind is NodeKind.DECORATOR or issubclass(
            resolved.node_type.cls, (ReactiveSequence, ReactiveFallback))
        sub.nodes.append(MonitoredNode(uid, behaviour, parent, inner, control, resets))
        self.keys.update(resolved.remappings.values())
        spec = resolved.spec
        assert spec is not None
        if spec.node_id == SUBTREE_ID and spec.subtree is not None:
            tree_id = spec.subtree.tree_id
            name = spec.name or tree_id
            path = prefix + name + (f"::{uid}" if name == tree_id else "")
            attrs = {"ID": tree_id, "_fullpath": path, "_uid": str(uid)}
        else:
            attrs = {"name": resolved.name, "_uid": str(uid)}
        attrs.update(_ports(resolved, self.texts.get(id(spec), spec)))
        attrs.update({kind: str(spec.conditions[kind].value) for kind in PRECONDITIONS if kind in spec.conditions})
        element = _Element(spec.node_id, attrs)
        parent_element.children.append(element)
        if spec.node_id == SUBTREE_ID and spec.subtree is not None:
            if resolved.children:
                instance = sub.instance_name + ("/" if sub.instance_name else "")
                instance += spec.name if spec.name else f"{spec.subtree.tree_id}::{uid}"
                self.subtree(spec.subtree.tree_id, instance, resolved.children[0], inner.decorated, uid)
            return
        for child_resolved, child in zip(resolved.children, inner.children, strict=True):
            self.node(child_resolved, child, sub, element, uid, prefix)


def _ports(resolved: ResolvedNode, textual: NodeSpec) -> dict[str, str]:
    """BT.CPP's ``config().input_ports`` then ``output_ports``: as written (XML text as it is, other
    literals as ``textual`` writes them), then the defaults of the rest."""
    spec = resolved.spec
    assert spec is not None
    node_type = resolved.node_type
    out: dict[str, str] = {}
    key_names = getattr(node_type.cls, "KEY_NAME_PORTS", ())  # entry names (SetBlackboard's output_key): text as written
    for port, arg in spec.ports.items():
        if arg.from_text or is_reference_text(arg.value) or port in key_names:
            out[port] = str(arg.value)
            continue
        text = textual.ports[port]
        if text.from_text:
            out[port] = str(text.value)
            continue
        declaration = node_type.port(port)
        try:
            out[port] = literal_text(arg.value, declaration.data_type if declaration is not None else object)
        except LiteralError:
            out[port] = str(arg.value)
    if spec.node_id == SUBTREE_ID:
        return out
    for direction, ports in ((0, node_type.input_ports), (1, node_type.output_ports)):
        for port, declaration in ports.items():
            default = default_text(declaration)
            if port in out or not default:  # BT.CPP adds only non-empty default strings
                continue
            if direction == 0 or is_reference_text(default):
                out[port] = default
    return out


def _write(element: _Element, depth: int, lines: list[str]) -> None:
    indent = _INDENT * depth
    attrs = xml_attributes(element.attrs)
    if not element.children:
        lines.append(f"{indent}<{element.tag}{attrs}/>")
        return
    lines.append(f"{indent}<{element.tag}{attrs}>")
    for child in element.children:
        _write(child, depth + 1, lines)
    lines.append(f"{indent}</{element.tag}>")


def _model_lines(registry: Registry) -> list[str]:
    """The ``<TreeNodesModel>`` block of :func:`node_model_xml` (built-ins included), re-indented as tinyxml2 does."""
    lines = node_model_xml(registry, include_builtin=True).splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip() == "<TreeNodesModel>")
    end = next(i for i, line in enumerate(lines) if line.strip() == "</TreeNodesModel>")
    out = []
    for line in lines[start:end + 1]:
        stripped = line.lstrip(" ")
        depth = (len(line) - len(stripped)) // 2  # node_model_xml indents by two spaces
        out.append(_INDENT * depth + stripped)
    return out
