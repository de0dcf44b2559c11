"""YAML <-> BT.CPP XML conversion that round-trips exactly, or refuses.

Both formats parse to the same model; what differs is how a literal is written. YAML types it
(``20``, ``[100, 0, 20]``, ``true``); XML holds text (``"20"``, ``"100;0;20"``, ``"true"``) that the
port's declaration types when the tree loads. So conversion goes through the registry:

- to XML, each literal becomes the text its port reads back as the same value
  (:func:`~chaser_bt.tree.ports.literal_text`; BT.CPP's forms: ``true``, ``1.5``, ``a;b;c``);
- to YAML, each text literal is typed by its port exactly as validation types it
  (:func:`~chaser_bt.tree.validation.typed_literal`), enums written by member name.

A SubTree's literal remapping is typed by the ports that read that key inside the subtree (when
they agree on one type). Literals of unknown nodes or ports are copied as they are; validating
the result reports them. :func:`convert_text` then reads its own output back and checks that
every tree, node, port and value is unchanged, and raises instead of writing anything lossy.

A file written to another folder names the same included files: relative include paths are
rewritten to start from the output's folder (:func:`rebased_include`). Comments are not carried
over (neither parser keeps them); :func:`comment_lines` counts what a conversion leaves behind.
"""

from __future__ import annotations

import copy
import enum
import os
import re
import xml.parsers.expat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import yaml

from chaser_bt.tree.documents import format_of, merge_includes, parse_document
from chaser_bt.tree.errors import Problem, TreeError
from chaser_bt.tree.model import SUBTREE_ID, Location, NodeSpec, PortArg, TreeDocument
from chaser_bt.tree.ports import LiteralError, is_reference_text, literal_text, parse_reference
from chaser_bt.tree.registry import NodeKind, Registry, default_registry
from chaser_bt.tree.validation import typed_literal
from chaser_bt.tree.xml_format import XmlWriteError, dump_xml
from chaser_bt.tree.yaml_format import dump_yaml

__all__ = [
    "typed_document", "textual_document", "write_document", "convert_text", "converted_file", "convert_file",
    "rebased_include", "comment_lines",
]

_Transform = Callable[[Any, Any, bool], Any]


def typed_document(document: TreeDocument, registry: Registry, context: TreeDocument | None = None) -> TreeDocument:
    """A copy whose literals are values of their ports' types, written the YAML way (enums by name).

    ``context`` (the document with its includes merged) types the ports of subtrees defined in
    included files; without it they are typed from ``document`` alone.
    """

    def typed(value: Any, data_type: Any, from_text: bool) -> Any:
        return _plain(typed_literal(value, data_type, from_text))

    return _map_literals(document, registry, typed, from_text_result=False, context=context)


def textual_document(document: TreeDocument, registry: Registry, context: TreeDocument | None = None) -> TreeDocument:
    """A copy whose literals are BT.CPP attribute text that reads back as the same value (``context``: as above)."""

    def textual(value: Any, data_type: Any, from_text: bool) -> Any:
        return literal_text(typed_literal(value, data_type, from_text), data_type)

    return _map_literals(document, registry, textual, from_text_result=True, context=context)


def write_document(document: TreeDocument, fmt: str, registry: Registry, context: TreeDocument | None = None) -> str:
    """The document as ``fmt`` (``"yaml"`` or ``"xml"``) text, literals converted for that format."""
    if fmt == "xml":
        return dump_xml(textual_document(document, registry, context))
    decorators = frozenset(i for i, t in registry.specs.items() if t.kind is NodeKind.DECORATOR) | {SUBTREE_ID}
    return dump_yaml(typed_document(document, registry, context), decorators)


def convert_text(
    text: str, source: str, target: str, registry: Registry | None = None, source_format: str | None = None,
    base_dir: Path | None = None, out_dir: Path | None = None,
) -> str:
    """Convert tree text to the ``target`` format, checking that it reads back unchanged.

    Includes stay includes; with ``base_dir`` (where relative include paths start) the subtrees they
    define give their ports' types, so literals passed to them convert exactly. With ``out_dir``
    too (the folder the output will be in) relative include paths are rewritten to start there.

    Raises:
        TreeError: the source does not parse, an include cannot be read, or a value cannot be carried
            over exactly.
    """
    registry = registry if registry is not None else default_registry()
    document, problems = parse_document(text, source, source_format)
    if problems:
        raise TreeError(problems)
    context = None
    if base_dir is not None and document.includes:
        context, problems = merge_includes(document, base_dir)
        if problems:
            raise TreeError(problems)
    if base_dir is not None and out_dir is not None:
        document = copy.deepcopy(document)
        for include in document.includes:
            include.value = rebased_include(str(include.value), base_dir, out_dir)
    try:
        output = write_document(document, target, registry, context)
    except (XmlWriteError, LiteralError) as e:
        raise TreeError([Problem(source, 1, 1, f"cannot write as {target}: {e}")]) from None
    again, problems = parse_document(output, f"<{target} output>", target)
    if problems:
        raise TreeError([Problem(source, 1, 1, f"the {target} written does not read back: {problems[0]}")])
    difference = _first_difference(typed_document(document, registry, context), typed_document(again, registry, context))
    if difference is not None:
        where, what = difference
        raise TreeError([Problem(where.file, where.line, where.column, f"does not survive conversion to {target}: {what}")])
    return output


