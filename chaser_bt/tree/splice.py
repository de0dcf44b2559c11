"""Replacing one subtree of a running tree: the spliced document, and the new instances built for it.

A retask may replace one subtree, named by its tree ID, instead of the whole tree
(:mod:`chaser_bt.mission.retask`). :func:`splice_document` puts the replacement's tree in place of
that definition in the running tree's document, as if the replacement were an included file; the
result is then validated as a whole, as any tree is, so the running tree's ``SubTree`` nodes must
still fit the new subtree (every key they remap is one it uses, every key it reads is written
somewhere, every entry keeps its type). :func:`plan_splice` builds only the new instances and pairs
each with the running ``SubTree`` node it goes under: the rest of the running tree, and its state,
stays as it is until :meth:`Splice.apply` swaps them in.
"""

from __future__ import annotations

import copy
import uuid
from dataclasses import dataclass

import py_trees

from chaser_bt.tree.builder import build_node
from chaser_bt.tree.errors import Problem, TreeError
from chaser_bt.tree.loader import MissionTree, build_tree, collect_wiring
from chaser_bt.tree.model import SUBTREE_ID, NodeSpec, TreeDocument, TreeSpec
from chaser_bt.tree.registry import Registry, default_registry
from chaser_bt.tree.validation import ResolvedNode, resolve_document

__all__ = ["Splice", "SpliceError", "SpliceSite", "build_document", "plan_splice", "replacement_tree",
           "splice_document", "subtree_ids"]


class SpliceError(ValueError):
    """A replacement that cannot go in; the message is one line saying why."""


@dataclass
class SpliceSite:
    """One instance of the replaced subtree: the running ``SubTree`` node, its child now and the new one.

    ``path`` is the instance's blackboard scope (``/leg``), which names it in logs.
    """

    wrapper: py_trees.decorators.Decorator
    old: py_trees.behaviour.Behaviour
    new: py_trees.behaviour.Behaviour
    path: str

    def swap(self) -> None:
        """Put ``new`` under the ``SubTree`` node in place of ``old`` (the node keeps its own status)."""
        self.wrapper.children[0] = self.wrapper.decorated = self.new
        self.new.parent = self.wrapper
        self.old.parent = None


@dataclass
class Splice:
    """A checked replacement of subtree ``name``: the whole tree as it flies once applied, and where.

    ``tree`` has the running root, and the spliced tree's resolution and wiring (Groot2 and
    ``chaser-bt show`` describe it); it is what flies after :meth:`apply`.
    """

    name: str
    document: TreeDocument
    tree: MissionTree
    sites: tuple[SpliceSite, ...]

    def apply(self) -> None:
        """Swap every instance in. The caller sets the new ones up and halts the running old ones first."""
        for site in self.sites:
            site.swap()


def build_document(document: TreeDocument, problems: list[Problem] | None = None,
                   registry: Registry | None = None) -> MissionTree:
    """Validate and build an already parsed document (includes merged), as :func:`~chaser_bt.tree.load_tree_text` does.

    Raises:
        TreeError: ``problems`` (parse problems) and every validation problem, sorted.
    """
    return build_tree(document, list(problems or []), registry)


def subtree_ids(tree: MissionTree) -> list[str]:
    """The tree IDs ``tree`` instantiates with ``SubTree`` nodes, each once, in the order met."""
    found: list[str] = []
    stack = [tree.resolved] if tree.resolved is not None else []
    while stack:
        node = stack.pop()
        ref = node.spec.subtree if node.spec is not None else None
        if ref is not None and ref.tree_id not in found:
            found.append(ref.tree_id)
        stack.extend(reversed(node.children))
    return found


def _main_of(document: TreeDocument) -> str | None:
    if document.main is not None:
        return document.main
    return next(iter(document.trees)) if len(document.trees) == 1 else None


def _called(document: TreeDocument, tree_id: str) -> list[str]:
    """The trees ``tree_id`` instantiates in ``document``, directly or not (not itself)."""
    seen: list[str] = []
    pending = [tree_id]
    while pending:
        tree = document.trees.get(pending.pop())
        stack: list[NodeSpec] = [tree.root] if tree is not None and tree.root is not None else []
        while stack:
            node = stack.pop()
            stack.extend(node.children)
            if node.node_id == SUBTREE_ID and node.subtree is not None:
                called = node.subtree.tree_id
                if called != tree_id and called not in seen:
                    seen.append(called)
                    pending.append(called)
    return seen


def replacement_tree(replacement: TreeDocument, name: str) -> str:
    """The ID of the tree of ``replacement`` that replaces subtree ``name``: its tree ``name``, else its main tree.

    Raises:
        SpliceError: it has neither.
    """
    chosen = name if name in replacement.trees else _main_of(replacement)
    if chosen is None or chosen not in replacement.trees or replacement.trees[chosen].root is None:
        trees = ", ".join(replacement.trees) or "none"
        raise SpliceError(f"the replacement has no tree {name!r} and no main tree to put in its place; "
                          f"its trees: {trees}")
    return chosen


