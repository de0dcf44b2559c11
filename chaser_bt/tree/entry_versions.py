"""BT.CPP's per-entry sequence ids, for WasEntryUpdated, SkipUnlessUpdated and WaitValueUpdate.

Every write to a BT.CPP blackboard entry bumps its ``sequence_id``. py_trees' blackboard keeps
no such count, but every write it makes goes through ``Blackboard.storage[key] = value``, so the
storage is swapped for a dict that counts writes per key (``clear()`` keeps the counts, so a
node that saw version 3 of a key sees a later write after a reset as an update).
"""

from __future__ import annotations

from typing import Any

import py_trees

__all__ = ["entry_version"]


class _VersionedStorage(dict):
    versions: dict[str, int]

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self.versions = {}

    def __setitem__(self, key: str, value: Any) -> None:
        super().__setitem__(key, value)
        self.versions[key] = self.versions.get(key, 0) + 1


def _storage() -> _VersionedStorage:
    storage = py_trees.blackboard.Blackboard.storage
    if not isinstance(storage, _VersionedStorage):
        storage = _VersionedStorage(storage)
        py_trees.blackboard.Blackboard.storage = storage
    return storage


def entry_version(key: str) -> int | None:
    """How many times ``key`` was written, or None when it has no value now."""
    storage = _storage()
    return storage.versions.get(key, 0) if key in storage else None


_storage()
