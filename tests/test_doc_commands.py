"""Every command the README and docs/ show in a console block works as shown.

Cheap ones (validate, show, nodes, convert, export-model, chase-geometry) are run; the others are
parsed by the real command line (every option exists, every value is accepted, every file in the
repository it names exists), and benchmark scripts answer ``--help``. Flights are left to the
end-to-end tests.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from chaser_bt.cli import _parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RUN = {"validate", "show", "nodes", "convert", "export-model", "chase-geometry", "calibrate"}


def _commands() -> list[tuple[str, str]]:
    """(doc, command) for each command line in a fenced block, prompt, ``.venv/bin/`` and comment removed."""
    found = []
    for doc in DOCS:
        for block in re.finditer(r"```(\w*)\n(.*?)```", doc.read_text(), re.S):
            for line in block.group(2).splitlines():
                line = line.strip().removeprefix("$ ").split("  #")[0].split(" # ")[0].strip()
                line = line.replace(".venv/bin/", "")
                if block.group(1) in ("sh", "console", "bash") or re.match(r"(chaser-bt|python) ", line):
                    if line and not line.startswith("#"):
                        found.append((doc.name, line))
    return found


COMMANDS = _commands()


def test_the_docs_show_commands():
    assert len(COMMANDS) > 30


@pytest.mark.parametrize("doc,command", COMMANDS, ids=[f"{d}: {c[:60]}" for d, c in COMMANDS])
def test_a_documented_command_works_as_shown(doc, command, tmp_path, capsys, monkeypatch):
    words = [w for w in shlex.split(command.replace("[", "").replace("]", ""))]
    for word in words:  # files of the repository the command names
        if re.match(r"(trees|sitl|docs|benchmarks|tests)/", word) and not word.endswith((".png", "/")):
            assert (ROOT / word.split("::")[0]).exists(), f"{doc}: {command}: no {word}"
    if words[0] == "make":
        assert re.search(rf"^{words[1]}:", (ROOT / "Makefile").read_text(), re.M), f"{doc}: no make target {words[1]}"
    elif words[0] == "python" and words[1] != "-m":
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        done = subprocess.run([sys.executable, words[1], "--help"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        for option in (w for w in words[2:] if w.startswith("--")):
            assert option in done.stdout, f"{doc}: {command}: {words[1]} has no {option}"
    elif words[0] == "python" and words[2] == "pytest":  # python -m pytest PATHS: the paths exist (checked above)
        pass
    elif words[0] == "python":  # python -m MODULE ...: run in the scratch folder
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        done = subprocess.run([sys.executable, *words[1:]], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
    else:
        assert words[0] == "chaser-bt", command
        argv = words[1:words.index(">")] if ">" in words else words[1:]
        monkeypatch.chdir(tmp_path)  # outputs a doc names land in a scratch folder
        if argv[0] == "calibrate":  # the flight the doc writes first
            subprocess.run([sys.executable, "-m", "sitl.bench.radar_trials", argv[1]], cwd=tmp_path, check=True,
                           env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, timeout=120)
        if any(re.fullmatch(r"[A-Z][A-Z_]*", w) for w in argv):  # a synopsis (TREE, DIR ...): its options exist
            sub = _parser(argv)._subparsers._group_actions[0].choices[argv[0]]
            for option in (w for w in argv if w.startswith("-")):
                assert option in sub._option_string_actions, f"{doc}: {command}: no option {option}"
            return
        for i, word in enumerate(argv):
            if i == 0:
                continue
            if (ROOT / word).exists() and not Path(word).is_absolute():
                argv[i] = str(ROOT / word)
            elif word.startswith("/tmp/"):
                argv[i] = str(tmp_path / Path(word).name)
        if argv[0] == "chase-geometry" and "--plot" in argv:
            argv[argv.index("--plot") + 1] = str(tmp_path / "figure.png")
        args = _parser(argv).parse_args(argv)
        if argv[0] in RUN:
            assert args.handler(args) == 0, capsys.readouterr().err


def _inline_commands() -> list[tuple[str, str]]:
    """(doc, command) for each ``chaser-bt ...`` span in the prose (often a synopsis with TREE, FILE ...)."""
    found = []
    for doc in DOCS:
        prose = re.sub(r"```.*?```", "", doc.read_text(), flags=re.S)
        for span in re.finditer(r"`((?:\.venv/bin/)?chaser-bt [^`]+)`", prose):
            found.append((doc.name, " ".join(span.group(1).split()).replace(".venv/bin/", "")))
    return found


INLINE = _inline_commands()


@pytest.mark.parametrize("doc,command", INLINE, ids=[f"{d}: {c[:60]}" for d, c in INLINE])
def test_a_command_named_in_the_prose_has_the_options_it_shows(doc, command):
    words = command.replace("[", " ").replace("]", " ").split()
    name = words[1]
    choices = _parser([name])._subparsers._group_actions[0].choices
    assert name in choices, f"{doc}: {command}: no command {name}"
    known = choices[name]._option_string_actions
    for option in (w for w in words[2:] if w.startswith("-") and not re.fullmatch(r"-[\d.]+", w)):
        assert option in known, f"{doc}: {command}: {name} has no option {option}"