def converted_file(source: str | Path, target: str | Path, registry: Registry | None = None) -> str:
    """The text to write as ``target`` for tree file ``source``; formats by extension (``.xml`` = BT.CPP XML).

    Relative include paths are rewritten for ``target``'s folder, so the output names the same files.

    Raises:
        TreeError: as :func:`convert_text`, or ``source`` cannot be read.
    """
    source, target = Path(source), Path(target)
    try:
        text = source.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        reason = f"byte {e.start} is not UTF-8 text (a binary file?)" if isinstance(e, UnicodeDecodeError) else e.strerror or e
        raise TreeError([Problem(str(source), 1, 1, f"cannot read tree file: {reason}")])
    return convert_text(
        text, str(source), format_of(target), registry, format_of(source), base_dir=source.parent, out_dir=target.parent
    )


def convert_file(source: str | Path, target: str | Path, registry: Registry | None = None) -> None:
    """Convert tree file ``source`` into ``target`` (see :func:`converted_file`)."""
    Path(target).write_text(converted_file(source, target, registry), encoding="utf-8")


def rebased_include(path: str, from_dir: Path, to_dir: Path) -> str:
    """Include ``path``, written in a file in ``from_dir``, as a file in ``to_dir`` names the same file.

    Absolute paths, and paths between files in the same folder, stay as written; otherwise the result
    is relative (``/``-separated) from ``to_dir``, or absolute where there is no relative path
    (another Windows drive). Folders are compared resolved, as the operating system opens them.
    """
    start, end = os.path.realpath(from_dir), os.path.realpath(to_dir)
    if Path(path).is_absolute() or start == end:
        return path
    included = os.path.realpath(os.path.join(start, path))
    try:
        return Path(os.path.relpath(included, end)).as_posix()
    except ValueError:
        return included


def comment_lines(text: str, fmt: str) -> int:
    """How many lines of tree text in ``fmt`` (``"yaml"`` or ``"xml"``) hold a comment.

    Counted up to the first syntax error; a DOCTYPE stops the count (nothing is expanded).
    """
    lines: set[int] = set()
    if fmt == "xml":
        parser = xml.parsers.expat.ParserCreate()

        def comment(data: str) -> None:
            first = parser.CurrentLineNumber
            lines.update(range(first, first + data.count("\n") + 1))

        def doctype(*_: Any) -> None:
            raise ValueError("DOCTYPE")

        parser.CommentHandler = comment
        parser.StartDoctypeDeclHandler = doctype
        try:
            parser.Parse(text, True)
        except (xml.parsers.expat.ExpatError, ValueError):
            pass
        return len(lines)
    end = 0  # comments lie between tokens: each '#' there starts one, to the end of its line
    try:
        for token in yaml.scan(text):
            for match in re.finditer("#", text[end : token.start_mark.index]):
                lines.add(text.count("\n", 0, end + match.start()))
            end = max(end, token.end_mark.index)
    except yaml.YAMLError:
        pass
    return len(lines)


# ---------------------------------------------------------------------------------------- literals


def _plain(value: Any) -> Any:
    """A typed value as YAML writes it: enum members by name."""
    if isinstance(value, enum.Enum):
        return value.name
    if isinstance(value, list):
        return [_plain(item) for item in value]
    return value


