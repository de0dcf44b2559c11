"""Reading tree documents: the format by file extension, and ``include`` resolved into one document.

``.xml`` files are BehaviorTree.CPP v4 XML (:mod:`chaser_bt.tree.xml_format`), anything else is
the YAML format (:mod:`chaser_bt.tree.yaml_format`); both give the same model. A file's includes
(``<include path=.../>`` in XML, ``includes: [...]`` in YAML, either format may include the
other) are read relative to the including file's folder, as BT.CPP does, and their trees merged
into the including document: the trees a SubTree can instantiate. Included files' mission inputs
are merged too; their ``main`` is ignored. A missing or unreadable include, an include cycle, or a
tree ID defined twice across files is a problem at the offending line.
"""

from __future__ import annotations

import copy
from pathlib import Path

from chaser_bt.tree.errors import Problem
from chaser_bt.tree.model import Location, TreeDocument
from chaser_bt.tree.xml_format import parse_xml
from chaser_bt.tree.yaml_format import parse_yaml

__all__ = ["TREE_FORMATS", "format_of", "parse_document", "read_document", "read_text", "merge_includes", "tree_files"]

TREE_FORMATS = ("yaml", "xml")


def format_of(path: str | Path) -> str:
    """``"xml"`` for a ``.xml`` file, ``"yaml"`` for anything else."""
    return "xml" if Path(path).suffix.lower() == ".xml" else "yaml"


def parse_document(text: str, source: str, fmt: str | None = None) -> tuple[TreeDocument, list[Problem]]:
    """Parse tree text in ``fmt`` (default: by the source's extension; XML if the text starts with '<')."""
    if fmt is None:
        fmt = "xml" if format_of(source) == "xml" or text.lstrip().startswith("<") else "yaml"
    if fmt not in TREE_FORMATS:
        raise ValueError(f"unknown tree format {fmt!r}: expected one of {', '.join(TREE_FORMATS)}")
    return parse_xml(text, source) if fmt == "xml" else parse_yaml(text, source)


def read_text(path: Path, where: Location | None = None) -> tuple[str | None, list[Problem]]:
    """A tree file's text, or a problem naming the file (or the include that named it)."""
    try:
        return path.read_text(encoding="utf-8"), []
    except (OSError, UnicodeDecodeError) as e:
        reason = getattr(e, "strerror", None) or str(e)
        if isinstance(e, UnicodeDecodeError):
            reason = f"byte {e.start} is not UTF-8 text (a binary file?)"
        if where is None:
            return None, [Problem(str(path), 1, 1, f"cannot read tree file: {reason}")]
        return None, [Problem(where.file, where.line, where.column, f"cannot read included file {str(path)!r}: {reason}")]


def read_document(path: str | Path) -> tuple[TreeDocument, list[Problem]]:
    """Parse a tree file and merge everything it includes."""
    path = Path(path)
    text, problems = read_text(path)
    if text is None:
        return TreeDocument(source=str(path)), problems
    document, problems = parse_document(text, str(path), format_of(path))
    merged, more = merge_includes(document, path.parent)
    return merged, problems + more


def merge_includes(
    document: TreeDocument, base_dir: Path, _stack: tuple[Path, ...] = ()
) -> tuple[TreeDocument, list[Problem]]:
    """``document`` with the trees (and inputs) of every file it includes, recursively."""
    if not document.includes:
        return document, []
    merged = copy.copy(document)
    merged.trees = dict(document.trees)
    merged.inputs = list(document.inputs)
    merged.subtree_defaults = dict(document.subtree_defaults)
    problems: list[Problem] = []
    here = Path(document.source).resolve() if not document.source.startswith("<") else None
    stack = (*_stack, here) if here is not None else _stack
    for include in document.includes:
        where = include.value_at
        target = Path(str(include.value))
        target = target if target.is_absolute() else base_dir / target
        resolved = target.resolve()
        if resolved in stack:
            chain = " -> ".join(p.name for p in (*stack, resolved))
            problems.append(Problem(where.file, where.line, where.column, f"include cycle: {chain}"))
            continue
        if not target.is_file():
            problems.append(
                Problem(where.file, where.line, where.column, f"included file {str(include.value)!r} not found ({target})")
            )
            continue
        text, read_problems = read_text(target, where)
        problems += read_problems
        if text is None:
            continue
        included, parse_problems = parse_document(text, str(target), format_of(target))
        problems += parse_problems
        included, nested = merge_includes(included, target.parent, stack)
        problems += nested
        for tree_id, tree in included.trees.items():
            if tree_id in merged.trees:
                first = merged.trees[tree_id].location
                problems.append(
                    Problem(
                        tree.location.file,
                        tree.location.line,
                        tree.location.column,
                        f"duplicate tree ID '{tree_id}' (first defined at {first.file}:{first.line})",
                    )
                )
            else:
                merged.trees[tree_id] = tree
        for tree_id, defaults in included.subtree_defaults.items():
            merged.subtree_defaults.setdefault(tree_id, defaults)
        known = {arg.value for arg in merged.inputs}
        merged.inputs += [arg for arg in included.inputs if arg.value not in known]
    return merged, problems


def tree_files(path: str | Path) -> list[Path]:
    """``path`` and every file it includes, directly or through others: resolved, each once, in the
    order they are first included. Everything a tree's behaviour depends on besides the code (a
    campaign fingerprints them). Unreadable or missing includes are left out; loading reports them."""
    found: list[Path] = []

    def visit(file: Path) -> None:
        if file in found or not file.is_file():
            return
        found.append(file)
        text, _ = read_text(file)
        if text is None:
            return
        document, _ = parse_document(text, str(file), format_of(file))
        for include in document.includes:
            target = Path(str(include.value))
            visit((target if target.is_absolute() else file.parent / target).resolve())

    visit(Path(path).resolve())
    return found
