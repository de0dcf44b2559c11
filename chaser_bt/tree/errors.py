"""Tree problems as data: every one carries the file, line and column it was found at.

Validation collects :class:`Problem` objects instead of raising at the first, so an author
sees every mistake in a tree at once (DESIGN §4); :class:`TreeError` carries them all.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Problem", "TreeError", "UnknownNode"]


@dataclass(frozen=True, order=True)
class Problem:
    """One thing wrong with a tree file; lines and columns count from 1."""

    file: str
    line: int
    column: int
    message: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}: {self.message}"


class TreeError(Exception):
    """A tree that failed validation; ``problems`` lists every problem found."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


class UnknownNode(KeyError):
    """A node id that no registered behaviour or control node answers to."""

    def __init__(self, node_id: str, known: list[str], suggestions: list[str]) -> None:
        self.node_id = node_id
        self.known = known
        self.suggestions = suggestions
        super().__init__(node_id)

    def __str__(self) -> str:
        # Close matches say more than the whole list (some 75 ids); the list is for a name like none of them.
        if self.suggestions:
            return f"unknown node '{self.node_id}'; did you mean {' or '.join(self.suggestions)}?"
        return f"unknown node '{self.node_id}'; known nodes: {', '.join(self.known)}"
