"""BT.CPP's node categories, on their own so the built-in nodes can name theirs without importing the registry."""

from __future__ import annotations

import enum

__all__ = ["NodeKind"]


class NodeKind(enum.Enum):
    """BT.CPP's node categories (the tags of a ``<TreeNodesModel>``)."""

    ACTION = "Action"
    CONDITION = "Condition"
    CONTROL = "Control"
    DECORATOR = "Decorator"

    @property
    def is_leaf(self) -> bool:
        return self in (NodeKind.ACTION, NodeKind.CONDITION)
