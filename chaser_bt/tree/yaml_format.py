"""The YAML tree format: text -> :class:`TreeDocument` with a position on every value, and back.

::

    version: 1
    main: Patrol
    inputs: [cue]
    trees:
      Patrol:
        Sequence:
          children:
            - ArmAndTakeoff: {altitude_m: 20}
            - RTL

A node is a one-key mapping ``{NodeId: attributes}`` or a bare ``NodeId``. Attributes are
``name``, ``children`` (composites) or ``child`` (decorators), BT.CPP's pre-conditions
(``_while``, ``_skipIf``, ``_successIf``, ``_failureIf``) and the node's ports; a ``SubTree``
node takes ``ID``, ``_autoremap`` and the subtree's key remappings, as in BT.CPP. ``includes``
lists other tree files (YAML or XML) whose trees this file may instantiate.
The file is composed with ``yaml.compose`` (not ``safe_load``) so every node keeps its
start mark; scalars are then constructed with PyYAML's safe constructor, so values are typed
exactly as ``safe_load`` would type them. The full format is in ``docs/trees.md``.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import yaml

from chaser_bt.tree.errors import Problem
from chaser_bt.tree.model import (
    MAX_DEPTH,
    POSTCONDITIONS,
    PRECONDITIONS,
    SUBTREE_ID,
    Location,
    NodeSpec,
    PortArg,
    SubTreeRef,
    TreeDocument,
    TreeSpec,
)

__all__ = ["FORMAT_VERSION", "parse_yaml", "dump_yaml"]

FORMAT_VERSION = 1
_TOP_LEVEL = ("version", "main", "inputs", "includes", "trees")


def parse_yaml(text: str, source: str = "<string>") -> tuple[TreeDocument, list[Problem]]:
    """Parse tree YAML into the model, collecting every structural problem instead of stopping."""
    return _Parser(text, source).parse()


class _Parser:
    def __init__(self, text: str, source: str) -> None:
        self.text = text
        self.source = source
        self.problems: list[Problem] = []
        # PyYAML checks the characters as the loader is made: a NUL or other control character
        # raises ReaderError here, before parsing starts.
        try:
            self.loader: yaml.SafeLoader | None = yaml.SafeLoader(text)
        except yaml.reader.ReaderError as e:
            self.loader = None
            before = text[: e.position]
            line, column = before.count("\n") + 1, e.position - (before.rfind("\n") + 1) + 1
            self.problems.append(Problem(source, line, column, f"YAML error: {e.reason} (character {e.character!r})"))

    # ---- helpers

    def at(self, node: yaml.Node) -> Location:
        mark = node.start_mark
        return Location(self.source, mark.line + 1, mark.column + 1)

    def problem(self, where: Location | yaml.Node, message: str) -> None:
        loc = where if isinstance(where, Location) else self.at(where)
        self.problems.append(Problem(loc.file, loc.line, loc.column, message))

    def value(self, node: yaml.Node) -> tuple[bool, Any]:
        assert self.loader is not None
        try:
            return True, self.loader.construct_object(node, deep=True)
        except yaml.YAMLError as e:
            self.problem(node, f"cannot read value: {getattr(e, 'problem', None) or e}")
            return False, None
        except ValueError as e:  # an integer of thousands of digits: int() refuses it
            self.problem(node, f"cannot read value: {str(e).split(':')[0]}")
            return False, None
        except RecursionError:
            self.problem(node, "cannot read value: nested too deeply")
            return False, None

    def string(self, node: yaml.Node, what: str) -> str | None:
        if isinstance(node, yaml.ScalarNode) and node.tag == "tag:yaml.org,2002:str" and node.value:
            return str(node.value)
        self.problem(node, f"{what} must be a non-empty string, got {_describe(node)}")
        return None

    def pairs(self, node: yaml.MappingNode, what: str) -> Iterator[tuple[str, yaml.Node, yaml.Node]]:
        """Key/value pairs with string keys; duplicate keys are problems (YAML would keep the last)."""
        seen: dict[str, int] = {}
        for key_node, value_node in node.value:
            key = self.string(key_node, f"a key in {what}")
            if key is None:
                continue
            if key in seen:
                self.problem(key_node, f"duplicate key '{key}' in {what} (first at line {seen[key]})")
                continue
            seen[key] = key_node.start_mark.line + 1
            yield key, key_node, value_node

    # ---- document

    def parse(self) -> tuple[TreeDocument, list[Problem]]:
        document = TreeDocument(source=self.source)
        if self.loader is None:
            return document, self.problems
        try:
            root = self.loader.get_single_node()
        except RecursionError:
            self.problems.append(Problem(self.source, 1, 1, "YAML nested too deeply to read"))
            return document, self.problems
        except yaml.MarkedYAMLError as e:
            mark = e.problem_mark or e.context_mark
            line, column = (mark.line + 1, mark.column + 1) if mark else (1, 1)
            message = " ".join(part for part in (e.context, e.problem) if part) or str(e)
            self.problems.append(Problem(self.source, line, column, f"YAML syntax error: {message}"))
            return document, self.problems
        except yaml.YAMLError as e:
            self.problems.append(Problem(self.source, 1, 1, f"YAML error: {e}"))
            return document, self.problems
        if root is None:
            self.problems.append(Problem(self.source, 1, 1, "empty tree file: expected version, trees"))
            return document, self.problems
        if not isinstance(root, yaml.MappingNode):
            self.problem(root, f"a tree file is a mapping with keys {', '.join(_TOP_LEVEL)}; got {_describe(root)}")
            return document, self.problems
        fields = {}
        for key, key_node, value_node in self.pairs(root, "the file"):
            if key not in _TOP_LEVEL:
                self.problem(key_node, f"unknown top-level key '{key}' (expected {', '.join(_TOP_LEVEL)})")
            else:
                fields[key] = value_node
        self.version(document, fields.get("version"))
        if "main" in fields:
            document.main = self.string(fields["main"], "main")
            document.main_location = self.at(fields["main"])
        if "inputs" in fields:
            document.inputs = self.inputs(fields["inputs"])
        if "includes" in fields:
            document.includes = self.includes(fields["includes"])
        if "trees" not in fields:
            self.problems.append(Problem(self.source, 1, 1, "missing 'trees': the tree definitions"))
        else:
            document.trees = self.trees(fields["trees"])
        return document, self.problems

    def version(self, document: TreeDocument, node: yaml.Node | None) -> None:
        if node is None:
            message = f"missing 'version: {FORMAT_VERSION}' (the format version)"
            self.problems.append(Problem(self.source, 1, 1, message))
            return
        _, document.version = self.value(node)
        if type(document.version) is not int or document.version != FORMAT_VERSION:
            self.problem(
                node, f"unsupported format version {document.version!r}: this loader reads version {FORMAT_VERSION}"
            )

    def inputs(self, node: yaml.Node) -> list[PortArg]:
        if not isinstance(node, yaml.SequenceNode):
            self.problem(node, f"inputs must be a list of blackboard keys, got {_describe(node)}")
            return []
        keys = []
        for item in node.value:
            key = self.string(item, "an input key")
            if key is not None:
                keys.append(PortArg(key, self.at(item)))
        return keys

    def includes(self, node: yaml.Node) -> list[PortArg]:
        if not isinstance(node, yaml.SequenceNode):
            self.problem(node, f"includes must be a list of tree file paths, got {_describe(node)}")
            return []
        paths = []
        for item in node.value:
            path = self.string(item, "an included file path")
            if path is not None:
                paths.append(PortArg(path, self.at(item)))
        return paths

    def trees(self, node: yaml.Node) -> dict[str, TreeSpec]:
        if not isinstance(node, yaml.MappingNode) or not node.value:
            self.problem(node, f"trees must map tree ids to their root nodes, got {_describe(node)}")
            return {}
        trees = {}
        for tree_id, key_node, value_node in self.pairs(node, "trees (tree ids must be unique)"):
            trees[tree_id] = TreeSpec(tree_id, self.node(value_node), self.at(key_node))
        return trees

    # ---- nodes

    def node(self, node: yaml.Node, depth: int = 1) -> NodeSpec | None:
        if depth > MAX_DEPTH:
            self.problem(node, f"nodes nested deeper than {MAX_DEPTH}")
            return None
        if isinstance(node, yaml.ScalarNode):
            node_id = self.string(node, "a node")
            return None if node_id is None else NodeSpec(node_id, self.at(node))
        if not isinstance(node, yaml.MappingNode) or len(node.value) != 1:
            if isinstance(node, yaml.MappingNode) and node.value:
                keys = ", ".join(str(k.value) for k, _ in node.value)
                self.problem(
                    node,
                    f"a node is a one-key mapping {{NodeId: attributes}}, got keys {keys}: "
                    "indent the attributes under the node id",
                )
            else:
                self.problem(
                    node, f"a node is a NodeId or a one-key mapping {{NodeId: attributes}}, got {_describe(node)}"
                )
            return None
        key_node, attrs_node = node.value[0]
        node_id = self.string(key_node, "a node id")
        if node_id is None:
            return None
        spec = NodeSpec(node_id, self.at(key_node))
        if isinstance(attrs_node, yaml.ScalarNode) and attrs_node.tag == "tag:yaml.org,2002:null":
            attrs: list[tuple[str, yaml.Node, yaml.Node]] = []
        elif isinstance(attrs_node, yaml.MappingNode):
            attrs = list(self.pairs(attrs_node, f"the attributes of {node_id}"))
        else:
            self.problem(attrs_node, f"the attributes of {node_id} must be a mapping, got {_describe(attrs_node)}")
            return spec
        self.attributes(spec, attrs, depth)
        return spec

    def attributes(self, spec: NodeSpec, attrs: list[tuple[str, yaml.Node, yaml.Node]], depth: int = 1) -> None:
        subtree_id: str | None = None
        autoremap = False
        child_keys = [key_node for key, key_node, _ in attrs if key in ("children", "child")]
        if len(child_keys) > 1:
            self.problem(child_keys[1], f"{spec.node_id} has both 'children' and 'child': use one")
        for key, key_node, value_node in attrs:
            if key == "name":
                spec.name = self.string(value_node, "name")
            elif key in ("children", "child"):
                items = (
                    self.children(value_node, spec.node_id, depth + 1)
                    if key == "children"
                    else [self.node(value_node, depth + 1)]
                )
                spec.children.extend(child for child in items if child is not None)
                spec.unreadable_children += sum(1 for child in items if child is None)
            elif key in PRECONDITIONS or key in POSTCONDITIONS:
                expression = self.string(value_node, f"{key} (a script)")
                if expression is not None:
                    spec.conditions[key] = PortArg(expression, self.at(key_node), self.at(value_node))
            elif spec.node_id == SUBTREE_ID and key == "ID":
                subtree_id = self.string(value_node, "SubTree ID")
            elif spec.node_id == SUBTREE_ID and key == "_autoremap":
                ok, autoremap = self.value(value_node)
                if ok and not isinstance(autoremap, bool):
                    self.problem(value_node, f"_autoremap must be true or false, got {autoremap!r}")
                    autoremap = False
            else:
                ok, value = self.value(value_node)
                if ok:
                    spec.ports[key] = PortArg(value, self.at(key_node), self.at(value_node))
        if spec.node_id == SUBTREE_ID:
            if subtree_id is None:
                self.problem(spec.location, "SubTree needs 'ID': the id of the tree to instantiate")
            else:
                spec.subtree = SubTreeRef(subtree_id, autoremap, spec.location)

    def children(self, node: yaml.Node, parent_id: str, depth: int = 2) -> list[NodeSpec | None]:
        """The nodes of a ``children`` list, None where one was unreadable (and reported)."""
        if not isinstance(node, yaml.SequenceNode):
            self.problem(node, f"children of {parent_id} must be a list of nodes, got {_describe(node)}")
            return [None]
        return [self.node(item, depth) for item in node.value]


def _describe(node: yaml.Node) -> str:
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    if node.tag == "tag:yaml.org,2002:null":
        return "nothing"
    return f"{node.tag.rsplit(':', 1)[-1]} {node.value!r}"


# ---------------------------------------------------------------------------------------- writing


def dump_yaml(document: TreeDocument, decorator_ids: frozenset[str] = frozenset()) -> str:
    """Write a model back as tree YAML; nodes whose id is in ``decorator_ids`` get ``child:``."""
    data: dict[str, Any] = {"version": FORMAT_VERSION}
    if document.main:
        data["main"] = document.main
    if document.inputs:
        data["inputs"] = [arg.value for arg in document.inputs]
    if document.includes:
        data["includes"] = [arg.value for arg in document.includes]
    data["trees"] = {
        tree_id: _node_data(tree.root, decorator_ids)
        for tree_id, tree in document.trees.items()
        if tree.root is not None
    }
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None, allow_unicode=True)


def _node_data(node: NodeSpec, decorator_ids: frozenset[str]) -> Any:
    attrs: dict[str, Any] = {}
    if node.subtree is not None:
        attrs["ID"] = node.subtree.tree_id
        if node.subtree.autoremap:
            attrs["_autoremap"] = True
    if node.name:
        attrs["name"] = node.name
    attrs.update({key: arg.value for key, arg in node.conditions.items()})
    attrs.update({port: arg.value for port, arg in node.ports.items()})
    if node.node_id in decorator_ids and len(node.children) == 1:
        attrs["child"] = _node_data(node.children[0], decorator_ids)
    elif node.children:
        attrs["children"] = [_node_data(child, decorator_ids) for child in node.children]
    return {node.node_id: attrs} if attrs else node.node_id
