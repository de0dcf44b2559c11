"""The BehaviorTree.CPP v4 XML format: text -> :class:`TreeDocument` with a position on every value, and back.

::

    <root BTCPP_format="4" main_tree_to_execute="Patrol">
      <include path="subtrees/launch.xml"/>
      <BehaviorTree ID="Patrol">
        <Sequence name="patrol">
          <SubTree ID="Launch" altitude_m="20"/>
          <GoTo waypoint="100;0;20" _while="battery_ok"/>
        </Sequence>
      </BehaviorTree>
    </root>

Nodes are written compactly (``<GoTo .../>``) or explicitly (``<Action ID="GoTo" .../>``, also
``Condition``, ``Control``, ``Decorator``) exactly as BT.CPP and Groot2 read them; attributes are
``name``, the pre-conditions, and ports as text that validation types by each port's declaration.
Groot2's editor attributes (``_description``, ``_uid``, ``_fullpath``) are ignored, and so is a
``<TreeNodesModel>`` saved in the file (ours is generated: ``chaser-bt export-model``). Mission
inputs, which BT.CPP has no place for, are the root attribute ``mission_inputs="a;b"``.

Trees are shared files, so parsing is defensive in the way of ``defusedxml``: the standard
library's expat reads the text, with any DOCTYPE, entity declaration or external entity refused
before it could expand (no "billion laughs", no file or network access). Expat reports the line
and column of every element; attribute positions are found in the element's start tag.
"""

from __future__ import annotations

import re
import xml.parsers.expat
from bisect import bisect_right
from dataclasses import dataclass, field
from typing import Any

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

__all__ = ["FORMAT_VERSION", "parse_xml", "dump_xml", "XmlWriteError", "attributes_text"]

#: The BTCPP_format this loader reads and writes.
FORMAT_VERSION = "4"

#: ``<Action ID="GoTo"/>`` and friends: the explicit form of a node (Groot2 and BT.CPP both read it).
_EXPLICIT_TAGS = ("Action", "Condition", "Control", "Decorator")
#: Attributes Groot2 keeps for its editor; they mean nothing to a running tree.
_EDITOR_ATTRIBUTES = ("_description", "_uid", "_fullpath")
_ROOT_ATTRIBUTES = ("BTCPP_format", "main_tree_to_execute", "mission_inputs")
_XML_CHAR = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


class _Refused(Exception):
    """A DOCTYPE, entity or external reference: refused before it is expanded."""


@dataclass
class _Element:
    tag: str
    attrs: dict[str, str]
    offset: int  # character offset of '<' in the text
    location: Location
    children: list[_Element] = field(default_factory=list)
    text: list[tuple[str, Location]] = field(default_factory=list)


class _Source:
    """Character offsets -> Locations, for a text parsed as UTF-8 bytes."""

    def __init__(self, text: str, source: str) -> None:
        self.text = text
        self.source = source
        self.data = text.encode("utf-8")
        self.ascii = len(self.data) == len(text)
        self.line_starts = [0] + [m.end() for m in re.finditer("\n", text)]

    def char_offset(self, byte_index: int) -> int:
        if self.ascii:
            return byte_index
        return len(self.data[:byte_index].decode("utf-8", errors="ignore"))

    def at(self, offset: int) -> Location:
        line = bisect_right(self.line_starts, offset)
        return Location(self.source, line, offset - self.line_starts[line - 1] + 1)

    def attribute_at(self, element: _Element, name: str) -> Location:
        """Where ``name=`` is written in the element's start tag (the element's position if not found)."""
        match = re.compile(rf"\s{re.escape(name)}\s*=\s*[\"']").search(self.text, element.offset)
        return self.at(match.start() + 1) if match else element.location


def parse_xml(text: str, source: str = "<string>") -> tuple[TreeDocument, list[Problem]]:
    """Parse BT.CPP v4 XML into the model, collecting every structural problem instead of stopping."""
    return _Parser(text, source).parse()