def splice_document(running: TreeDocument, replacement: TreeDocument, name: str) -> TreeDocument:
    """``running`` with tree ``name`` replaced by the replacement's tree of that ID, else its main tree.

    The trees the new subtree instantiates come with it; one the running document already defines
    must be the same there. The replacement's mission inputs are added, as an include's are.

    Raises:
        SpliceError: ``name`` is the running main tree or not a tree of it, the replacement has no
            tree to give, or it brings a tree the running document defines otherwise.
    """
    if name not in running.trees:
        raise SpliceError(f"the running tree has no subtree {name!r}")
    if name == _main_of(running):
        raise SpliceError(f"{name!r} is the running main tree: retask the whole tree instead")
    chosen = replacement_tree(replacement, name)
    spliced = copy.copy(running)
    spliced.main = _main_of(running)
    spliced.trees = dict(running.trees)
    new = replacement.trees[chosen]
    spliced.trees[name] = TreeSpec(name, new.root, new.location)
    for tree_id in _called(replacement, chosen):
        if tree_id == name or tree_id not in replacement.trees:
            continue  # validation names the recursion, or the missing tree
        theirs = replacement.trees[tree_id]
        ours = running.trees.get(tree_id)
        if ours is None:
            spliced.trees[tree_id] = theirs
        elif ours.root != theirs.root:
            raise SpliceError(f"the replacement's tree {tree_id!r} differs from the running tree's: replace that "
                              f"subtree by its own retask")
    spliced.subtree_defaults = dict(running.subtree_defaults)
    if chosen in replacement.subtree_defaults:
        spliced.subtree_defaults.setdefault(name, replacement.subtree_defaults[chosen])
    known = {arg.value for arg in running.inputs}
    spliced.inputs = list(running.inputs) + [arg for arg in replacement.inputs if arg.value not in known]
    return spliced


def plan_splice(running: MissionTree, document: TreeDocument, replacement: TreeDocument, name: str,
                registry: Registry | None = None) -> Splice:
    """Check the replacement of subtree ``name`` of ``running`` (built from ``document``) and build its instances.

    Nothing of ``running`` changes here.

    Raises:
        SpliceError: ``running`` instantiates no subtree ``name``, :func:`splice_document` refuses, or
            ``running`` is not the tree ``document`` describes.
        TreeError: the spliced whole tree is not valid (every problem, sorted).
    """
    instantiated = subtree_ids(running)
    if name not in instantiated:
        listed = ", ".join(instantiated) or "none"
        raise SpliceError(f"the running tree has no subtree {name!r}; its subtrees: {listed}")
    spliced = splice_document(document, replacement, name)
    resolution, problems = resolve_document(spliced, registry if registry is not None else default_registry())
    if problems:
        raise TreeError(sorted(set(problems)))
    assert resolution.root is not None and resolution.main is not None
    sites: list[SpliceSite] = []
    wiring = dict(running.wiring)
    _pair(resolution.root, running.root, name, sites, wiring)
    tree = MissionTree(resolution.main, running.root, None, resolution.inputs, wiring, resolution.root)
    return Splice(name, spliced, tree, tuple(sites))


def _pair(resolved: ResolvedNode, behaviour: py_trees.behaviour.Behaviour, name: str, sites: list[SpliceSite],
          wiring: dict[uuid.UUID, dict[str, str]]) -> None:
    """Walk the spliced resolution beside the running tree; build a new instance at each ``SubTree`` of ``name``."""
    if resolved.conditions:  # a Preconditions wrapper around the node (chaser_bt.tree.builder)
        behaviour = getattr(behaviour, "decorated", behaviour)
    if type(behaviour) is not resolved.node_type.cls or behaviour.name != resolved.name:
        raise _not_described(behaviour)
    ref = resolved.spec.subtree if resolved.spec is not None else None
    if ref is not None and ref.tree_id == name and resolved.children:
        top = resolved.children[0]
        new = build_node(top)
        collect_wiring(top, new, wiring)
        old = behaviour.children[0]
        for node in old.iterate():
            wiring.pop(node.id, None)
        sites.append(SpliceSite(behaviour, old, new, top.namespace))
        return
    if len(resolved.children) != len(behaviour.children):
        raise _not_described(behaviour)
    for resolved_child, child in zip(resolved.children, behaviour.children):
        _pair(resolved_child, child, name, sites, wiring)


def _not_described(behaviour: py_trees.behaviour.Behaviour) -> SpliceError:
    """The running tree differs from its document (the file changed after it was read, say)."""
    return SpliceError(f"the running tree is not the one its document describes (at {behaviour.name!r}): "
                       f"retask the whole tree instead")