def _map_literals(
    document: TreeDocument, registry: Registry, transform: _Transform, from_text_result: bool,
    context: TreeDocument | None = None,
) -> TreeDocument:
    result = copy.deepcopy(document)
    types_from = result if context is None else context
    for tree in result.trees.values():
        for node in _walk(tree.root):
            node_class = registry.get(node.node_id).cls if node.node_id in registry else None
            key_ports = getattr(node_class, "KEY_NAME_PORTS", ())
            for port, arg in node.ports.items():
                if port in key_ports:
                    # BT.CPP's form names the entry: output_key="x", not the old "{x}".
                    if getattr(node_class, "BRACES_ARE_OLD_FORM", True) and is_reference_text(arg.value):
                        try:
                            arg.value = parse_reference(str(arg.value).strip())
                        except ValueError:
                            pass
                    continue
                if is_reference_text(arg.value):
                    continue
                if node.node_id == SUBTREE_ID:
                    types = _subtree_key_types(types_from, node.subtree.tree_id if node.subtree else "", port, registry, set())
                    data_type = types.pop() if len(types) == 1 else None
                elif node.node_id in registry:
                    declaration = registry.get(node.node_id).port(port)
                    data_type = None if declaration is None else declaration.data_type
                else:
                    data_type = None
                if data_type is None:
                    continue
                try:
                    arg.value = transform(arg.value, data_type, arg.from_text)
                    arg.from_text = from_text_result
                except LiteralError:
                    continue  # left as written: validation reports it
    return result


def _walk(node: NodeSpec | None) -> Iterator[NodeSpec]:
    stack = [node] if node is not None else []
    while stack:
        current = stack.pop()
        yield current
        stack.extend(current.children)


def _subtree_key_types(
    document: TreeDocument, tree_id: str, key: str, registry: Registry, visited: set[tuple[str, str]]
) -> list[Any]:
    """The distinct types of the ports that read ``{key}`` inside tree ``tree_id`` (through nested subtrees)."""
    if (tree_id, key) in visited or tree_id not in document.trees:
        return []
    visited.add((tree_id, key))
    types: list[Any] = []
    for node in _walk(document.trees[tree_id].root):
        if node.node_id == SUBTREE_ID and node.subtree is not None:
            for port, arg in node.ports.items():
                if _reference_key(arg.value, port) == key:
                    types += _subtree_key_types(document, node.subtree.tree_id, port, registry, visited)
            if node.subtree.autoremap and key not in node.ports:
                types += _subtree_key_types(document, node.subtree.tree_id, key, registry, visited)
        elif node.node_id in registry:
            node_type = registry.get(node.node_id)
            for port, arg in node.ports.items():
                declaration = node_type.input_ports.get(port)
                if declaration is not None and _reference_key(arg.value, port) == key:
                    types.append(declaration.data_type)
    unique: list[Any] = []
    for data_type in types:
        if data_type not in unique:
            unique.append(data_type)
    return unique


def _reference_key(value: Any, port: str) -> str | None:
    if not is_reference_text(value):
        return None
    try:
        key = parse_reference(value)
    except ValueError:
        return None
    return port if key == "=" else key


# ---------------------------------------------------------------------------------------- checking


def _first_difference(a: TreeDocument, b: TreeDocument) -> tuple[Location, str] | None:
    here = Location(a.source, 1, 1)
    if a.main != b.main:
        return here, f"main {a.main!r} became {b.main!r}"
    if [x.value for x in a.inputs] != [x.value for x in b.inputs]:
        return here, "the mission inputs changed"
    if [x.value for x in a.includes] != [x.value for x in b.includes]:
        return here, "the includes changed"
    if list(a.trees) != list(b.trees):
        return here, f"trees {list(a.trees)} became {list(b.trees)}"
    for tree_id, tree in a.trees.items():
        found = _node_difference(tree.root, b.trees[tree_id].root, tree.location)
        if found is not None:
            return found
    return None


def _node_difference(x: NodeSpec | None, y: NodeSpec | None, where: Location) -> tuple[Location, str] | None:
    if x is None or y is None:
        return None if x is y else (where, "a tree root was lost")
    if (x.node_id, x.name, x.subtree) != (y.node_id, y.name, y.subtree):
        return x.location, f"node {x.node_id} (name {x.name!r}) became {y.node_id} (name {y.name!r})"
    for kind, values_x, values_y in (("port", x.ports, y.ports), ("condition", x.conditions, y.conditions)):
        for name in {*values_x, *values_y}:
            vx = values_x.get(name, PortArg(None, where)).value
            vy = values_y.get(name, PortArg(None, where)).value
            if vx != vy or type(vx) is not type(vy):
                location = values_x[name].value_at if name in values_x else x.location
                return location, f"{kind} {name} of {x.node_id}: {vx!r} became {vy!r}"
    if len(x.children) != len(y.children):
        return x.location, f"{x.node_id} had {len(x.children)} children, now {len(y.children)}"
    for cx, cy in zip(x.children, y.children):
        found = _node_difference(cx, cy, where)
        if found is not None:
            return found
    return None