class _Parser:
    def __init__(self, text: str, source: str) -> None:
        self.src = _Source(text, source)
        self.source = source
        self.problems: list[Problem] = []

    def problem(self, location: Location, message: str) -> None:
        self.problems.append(Problem(location.file, location.line, location.column, message))

    # ---- XML -> elements

    def elements(self) -> _Element | None:
        parser = xml.parsers.expat.ParserCreate(encoding="utf-8")
        parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
        stack: list[_Element] = []
        roots: list[_Element] = []

        def refuse(what: str) -> Any:
            def handler(*args: Any) -> None:
                raise _Refused(what)

            return handler

        def start(tag: str, attrs: dict[str, str]) -> None:
            if len(stack) > MAX_DEPTH + 2:  # <root><BehaviorTree> plus the nodes
                raise _Refused(f"nesting deeper than {MAX_DEPTH} nodes")
            offset = self.src.char_offset(parser.CurrentByteIndex)
            element = _Element(tag, attrs, offset, self.src.at(offset))
            (stack[-1].children if stack else roots).append(element)
            stack.append(element)

        def end(tag: str) -> None:
            stack.pop()

        def characters(data: str) -> None:
            if stack and data.strip():
                offset = self.src.char_offset(parser.CurrentByteIndex)
                stack[-1].text.append((data.strip(), self.src.at(offset)))

        parser.StartDoctypeDeclHandler = refuse("a DOCTYPE")
        parser.EntityDeclHandler = refuse("an entity declaration")
        parser.UnparsedEntityDeclHandler = refuse("an entity declaration")
        parser.ExternalEntityRefHandler = refuse("an external entity")
        parser.StartElementHandler = start
        parser.EndElementHandler = end
        parser.CharacterDataHandler = characters
        try:
            parser.Parse(self.src.data, True)
        except xml.parsers.expat.ExpatError as e:
            reason = xml.parsers.expat.errors.messages.get(e.code, str(e))
            self.problem(Location(self.source, e.lineno, e.offset + 1), f"malformed XML: {reason}")
            return None
        except _Refused as e:
            where = self.src.at(self.src.char_offset(parser.CurrentByteIndex))
            why = "" if str(e).startswith("nesting") else " (entities could expand without bound)"
            self.problem(where, f"{e} is not allowed in a tree file{why}")
            return None
        return roots[0] if roots else None

    # ---- elements -> model

    def parse(self) -> tuple[TreeDocument, list[Problem]]:
        document = TreeDocument(source=self.source)
        root = self.elements()
        if root is None:
            if not self.problems:
                self.problem(Location(self.source, 1, 1), "empty tree file: expected <root BTCPP_format=\"4\">")
            return document, self.problems
        if root.tag != "root":
            self.problem(root.location, f"the top element must be <root BTCPP_format=\"4\">, got <{root.tag}>")
            return document, self.problems
        self.root_attributes(document, root)
        self.no_text(root)
        for element in root.children:
            if element.tag == "BehaviorTree":
                self.behavior_tree(document, element)
            elif element.tag == "include":
                self.include(document, element)
            elif element.tag == "TreeNodesModel":
                self.subtree_models(document, element)  # the rest is Groot2's; ours comes from the registry
            else:
                self.problem(
                    element.location,
                    f"unexpected <{element.tag}> under <root>: expected <BehaviorTree>, <include> or <TreeNodesModel>",
                )
        if not document.trees and not document.includes:
            self.problem(root.location, "no <BehaviorTree> in the file")
        return document, self.problems

    def subtree_models(self, document: TreeDocument, model: _Element) -> None:
        """Port defaults of ``<SubTree ID>`` model entries: BT.CPP's remapping for ports a SubTree node omits."""
        for entry in model.children:
            tree_id = entry.attrs.get("ID", "")
            if entry.tag != "SubTree" or not tree_id:
                continue
            defaults = document.subtree_defaults.setdefault(tree_id, {})
            for port in entry.children:
                name, default = port.attrs.get("name", ""), port.attrs.get("default")
                if port.tag.endswith("_port") and name and default is not None and default != "":
                    defaults[name] = PortArg(default, port.location, self.src.attribute_at(port, "default"), from_text=True)

    def root_attributes(self, document: TreeDocument, root: _Element) -> None:
        for name in root.attrs:
            if name not in _ROOT_ATTRIBUTES:
                self.problem(
                    self.src.attribute_at(root, name),
                    f"unknown <root> attribute '{name}' (expected {', '.join(_ROOT_ATTRIBUTES)})",
                )
        version = root.attrs.get("BTCPP_format")
        document.version = version
        if version is None:
            self.problem(root.location, f'missing BTCPP_format="{FORMAT_VERSION}" on <root> (the format version)')
        elif version.strip() != FORMAT_VERSION:
            self.problem(
                self.src.attribute_at(root, "BTCPP_format"),
                f"unsupported BTCPP_format {version!r}: this loader reads BehaviorTree.CPP v{FORMAT_VERSION} XML",
            )
        if "main_tree_to_execute" in root.attrs:
            document.main = root.attrs["main_tree_to_execute"] or None
            document.main_location = self.src.attribute_at(root, "main_tree_to_execute")
        if "mission_inputs" in root.attrs:
            where = self.src.attribute_at(root, "mission_inputs")
            keys = [key.strip() for key in root.attrs["mission_inputs"].split(";")]
            document.inputs = [PortArg(key, where) for key in keys if key]

    def no_text(self, element: _Element) -> None:
        for text, location in element.text:
            shown = text if len(text) <= 20 else text[:20] + "..."
            self.problem(location, f"unexpected text {shown!r} in <{element.tag}>: values go in attributes")

    def include(self, document: TreeDocument, element: _Element) -> None:
        self.no_text(element)
        for name in element.attrs:
            if name != "path":
                extra = " (ROS packages are not searched)" if name == "ros_pkg" else ""
                self.problem(self.src.attribute_at(element, name), f"<include> takes only 'path', got '{name}'{extra}")
        path = element.attrs.get("path", "").strip()
        if not path:
            self.problem(element.location, "<include> needs path=\"FILE\": the tree file to include")
            return
        if element.children:
            self.problem(element.children[0].location, "<include> takes no children")
        document.includes.append(PortArg(path, element.location, self.src.attribute_at(element, "path")))

    def behavior_tree(self, document: TreeDocument, element: _Element) -> None:
        self.no_text(element)
        tree_id = element.attrs.get("ID", "")
        for name in element.attrs:
            if name != "ID" and name not in _EDITOR_ATTRIBUTES:
                self.problem(self.src.attribute_at(element, name), f"<BehaviorTree> takes only 'ID', got '{name}'")
        if not tree_id:
            self.problem(element.location, "<BehaviorTree> needs an ID")
            return
        if tree_id in document.trees:
            first = document.trees[tree_id].location
            self.problem(element.location, f"duplicate tree ID '{tree_id}' (first at line {first.line})")
            return
        if len(element.children) != 1:
            self.problem(
                element.location,
                f"<BehaviorTree ID=\"{tree_id}\"> must hold exactly one root node, got {len(element.children)}",
            )
        root = self.node(element.children[0]) if element.children else None
        document.trees[tree_id] = TreeSpec(tree_id, root, element.location)

    def node(self, element: _Element) -> NodeSpec | None:
        self.no_text(element)
        attrs = dict(element.attrs)
        node_id = element.tag
        if element.tag in _EXPLICIT_TAGS:
            node_id = attrs.pop("ID", "")
            if not node_id:
                self.problem(element.location, f"<{element.tag}> needs ID=\"NodeId\": the node to use")
                return None
        spec = NodeSpec(node_id, element.location)
        if element.tag in _EXPLICIT_TAGS:
            spec.explicit_tag = element.tag
        if node_id == SUBTREE_ID:
            subtree_id = attrs.pop("ID", "")
            autoremap = self.autoremap(element, attrs.pop("_autoremap", None))
            if subtree_id:
                spec.subtree = SubTreeRef(subtree_id, autoremap, element.location)
            else:
                self.problem(element.location, "<SubTree> needs ID: the id of the tree to instantiate")
        for name, value in attrs.items():
            where = self.src.attribute_at(element, name)
            if name == "name":
                spec.name = value or None
            elif name in PRECONDITIONS or name in POSTCONDITIONS:
                if value.strip():
                    spec.conditions[name] = PortArg(value, where)
                else:
                    self.problem(where, f"{name} needs a script")
            elif name in _EDITOR_ATTRIBUTES:
                continue
            elif name.startswith("_"):
                known = ", ".join((*PRECONDITIONS, *POSTCONDITIONS, *(("_autoremap",) if node_id == SUBTREE_ID else ())))
                self.problem(where, f"unknown special attribute '{name}' (BT.CPP's are {known})")
            else:
                spec.ports[name] = PortArg(value, where, from_text=True)
        children = [self.node(child) for child in element.children]
        spec.children = [child for child in children if child is not None]
        spec.unreadable_children = len(children) - len(spec.children)
        return spec

    def autoremap(self, element: _Element, value: str | None) -> bool:
        if value is None:
            return False
        flag = value.strip().lower()
        if flag in ("true", "1"):
            return True
        if flag not in ("false", "0"):
            self.problem(self.src.attribute_at(element, "_autoremap"), f"_autoremap must be true or false, got {value!r}")
        return False


