"""The architecture as executable contracts (DESIGN §2): import-linter checks pyproject.toml's.

The simulator (``sitl.vehicle``, ``sitl.world``) never imports the bench, ``behaviours`` or the mission
side of ``chaser_bt``; ``chaser_bt`` never imports ``behaviours`` or ``sitl`` but for the CLI's lazy entry
points; ``behaviours`` never import ``sitl``; no import circles anywhere. The second test shows each
contract breaks on a package tree that violates it, so a green first test means something.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT = "from importlinter.cli import lint_imports; raise SystemExit(lint_imports(no_cache=True, no_logo=True))"


def _lint(cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", LINT], cwd=cwd, env={"PYTHONPATH": str(cwd), "PATH": ""},
                          capture_output=True, text=True, timeout=120)


def _contracts() -> list[dict]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]


def test_the_project_keeps_every_architecture_contract():
    result = _lint(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"Contracts: {len(_contracts())} kept, 0 broken." in result.stdout


def _module_names(contract: dict) -> set[str]:
    names = set(contract.get("source_modules", ())) | set(contract.get("forbidden_modules", ()))
    names |= set(contract.get("ancestors", ()))
    for layer in contract.get("layers", ()):
        names |= {m.strip() for m in layer.replace(":", "|").split("|")}
    return names


def _write_package_tree(root: Path, modules: set[str], imports: dict[str, str]) -> None:
    """Every name in ``modules`` as a package; ``imports[module]`` is that module's source."""
    for name in sorted(modules | set(imports)):
        parts = name.split(".")
        for k in range(1, len(parts) + 1):
            folder = root.joinpath(*parts[:k])
            folder.mkdir(exist_ok=True)
            (folder / "__init__.py").touch()
    for name, source in imports.items():
        (root.joinpath(*name.split(".")) / "__init__.py").write_text(textwrap.dedent(source))


def test_each_contract_breaks_on_a_tree_that_violates_it(tmp_path):
    contracts = _contracts()
    modules = set().union(*(_module_names(c) for c in contracts))
    violations = {
        "sitl.world": "import sitl.bench\n",  # the world reaching into the bench
        "sitl.vehicle": "import chaser_bt.mission\nimport sitl.world\n",  # the mission side; a layer upwards
        "chaser_bt.geo": "import sitl.simulator\n",  # not the CLI's lazy entry point
        "chaser_bt.cli": "def main():\n    import sitl.bench\n",  # allowed: the lazy entry point
        "behaviours.takeoff": "import sitl.simulator\n",
        "chaser_bt.alpha": "import chaser_bt.beta\n",  # a circle
        "chaser_bt.beta": "import chaser_bt.alpha\n",
    }
    _write_package_tree(tmp_path, modules, violations)
    (tmp_path / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text())
    result = _lint(tmp_path)
    assert result.returncode == 1, result.stdout + result.stderr
    assert f"Contracts: 0 kept, {len(contracts)} broken." in result.stdout, result.stdout
    assert "chaser_bt.cli -> sitl.bench" not in result.stdout  # the excepted import is not reported


@pytest.mark.parametrize("contract", _contracts(), ids=lambda c: c["type"])
def test_every_contract_names_modules_that_exist(contract):
    """A contract over a module that was renamed away would check nothing."""
    import importlib.util

    missing = [m for m in sorted(_module_names(contract)) if importlib.util.find_spec(m) is None]
    assert not missing, f"{contract['name']}: no such module {missing}"
