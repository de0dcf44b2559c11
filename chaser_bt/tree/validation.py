"""Checks a parsed tree against the registry and resolves its blackboard wiring, collecting every problem.

Validation and wiring are one pass: resolving a ``{key}`` reference (through subtree scopes
and BT.CPP remappings) is how a malformed one is found, and coercing a literal is how a
mistyped one is found. The result, a tree of :class:`ResolvedNode`, is all the builder needs,
so a tree that validates cannot fail to build for any reason validation could have seen.

Blackboard scopes follow BT.CPP v4: ``{key}`` in the main tree is ``/key``; each SubTree
instance gets its own scope ``/<instance name>`` in which only the keys its ``SubTree`` node
remaps (or all keys, with ``_autoremap: true``) reach the parent; ``{@key}`` is always the root.
"""

from __future__ import annotations

import difflib
import enum
import logging
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import py_trees
from py_trees.ports_utils import sanitize_name_for_blackboard_use

from chaser_bt.tree.control import SubTree
from chaser_bt.tree.errors import Problem, UnknownNode
from chaser_bt.tree.expressions import ExpressionError, parse_expression
from chaser_bt.tree.model import MAX_DEPTH, POSTCONDITIONS, PRECONDITIONS, SUBTREE_ID, Location, NodeSpec, PortArg, TreeDocument
from chaser_bt.tree.ports import (
    SAME_AS_PORT,
    LiteralError,
    Port,
    btcpp_type,
    coerce_literal,
    convert_from_string,
    finite_violation,
    is_reference_text,
    literal_from_text,
    parse_reference,
    type_name,
)
from chaser_bt.tree.preconditions import BlackboardEnv, Condition, Constant
from chaser_bt.tree.registry import NodeKind, NodeType, Registry

__all__ = ["ResolvedNode", "Resolution", "resolve_document", "typed_literal", "SUBTREE_TYPE"]

logger = logging.getLogger(__name__)

#: The node type of a SubTree instance (a pass-through wrapper around the instantiated tree).
SUBTREE_TYPE = NodeType(SUBTREE_ID, SubTree, NodeKind.DECORATOR)


#: BT.CPP's C++ type for ports whose Python declaration (in composites.py) does not say it.
_BTCPP_PORT_TYPES: dict[tuple[str, str], str] = {(f"Switch{n}", "variable"): "std::string" for n in range(2, 7)}

#: Characters BT.CPP 4.10 refuses in a tree or node ID (``findForbiddenChar``).
_FORBIDDEN_IN_IDS = frozenset(" \t\n\r<>&\"'/\\:*?|.")


@dataclass
class ResolvedNode:
    """A node ready to build: its type, instance name, blackboard scope and port wiring.

    Attributes:
        remappings: port -> absolute blackboard key (``{key}`` references and default keys).
        literals: port -> typed value, stored on the blackboard privately for that node.
        wiring: port -> how a person reads it ("20", "{/alt}"), for display.
        conditions: BT.CPP pre-conditions, in BT.CPP's order of evaluation, then post-conditions.
        scripts: port -> the script a script port (``Script``'s ``code``) holds, bound to the blackboard.
        spec: the node as written (Groot2's monitor writes the tree back from it).
    """

    node_type: NodeType
    name: str
    namespace: str
    location: Location
    remappings: dict[str, str] = field(default_factory=dict)
    literals: dict[str, Any] = field(default_factory=dict)
    wiring: dict[str, str] = field(default_factory=dict)
    children: list[ResolvedNode] = field(default_factory=list)
    conditions: list[Condition] = field(default_factory=list)
    scripts: dict[str, Condition] = field(default_factory=dict)
    spec: NodeSpec | None = field(default=None, compare=False, repr=False)


@dataclass
class Resolution:
    """The main tree, resolved, and the mission inputs as absolute keys."""

    main: str | None
    root: ResolvedNode | None
    inputs: tuple[str, ...]