# ---------------------------------------------------------------------------------------- writing


class XmlWriteError(ValueError):
    """A model that XML cannot hold (a value with characters XML 1.0 forbids, or no text form)."""


def dump_xml(document: TreeDocument) -> str:
    """Write a model as BT.CPP v4 XML. Port values must already be text (see :mod:`chaser_bt.tree.conversion`).

    Non-text literals are written with ``str()``; use the conversion module to get BT.CPP's text
    forms (``true``, ``1.0;2.0``) for typed values.

    Raises:
        XmlWriteError: a value holds a character XML 1.0 cannot carry.
    """
    root = {"BTCPP_format": FORMAT_VERSION}
    if document.main:
        root["main_tree_to_execute"] = document.main
    if document.inputs:
        root["mission_inputs"] = ";".join(str(arg.value) for arg in document.inputs)
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', f"<root{attributes_text(root)}>"]
    for include in document.includes:
        lines.append(f"  <include{attributes_text({'path': str(include.value)})}/>")
    for tree_id, tree in document.trees.items():
        if tree.root is None:
            continue
        lines.append(f"  <BehaviorTree{attributes_text({'ID': tree_id})}>")
        _write_node(tree.root, 2, lines)
        lines.append("  </BehaviorTree>")
    lines.append("</root>")
    return "\n".join(lines) + "\n"


