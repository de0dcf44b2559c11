"""The trees and scenarios chaser-bt ships, found by name: ``chaser-bt rehearse chase --scenario chase``.

Where they are:

- trees: the repository's ``trees/`` (with ``subtrees/``). A wheel carries them as this package's
  ``trees/`` folder (pyproject.toml maps the package ``chaser_bt.shipped.trees`` onto ``trees/``); a
  source checkout has no such folder here and reads ``trees/`` itself, so ``trees/chase.yaml`` stays
  the path the docs and tests use.
- scenarios: the ``sitl`` package's ``scenarios/`` folder, in a checkout and in a wheel alike. It is
  located, not imported (chaser_bt never imports sitl; docs/design.md §2).

A name is a shipped file's path in its folder without the suffix (``chase``: ``chase.yaml`` before
``chase.xml``; ``hard/crossing``), or with it (``chase.xml``). :func:`resolve_tree` and
:func:`resolve_scenario` (and :func:`resolve_scenarios`, which also knows shipped folders: ``hard``) take what a user typed: an existing file or folder is that path, as before; else a
shipped name is its file; else anything written as a path (it has a ``/``) is that path, and whoever reads it
reports it missing; and a word that is none of these raises :class:`NotShipped`, one line naming the shipped
ones.
"""

from __future__ import annotations

import difflib
import importlib.util
import os
from pathlib import Path

__all__ = [
    "NotShipped", "TREE_SUFFIXES", "SCENARIO_SUFFIXES", "trees_dir", "scenarios_dir", "shipped_trees",
    "shipped_scenarios", "shipped_files", "resolve_tree", "resolve_scenario", "resolve_scenarios",
]

#: Tree files, in the order a bare stem prefers them (``chase`` is chase.yaml; chase.xml is its BT.CPP copy).
TREE_SUFFIXES = (".yaml", ".yml", ".xml")
SCENARIO_SUFFIXES = (".yaml", ".yml")

_HERE = Path(__file__).resolve().parent


class NotShipped(ValueError):
    """A bare name that is neither a file nor a shipped tree or scenario; the message lists the shipped names."""


def trees_dir() -> Path | None:
    """The shipped trees' folder: this package's ``trees/`` in a wheel, the checkout's ``trees/`` in a checkout."""
    packaged = _HERE / "trees"
    if packaged.is_dir():
        return packaged
    root = _HERE.parents[1]  # the checkout's root: chaser_bt/shipped -> chaser_bt -> .
    if (root / "pyproject.toml").is_file() and (root / "trees").is_dir():
        return root / "trees"
    return None


def scenarios_dir() -> Path | None:
    """The shipped scenarios' folder: ``scenarios/`` of the ``sitl`` package (found without importing it).

    sitl is chaser_bt's sibling in a wheel's install and in a checkout alike; failing that, wherever the
    import system would find it.
    """
    beside = _HERE.parents[1] / "sitl"
    locations = [beside] if (beside / "__init__.py").is_file() else []
    spec = importlib.util.find_spec("sitl")
    locations += [Path(p) for p in ((spec.submodule_search_locations or ()) if spec is not None else ())]
    for location in locations:
        if (location / "scenarios").is_dir():
            return location / "scenarios"
    return None


def shipped_files(folder: Path | None, suffixes: tuple[str, ...], parts: str | None = None) -> dict[str, list[Path]]:
    """Name -> its files in ``folder``, preferred suffix first.

    A name is the file's path in ``folder`` without its suffix, ``/``-separated (``chase``, ``hard/crossing``);
    those at the top come first, each group sorted. Files under ``folder/parts`` (the trees' ``subtrees/``:
    parts of trees, not missions) are left out.
    """
    if folder is None:
        return {}
    found: dict[str, list[Path]] = {}
    for path in folder.rglob("*"):
        relative = path.relative_to(folder)
        if path.suffix in suffixes and relative.parts[0] != parts and path.is_file():
            found.setdefault(relative.with_suffix("").as_posix(), []).append(path)
    return {name: sorted(found[name], key=lambda p: suffixes.index(p.suffix))
            for name in sorted(found, key=lambda name: ("/" in name, name))}


def shipped_trees() -> dict[str, list[Path]]:
    """Each shipped tree's name and its files (``chase``: chase.yaml, chase.xml); subtrees/ holds parts, not trees."""
    return shipped_files(trees_dir(), TREE_SUFFIXES, parts="subtrees")


def shipped_scenarios() -> dict[str, list[Path]]:
    """Each shipped scenario's name and its file."""
    return shipped_files(scenarios_dir(), SCENARIO_SUFFIXES)


def resolve_tree(text: str | os.PathLike) -> Path:
    """The tree file ``text`` means: a path as given, or a shipped tree's file (see the module's docstring)."""
    return _resolve(text, "tree", trees_dir(), shipped_trees())


def resolve_scenario(text: str | os.PathLike) -> Path:
    """The scenario file ``text`` means: a path as given, or a shipped scenario's file."""
    return _resolve(text, "scenario", scenarios_dir(), shipped_scenarios())


def resolve_scenarios(text: str | os.PathLike) -> Path:
    """A scenario file or a folder of them: a path as given, a shipped folder's name (``hard``), or a
    shipped scenario's name (``retask/chase_then_sar``)."""
    folder = scenarios_dir()
    word = os.fspath(text).replace(os.sep, "/").strip("/")
    if not Path(text).exists() and folder is not None and word and (folder / word).is_dir():
        return folder / word
    return resolve_scenario(text)


def _resolve(text: str | os.PathLike, what: str, folder: Path | None, shipped: dict[str, list[Path]]) -> Path:
    path = Path(text)
    if path.exists():
        return path
    word = os.fspath(text).replace(os.sep, "/")
    if word in shipped:  # a name: chase, hard/crossing
        return shipped[word][0]
    for files in shipped.values():  # a file's name: chase.xml, hard/crossing.yaml
        for file in files:
            if file.relative_to(folder).as_posix() == word:
                return file
    if _written_as_path(os.fspath(text)):  # whoever reads it says what is wrong with it
        return path
    names = list(shipped)
    stem = word.rsplit(".", 1)[0] if Path(word).suffix in TREE_SUFFIXES else word
    close = difflib.get_close_matches(stem, names, n=1, cutoff=0.6)
    hint = f" (did you mean {close[0]}?)" if close else ""
    listed = ", ".join(names) if names else "none found"
    raise NotShipped(f"no {what} file or shipped {what} named {word!r}{hint}; shipped {what}s: {listed}")


def _written_as_path(word: str) -> bool:
    """``word`` names a path rather than a shipped name: it has a folder separator (``./x.yaml``, ``~/t.xml``)."""
    return any(sep and sep in word for sep in (os.sep, os.altsep))