def resolve_document(document: TreeDocument, registry: Registry) -> tuple[Resolution, list[Problem]]:
    """Validate every tree of ``document`` and resolve the main one; problems sorted by position."""
    return _Resolver(document, registry).run()


def typed_literal(value: Any, data_type: Any, from_text: bool) -> Any:
    """A literal as its port's type: attribute text (XML) is read by :func:`literal_from_text`.

    Raises:
        LiteralError: the value does not fit the port.
    """
    if from_text and isinstance(value, str):
        return literal_from_text(value, data_type)
    return coerce_literal(value, data_type)


def _show(value: Any) -> str:
    """A literal as a person reads it: enum members by name, strings quoted."""
    if isinstance(value, enum.Enum):
        return value.name
    return repr(value) if isinstance(value, str) else str(value)


@dataclass(frozen=True)
class _Literal:
    """A SubTree port given a literal: the subtree's key holds that value."""

    value: Any
    location: Location
    from_text: bool = False


_INT_TEXT = re.compile(r"-?\d+")
_DOUBLE_TEXT = re.compile(r"-?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)", re.IGNORECASE)


def subtree_literal(value: Any, from_text: bool) -> Any:
    """A SubTree literal as a script in the subtree sees it, as BT.CPP 4.10 stores it in the subtree's blackboard.

    From XML text: an integer (no ``.``, ``e``) is an int, another number a float, anything else the
    text itself (``true``, ``0x1F``, ``1;2``). A YAML literal keeps its type.
    """
    if not from_text or not isinstance(value, str):
        return value
    if _INT_TEXT.fullmatch(value) and -(2**63) <= int(value) < 2**63:
        return int(value)
    if _DOUBLE_TEXT.fullmatch(value):
        return float(value)
    return value


@dataclass(frozen=True)
class _Declared:
    """A blackboard entry as the first port wired to it declared it (BT.CPP creates it when the tree loads)."""

    cpp: str | None
    data_type: Any
    what: str
    location: Location


class _DeclaredEnv(BlackboardEnv):
    """A script's blackboard, where an entry a port declares exists before anything writes it (BT.CPP).

    Text assigned to such an entry is converted as the declaring port reads text (``converter``).
    """

    def __init__(self, bindings: dict[str, str | Constant], declared: dict[str, _Declared]) -> None:
        super().__init__(bindings)
        self.declared = declared

    def has(self, name: str) -> bool:
        binding = self.bindings[name]
        return super().has(name) or (isinstance(binding, str) and binding in self.declared)

    def converter(self, name: str) -> Any:
        binding = self.bindings[name]
        declared = self.declared.get(binding) if isinstance(binding, str) else None
        if declared is None or declared.cpp is None:
            return None
        return lambda text: convert_from_string(text, declared.data_type, declared.cpp)


@dataclass(frozen=True)
class _Script(Condition):
    """A :class:`Condition` run against its tree's declared entries (:class:`_DeclaredEnv`)."""

    declared: dict[str, _Declared] = field(default_factory=dict, compare=False, repr=False)

    def run(self) -> Any:
        return self.expression.run(_DeclaredEnv(self.bindings, self.declared))


_Binding = str | _Literal


@dataclass
class _Scope:
    namespace: str
    bindings: dict[str, _Binding] = field(default_factory=dict)
    parent: _Scope | None = None
    autoremap: bool = False

    def resolve(self, key: str) -> _Binding:
        if key.startswith("@"):
            return "/" + key[1:]
        if key in self.bindings:
            return self.bindings[key]
        # _autoremap passes every key through but the private ones (``_name``), as BT.CPP does.
        if self.autoremap and self.parent is not None and not key.startswith("_"):
            return self.parent.resolve(key)
        return py_trees.blackboard.Blackboard.absolute_name(self.namespace, key)


@dataclass(frozen=True)
class _Read:
    key: str
    location: Location
    text: str