def _write_node(node: NodeSpec, depth: int, lines: list[str]) -> None:
    attrs: dict[str, Any] = {}
    if node.subtree is not None:
        attrs["ID"] = node.subtree.tree_id
    if node.name:
        attrs["name"] = node.name
    if node.subtree is not None and node.subtree.autoremap:
        attrs["_autoremap"] = "true"
    attrs.update({key: arg.value for key, arg in node.conditions.items()})
    attrs.update({port: arg.value for port, arg in node.ports.items()})
    indent = "  " * depth
    tag = node.node_id
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.-]*", tag):
        raise XmlWriteError(f"node id {tag!r} is not an XML element name")
    if not node.children:
        lines.append(f"{indent}<{tag}{attributes_text(attrs)}/>")
        return
    lines.append(f"{indent}<{tag}{attributes_text(attrs)}>")
    for child in node.children:
        _write_node(child, depth + 1, lines)
    lines.append(f"{indent}</{tag}>")


def attributes_text(attrs: dict[str, Any]) -> str:
    """`` name="value"`` for each attribute, escaped as XML 1.0 needs (raises :class:`XmlWriteError` where it cannot)."""
    for name in attrs:
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.-]*", name):
            raise XmlWriteError(f"{name!r} is not an XML attribute name")
    return "".join(f' {name}="{_escape(str(value), name)}"' for name, value in attrs.items())


def _escape(text: str, name: str) -> str:
    bad = _XML_CHAR.search(text)
    if bad:
        raise XmlWriteError(f"attribute {name}: character {bad.group()!r} cannot be written in XML 1.0")
    return (
        text.replace("&", "&amp;")
        .replace("<", "&lt;")
        .replace(">", "&gt;")
        .replace('"', "&quot;")
        .replace("\t", "&#9;")
        .replace("\n", "&#10;")
        .replace("\r", "&#13;")
    )
