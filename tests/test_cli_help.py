"""Every command's ``--help``, read from the parser ``chaser-bt`` itself builds.

Each option that takes a value names it with a short metavar of its own (``S``, ``DEG``, ``FILE``; never
argparse's upper-cased dest, ``HFOV_DEG``) and says its default, or that it is required; every argument has
help; positional arguments are upper-case, one name for one kind of thing; and every seed defaults alike.
"""

from __future__ import annotations

import argparse
import re

import pytest

from chaser_bt.cli import DEFAULT_SEED, _parser


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def _command(name: str) -> argparse.ArgumentParser:
    """The top-level parser, or ``name``'s: built as ``chaser-bt name`` builds it (sitl/ commands only when named)."""
    if name == "chaser-bt":
        return _parser([])
    return _subcommands(_parser([name]))[name]


COMMANDS = ["chaser-bt", *_subcommands(_parser([]))]


def _arguments(name: str) -> list[argparse.Action]:
    return [a for a in _command(name)._actions if not isinstance(a, argparse._HelpAction)]


def _takes_value(action: argparse.Action) -> bool:
    return bool(action.option_strings) and action.nargs != 0


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The help line as ``--help`` prints it (``%(default)s`` filled in)."""
    return parser._get_formatter()._expand_help(action)


def _label(action: argparse.Action) -> str:
    return "/".join(action.option_strings) or action.dest


def test_every_command_is_walked():
    assert {"validate", "run", "rehearse", "campaign", "search-trial", "sitl", "train-refiner"} <= set(COMMANDS)
    assert _command("campaign").get_default("handler") is not None  # the real parser, not the --help placeholder


@pytest.mark.parametrize("name", COMMANDS)
def test_every_argument_has_help(name):
    missing = [_label(a) for a in _arguments(name) if not a.help or a.help == argparse.SUPPRESS]
    assert not missing, f"{name}: no help for {missing}"


@pytest.mark.parametrize("name", COMMANDS)
def test_value_options_name_their_value_themselves(name):
    """A metavar of the option's own, not the dest argparse upper-cases (``--hfov-deg HFOV_DEG``).

    An option with choices and no metavar shows them (``{unicode,dot}``), which names the value too.
    """
    bad = []
    for action in filter(_takes_value, _arguments(name)):
        metavar = action.metavar
        if metavar is None and action.choices is not None:
            continue
        names = metavar if isinstance(metavar, tuple) else (metavar,)
        if any(m is None or not m or m == action.dest.upper() for m in names):
            bad.append(f"{_label(action)} {metavar!r}")
    assert not bad, f"{name}: value options without a metavar of their own: {bad}"


@pytest.mark.parametrize("name", COMMANDS)
def test_value_options_state_their_default_or_that_they_are_required(name):
    parser = _command(name)
    bad = []
    for action in filter(_takes_value, _arguments(name)):
        text = _help(parser, action)
        word = r"\brequired\b" if action.required else r"\bdefault\b"
        if not re.search(word, text, re.IGNORECASE):
            bad.append(f"{_label(action)}: {text!r}")
    assert not bad, f"{name}: help without its default (or, for a required option, 'required'): {bad}"


@pytest.mark.parametrize("name", COMMANDS)
def test_positional_arguments_are_upper_case(name):
    bad = [f"{a.dest} {a.metavar!r}" for a in _arguments(name)
           if not a.option_strings and not (isinstance(a.metavar, str) and a.metavar and a.metavar == a.metavar.upper())]
    assert not bad, f"{name}: positional arguments not shown upper-case: {bad}"


def test_one_kind_of_positional_argument_has_one_name_everywhere():
    names: dict[str, set[str]] = {}
    for name in COMMANDS:
        for action in _arguments(name):
            if not action.option_strings:
                names.setdefault(action.dest, set()).add(action.metavar)
    assert {dest: shown for dest, shown in names.items() if len(shown) > 1} == {}
    assert names["tree"] == {"TREE"} and names["log"] == {"LOG"}


def test_every_seed_defaults_to_rehearses():
    seeds = {}
    for name in COMMANDS:
        for action in _arguments(name):
            if "--seed" in action.option_strings:
                seeds[name] = action.default
            elif "--seeds" in action.option_strings:  # a campaign's list starts where a single run's seed is
                seeds[name] = action.type(action.default)[0] if isinstance(action.default, str) else action.default[0]
    assert {"rehearse", "sitl", "campaign", "search-trial", "train-detector"} <= set(seeds)
    assert seeds == dict.fromkeys(seeds, DEFAULT_SEED)


@pytest.mark.parametrize("name", COMMANDS)
def test_an_option_whose_value_may_be_left_out_says_it_is_off_without_it(name):
    """``--groot2 [PORT]``: the default PORT is not the option's default, which is off."""
    parser = _command(name)
    bad = [_label(a) for a in _arguments(name) if a.nargs == "?" and a.option_strings and a.default is None
           and not re.search(r"default: (off|none|no)\b", _help(parser, a))]
    assert not bad, f"{name}: {bad} do not say they are off by default"