class _Resolver:
    def __init__(self, document: TreeDocument, registry: Registry) -> None:
        self.document = document
        self.registry = registry
        self.problems: list[Problem] = []
        self.instantiated: set[str] = set()
        self.namespaces: set[str] = set()
        self.writes: set[str] = set()
        self.reads: list[_Read] = []
        #: absolute key -> the entry as its first port declared it, in BT.CPP's order of creation
        #: (depth first, a node before its children); shared with every script of the tree.
        self.declared: dict[str, _Declared] = {}

    def problem(self, location: Location, message: str) -> None:
        self.problems.append(Problem(location.file, location.line, location.column, message))

    def file_problem(self, message: str) -> None:
        self.problems.append(Problem(self.document.source, 1, 1, message))

    # ---- document

    def run(self) -> tuple[Resolution, list[Problem]]:
        self.check_tree_ids()
        inputs = self.inputs()
        main = self.main_tree()
        root = None
        if main is not None:
            self.instantiated.add(main)
            root = self.tree(main, _Scope("/"), (main,))
            self.check_data_flow(set(inputs))
        # Trees no instance reaches are still checked, each in a scope of its own.
        for tree_id in self.document.trees:
            if tree_id not in self.instantiated:
                self.instantiated.add(tree_id)
                self.tree(tree_id, _Scope(self.namespace("/", tree_id)), (tree_id,))
        problems = sorted(set(self.problems))
        return Resolution(main, root, tuple(inputs)), problems

    def check_tree_ids(self) -> None:
        """BT.CPP's rules for a tree ID (``validateModelName``): what it refuses at load is refused here."""
        for tree_id, tree in self.document.trees.items():
            forbidden = next((c for c in tree_id if c in _FORBIDDEN_IN_IDS), None)
            if tree_id in ("Root", "root"):
                self.problem(tree.location, f"tree ID '{tree_id}' is reserved (BehaviorTree.CPP refuses it)")
            elif forbidden is not None:
                self.problem(tree.location, f"tree ID {tree_id!r} contains {forbidden!r}, which BehaviorTree.CPP refuses in IDs")
            elif tree_id in self.registry:
                self.problem(tree.location, f"tree ID '{tree_id}' is the name of a registered node: BehaviorTree.CPP refuses it")

    def inputs(self) -> list[str]:
        keys: list[str] = []
        for arg in self.document.inputs:
            try:
                key = parse_reference("{" + str(arg.value) + "}")
            except ValueError:
                self.problem(arg.location, f"input {arg.value!r} is not a blackboard key name")
                continue
            absolute = "/" + key.lstrip("@")
            if key == SAME_AS_PORT:
                self.problem(arg.location, "an input is a key name, not '='")
            elif absolute in keys:
                self.problem(arg.location, f"input '{arg.value}' is listed twice")
            else:
                keys.append(absolute)
        return keys

    def main_tree(self) -> str | None:
        trees = self.document.trees
        if not trees:
            return None
        if self.document.main is not None:
            if self.document.main in trees:
                return self.document.main
            location = self.document.main_location or Location(self.document.source, 1, 1)
            self.problem(location, f"main '{self.document.main}' names no tree; trees: {', '.join(trees)}")
            return None
        if len(trees) == 1:
            return next(iter(trees))
        self.file_problem(f"several trees ({', '.join(trees)}): name the one to execute with 'main'")
        return None

    def tree(self, tree_id: str, scope: _Scope, stack: tuple[str, ...]) -> ResolvedNode | None:
        root = self.document.trees[tree_id].root
        return None if root is None else self.node(root, scope, stack)

    def namespace(self, parent: str, name: str) -> str:
        """A blackboard scope for a subtree instance, unique among the instances in this tree."""
        base = py_trees.blackboard.Blackboard.absolute_name(parent, sanitize_name_for_blackboard_use(name))
        candidate, suffix = base, 2
        while candidate in self.namespaces:
            candidate, suffix = f"{base}_{suffix}", suffix + 1
        self.namespaces.add(candidate)
        return candidate

    def check_data_flow(self, inputs: set[str]) -> None:
        """A required port reading a key that nothing writes would wait forever: say so before flight."""
        written = self.writes | inputs
        for read in self.reads:
            if read.key not in written:
                self.problem(
                    read.location,
                    f"{read.text} reads '{read.key}', which no node writes and 'inputs' does not list",
                )

    # ---- nodes

    def node(self, spec: NodeSpec, scope: _Scope, stack: tuple[str, ...]) -> ResolvedNode | None:
        resolved = self.plain_node(spec, scope, stack)
        conditions = self.conditions(spec, scope)
        if resolved is not None:
            resolved.conditions = conditions
            resolved.spec = spec
        return resolved

    def conditions(self, spec: NodeSpec, scope: _Scope) -> list[Condition]:
        """Parse the node's pre- and post-conditions; their names resolve in the node's own scope, as its ports do."""
        conditions = []
        for kind in (*PRECONDITIONS, *POSTCONDITIONS):
            arg = spec.conditions.get(kind)
            if arg is not None:
                script = self.script(kind, str(arg.value), arg.value_at, scope, f"{kind} of {spec.node_id}")
                if script is not None:
                    conditions.append(script)
        return conditions

    def script(self, kind: str, text: str, location: Location, scope: _Scope, what: str) -> Condition | None:
        """A BT.CPP script bound to the blackboard keys of ``scope`` (None, with a problem, when malformed)."""
        try:
            expression = parse_expression(text, self.registry.scripting_enums)
        except ExpressionError as e:
            self.problem(location, f"{what}: {e}")
            return None
        bindings: dict[str, str | Constant] = {}
        for variable in expression.variables:
            binding = scope.resolve(variable)
            if isinstance(binding, _Literal):
                bindings[variable] = Constant(subtree_literal(binding.value, binding.from_text))
            else:
                bindings[variable] = binding
                if variable in expression.assigned:
                    self.writes.add(binding)
                else:
                    self.reads.append(_Read(binding, location, what))
        return _Script(kind, expression, bindings, self.declared)

    def plain_node(self, spec: NodeSpec, scope: _Scope, stack: tuple[str, ...]) -> ResolvedNode | None:
        if spec.node_id == SUBTREE_ID:
            return self.subtree(spec, scope, stack)
        try:
            node_type = self.registry.get(spec.node_id)
        except UnknownNode as e:
            self.problem(spec.location, str(e))
            for child in spec.children:
                self.node(child, scope, stack)
            return None
        self.check_children(spec, node_type)
        resolved = ResolvedNode(node_type, spec.display_name, scope.namespace, spec.location)
        # Ports before children: BT.CPP creates a node's entries before its children's.
        for port, arg in spec.ports.items():
            self.port(spec, node_type, port, arg, scope, resolved)
        self.unwired_ports(spec, node_type, scope, resolved)
        self.check_values(spec, node_type, resolved)
        children = [self.node(child, scope, stack) for child in spec.children]
        resolved.children = [child for child in children if child is not None]
        return resolved

    def check_children(self, spec: NodeSpec, node_type: NodeType) -> None:
        if spec.node_id == "ReactiveSequence":
            for child in spec.children:
                if child.explicit_tag is not None:
                    self.problem(
                        child.location,
                        f"BehaviorTree.CPP 4.10 cannot load <{child.explicit_tag} ID=\"{child.node_id}\"> directly under "
                        f"a ReactiveSequence (it looks the tag up as a node id): write <{child.node_id} .../>",
                    )
        if spec.unreadable_children:
            return
        count = len(spec.children)
        if node_type.kind is NodeKind.CONTROL and count == 0:
            self.problem(spec.location, f"{spec.node_id} is a composite: give it 'children: [...]'")
        elif node_type.kind is NodeKind.DECORATOR and count != 1:
            self.problem(spec.location, f"{spec.node_id} is a decorator: give it exactly one 'child', got {count}")
        elif node_type.kind.is_leaf and count:
            self.problem(spec.location, f"{spec.node_id} is a leaf ({node_type.kind.value}): it takes no children")

    def port(
        self, spec: NodeSpec, node_type: NodeType, port: str, arg: PortArg, scope: _Scope, resolved: ResolvedNode
    ) -> None:
        declaration = node_type.port(port)
        if declaration is None:
            names = node_type.port_names()
            close = difflib.get_close_matches(port, names, n=2)
            if close:
                listed = f"did you mean {' or '.join(close)}?"
            else:
                listed = f"its ports: {', '.join(names)}" if names else "it has no ports"
            self.problem(arg.location, f"{spec.node_id} has no port '{port}'; {listed}")
            return
        is_output = port in node_type.output_ports
        if port in getattr(node_type.cls, "SCRIPT_PORTS", ()) and not is_reference_text(arg.value):
            script = self.script(port, str(arg.value), arg.value_at, scope, f"port '{port}' of {spec.node_id}")
            if script is not None:
                resolved.scripts[port] = script
                resolved.literals[port] = str(arg.value)
                resolved.wiring[port] = repr(str(arg.value))
            return
        names_entry = port in getattr(node_type.cls, "KEY_NAME_PORTS", ())
        if names_entry:
            arg = self.key_name(spec, port, arg, getattr(node_type.cls, "BRACES_ARE_OLD_FORM", True))
            if arg is None:
                return
        if not is_reference_text(arg.value):
            if is_output:
                self.problem(
                    arg.value_at, f"output port '{port}' of {spec.node_id} takes a {{key}} reference, got {arg.value!r}"
                )
                return
            self.literal(spec, port, declaration, arg.value, arg.value_at, resolved, arg.from_text)
            return
        try:
            key = parse_reference(arg.value)
        except ValueError as e:
            self.problem(arg.value_at, f"port '{port}' of {spec.node_id}: {e}")
            return
        binding = scope.resolve(port if key == SAME_AS_PORT else key)
        if not names_entry and not isinstance(binding, _Literal):
            # (a port naming an entry, SetBlackboard's output_key, declares nothing in BT.CPP)
            self.declare(binding, spec, node_type, port, declaration, is_output, arg.value_at)
        if isinstance(binding, _Literal):
            if is_output:
                self.problem(
                    arg.value_at,
                    f"output port '{port}' of {spec.node_id} is wired to {arg.value}, "
                    "which its SubTree sets to a literal",
                )
                return
            self.literal(spec, port, declaration, binding.value, binding.location, resolved, binding.from_text)
            return
        resolved.remappings[port] = binding
        resolved.wiring[port] = "{" + binding + "}"
        if is_output:
            self.writes.add(binding)
        elif declaration.required and not declaration.has_default:
            self.reads.append(_Read(binding, arg.value_at, f"port '{port}' of {spec.node_id}"))

    def declare(
        self, key: str, spec: NodeSpec, node_type: NodeType, port: str, declaration: Any, is_output: bool,
        location: Location,
    ) -> None:
        """BT.CPP's entry creation when a tree loads: the first port wired to an entry gives its type.

        A later port of another type is refused, as BT.CPP refuses it ("the port was initially created
        with type [int] and, later type [std::string] was used somewhere else"), unless the entry is
        text, which every input reads by conversion; an output writing another type into a text entry
        loads in BT.CPP and throws at the write: refused here before flight.
        """
        cpp = _BTCPP_PORT_TYPES.get((node_type.node_id, port), btcpp_type(declaration))
        what = f"port '{port}' of {spec.node_id}"
        previous = self.declared.get(key)
        if previous is None:
            self.declared[key] = _Declared(cpp, declaration.data_type, what, location)
            return
        if previous.cpp is None or cpp is None or previous.cpp == cpp:
            return
        first = f"{previous.what} (line {previous.location.line}) declared it {previous.cpp}"
        if previous.cpp != "std::string":
            self.problem(
                location,
                f"{what} uses the blackboard entry '{key}' as {cpp}, but {first}: BehaviorTree.CPP refuses "
                "a port type that differs from the entry's when the tree loads",
            )
        elif is_output:
            self.problem(
                location,
                f"{what} writes {cpp} into the blackboard entry '{key}', but {first}: BehaviorTree.CPP "
                "throws at that write (once declared, the type of a port shall not change)",
            )

    def key_name(self, spec: NodeSpec, port: str, arg: PortArg, braces_are_old_form: bool = True) -> PortArg | None:
        """A port whose value names a blackboard entry (BT.CPP's ``SetBlackboard output_key="x"``), as a reference.

        The old chaser-bt form ``output_key="{x}"`` still loads, with a warning saying how to fix it
        (BT.CPP would read entry x's *value* as the name, and fail).
        """
        text = str(arg.value).strip()
        if is_reference_text(text) and not braces_are_old_form:
            return arg
        if is_reference_text(text):
            where = arg.value_at
            logger.warning(
                "%s:%d:%d: %s %s=%r is the old form: BehaviorTree.CPP reads the text as the entry's name, "
                "write %s=%r",
                where.file, where.line, where.column, spec.node_id, port, text, port, text.strip("{}"),
            )
            return arg
        if not text:
            self.problem(arg.value_at, f"port '{port}' of {spec.node_id} needs the name of a blackboard entry")
            return None
        return PortArg("{" + text + "}", arg.location, arg.value_location, from_text=False)

    def literal(
        self,
        spec: NodeSpec,
        port: str,
        declaration: Any,
        value: Any,
        location: Location,
        resolved: ResolvedNode,
        from_text: bool = False,
    ) -> None:
        try:
            typed = typed_literal(value, declaration.data_type, from_text)
        except LiteralError as e:
            self.problem(location, f"port '{port}' of {spec.node_id}: {e}")
            return
        violation = declaration.violation(typed) if isinstance(declaration, Port) else finite_violation(typed)
        if violation is not None:
            self.problem(location, f"port '{port}' of {spec.node_id} {violation}")
            return
        resolved.literals[port] = typed
        resolved.wiring[port] = _show(typed)

    def unwired_ports(self, spec: NodeSpec, node_type: NodeType, scope: _Scope, resolved: ResolvedNode) -> None:
        for port in node_type.port_names():
            if port in spec.ports:
                continue
            declaration = node_type.port(port)
            default_key = getattr(declaration, "default_key", None)
            if default_key is not None:
                key = py_trees.blackboard.Blackboard.absolute_name(scope.namespace, default_key)
                resolved.remappings[port] = key
                resolved.wiring[port] = "{" + key + "}"
                if port in node_type.output_ports:
                    self.writes.add(key)
            elif declaration.required and not declaration.has_default:
                self.problem(
                    spec.location,
                    f"{spec.node_id} is missing required port '{port}' ({type_name(declaration.data_type)}: "
                    f"{declaration.description})",
                )

    def check_values(self, spec: NodeSpec, node_type: NodeType, resolved: ResolvedNode) -> None:
        check = getattr(node_type.cls, "check_ports", None)
        if check is None:
            return
        known = {
            port: declaration.default_value
            for port, declaration in node_type.input_ports.items()
            if declaration.has_default and port not in resolved.remappings
        }
        known.update(resolved.literals)
        for port, message in check(known, len(spec.children)):
            arg = spec.ports.get(port)
            self.problem(arg.value_at if arg else spec.location, f"{spec.node_id}: {message}")

    # ---- subtrees

    def subtree(self, spec: NodeSpec, scope: _Scope, stack: tuple[str, ...]) -> ResolvedNode | None:
        ref = spec.subtree
        if ref is None:
            return None
        if spec.children:
            self.problem(spec.location, "SubTree takes no children: it instantiates the tree named by ID")
        tree = self.document.trees.get(ref.tree_id)
        if tree is None:
            trees = ", ".join(self.document.trees) or "none"
            self.problem(ref.location, f"SubTree ID '{ref.tree_id}' names no tree in this file; trees: {trees}")
            return None
        if ref.tree_id in stack:
            self.problem(ref.location, f"SubTree '{ref.tree_id}' is recursive: {' -> '.join((*stack, ref.tree_id))}")
            return None
        if len(stack) >= MAX_DEPTH:
            self.problem(ref.location, f"SubTrees nested deeper than {MAX_DEPTH}")
            return None
        self.instantiated.add(ref.tree_id)
        used = set(self.keys_used(ref.tree_id, set()))
        bindings: dict[str, _Binding] = {}
        # BT.CPP applies a <TreeNodesModel> default only to an instance without _autoremap.
        defaults = {} if ref.autoremap else self.document.subtree_defaults.get(ref.tree_id, {})
        ports = {**{p: a for p, a in defaults.items() if p in used}, **spec.ports}
        name = spec.name or ref.tree_id
        namespace = self.namespace(scope.namespace, name)
        for port, arg in ports.items():
            if port not in used:
                listed = ", ".join(sorted(used)) or "none"
                self.problem(arg.location, f"SubTree '{ref.tree_id}' uses no key '{port}'; its keys: {listed}")
            if not is_reference_text(arg.value):
                # Typed by the ports that read it (BT.CPP 4.10 makes "3" an int entry, which a double
                # or unsigned port then refuses at load; chaser-bt does not: see docs/trees.md).
                bindings[port] = _Literal(arg.value, arg.value_at, arg.from_text)
                continue
            try:
                key = parse_reference(arg.value)
            except ValueError as e:
                self.problem(arg.value_at, f"SubTree port '{port}': {e}")
                continue
            bindings[port] = scope.resolve(port if key == SAME_AS_PORT else key)
        child_scope = _Scope(namespace, bindings, scope, ref.autoremap)
        root = self.tree(ref.tree_id, child_scope, (*stack, ref.tree_id))
        resolved = ResolvedNode(SUBTREE_TYPE, name, scope.namespace, spec.location)
        resolved.wiring = {
            port: (_show(b.value) if isinstance(b, _Literal) else "{" + b + "}") for port, b in bindings.items()
        }
        if root is not None:
            resolved.children = [root]
        return resolved

    def keys_used(self, tree_id: str, visited: set[str]) -> Iterator[str]:
        """The scope-local keys a tree references (through autoremapped subtrees too)."""
        if tree_id in visited or tree_id not in self.document.trees:
            return
        visited.add(tree_id)
        root = self.document.trees[tree_id].root
        stack = [root] if root is not None else []
        while stack:
            node = stack.pop()
            stack.extend(node.children)
            for port, arg in node.ports.items():
                if is_reference_text(arg.value):
                    try:
                        key = parse_reference(arg.value)
                    except ValueError:
                        continue
                    if not key.startswith("@"):
                        yield port if key == SAME_AS_PORT else key
            scripts = list(node.conditions.values())
            if node.node_id in self.registry:
                script_ports = getattr(self.registry.get(node.node_id).cls, "SCRIPT_PORTS", ())
                scripts += [arg for port, arg in node.ports.items() if port in script_ports]
            for arg in scripts:
                try:
                    variables = parse_expression(str(arg.value), self.registry.scripting_enums).variables
                except ExpressionError:
                    continue
                yield from (v for v in variables if not v.startswith("@"))
            if node.subtree is not None and node.subtree.autoremap:
                yield from self.keys_used(node.subtree.tree_id, visited)

