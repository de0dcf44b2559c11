"""A package a user installs: the wheel, installed into a fresh virtual environment outside the repository,
gives a ``chaser-bt`` that lists, shows, validates and rehearses the shipped trees and scenarios by name, with
the detector's weights, and answers ``--version``.

The wheel is built from a copy of the sources with this environment's setuptools (no build isolation, no
index: nothing is downloaded). The fresh environment sees this one's dependencies through a ``.pth`` file
naming a folder of links to them, chaser-bt's own files left out, so every ``chaser_bt``, ``behaviours`` and
``sitl`` it imports comes from the wheel; each command runs from a folder outside the repository.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
SOURCES = ("pyproject.toml", "README.md", "chaser_bt", "behaviours", "sitl", "trees")  # what the build reads
OWN = ("chaser_bt", "behaviours", "sitl")  # the distribution's top-level packages


def test_pyproject_lists_every_package_folder():
    """pyproject.toml lists its packages (so that chaser_bt.shipped.trees can be trees/): none may be missing."""
    from setuptools import find_namespace_packages

    setuptools = PYPROJECT["tool"]["setuptools"]
    assert setuptools["package-dir"] == {"chaser_bt.shipped.trees": "trees"}
    found = set(find_namespace_packages(where=str(ROOT), include=[f"{p}*" for p in OWN]))  # data folders too
    missing = sorted(found - set(setuptools["packages"]))
    assert not missing, f"add {missing} to [tool.setuptools] packages in pyproject.toml, or the wheel leaves them out"
    assert set(setuptools["packages"]) == found | {"chaser_bt.shipped.trees", "chaser_bt.shipped.trees.subtrees"}


@dataclass
class Installed:
    env: Path  # the fresh virtual environment
    site: Path  # its site-packages, where the wheel went
    work: Path  # a scratch folder outside the repository: every command's cwd
    wheel: Path
    build_log: str  # pip wheel -v: the build backend's output

    def run(self, *argv: str, timeout: float = 120) -> subprocess.CompletedProcess:
        """``argv`` (a program in the environment's bin/, then its arguments), from ``work``."""
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
        env["PATH"] = f"{self.env / 'bin'}{os.pathsep}{env.get('PATH', '')}"
        return subprocess.run([str(self.env / "bin" / argv[0]), *argv[1:]], cwd=self.work, env=env,
                              capture_output=True, text=True, timeout=timeout)

    def chaser_bt(self, *argv: str, timeout: float = 120) -> subprocess.CompletedProcess:
        return self.run("chaser-bt", *argv, timeout=timeout)


def _check(done: subprocess.CompletedProcess) -> subprocess.CompletedProcess:
    assert done.returncode == 0, f"{done.args}: exit {done.returncode}\n{done.stdout}\n{done.stderr}"
    return done


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Installed:
    base = tmp_path_factory.mktemp("wheel")
    assert ROOT not in base.parents
    src, dist, env, work, deps = (base / n for n in ("src", "dist", "env", "work", "deps"))
    src.mkdir()
    for name in SOURCES:  # a copy: the build writes build/ and *.egg-info beside its sources
        copy = shutil.copytree if (ROOT / name).is_dir() else shutil.copy2
        copy(ROOT / name, src / name, **({"ignore": shutil.ignore_patterns("__pycache__", "*.pyc")}
                                         if copy is shutil.copytree else {}))
    quiet = dict(os.environ, PIP_DISABLE_PIP_VERSION_CHECK="1", PIP_NO_INPUT="1")
    built = _check(subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
                                   "-v", "-w", str(dist), str(src)], capture_output=True, text=True, env=quiet, timeout=300))
    (wheel,) = dist.glob("chaser_bt-*.whl")
    _check(subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env)], capture_output=True, text=True,
                          timeout=120))
    # This environment's dependencies (pip included), without chaser-bt itself: its editable install maps
    # chaser_bt, behaviours and sitl onto the repository.
    ours = sysconfig.get_paths()["purelib"]
    deps.mkdir()
    for entry in Path(ours).iterdir():
        if entry.name in OWN or entry.name.startswith(("chaser_bt", "chaser-bt", "__editable__")) or entry.suffix == ".pth":
            continue
        (deps / entry.name).symlink_to(entry)
    probe = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    site = Path(_check(subprocess.run([str(env / "bin" / "python"), "-c", probe], capture_output=True, text=True,
                                      cwd=base)).stdout.strip())
    (site / "_chaser_bt_test_deps.pth").write_text(f"{deps}\n")
    _check(subprocess.run([str(env / "bin" / "python"), "-m", "pip", "install", "--no-deps", "--no-index", "-q", str(wheel)],
                          capture_output=True, text=True, env=quiet, cwd=base, timeout=300))
    work.mkdir()
    return Installed(env=env, site=site, work=work, wheel=wheel, build_log=built.stdout + built.stderr)


@pytest.mark.slow
def test_the_packages_come_from_the_wheel_not_the_repository(installed):
    code = "import chaser_bt, behaviours, sitl; print(chaser_bt.__file__); print(behaviours.__file__); print(sitl.__file__)"
    for line in _check(installed.run("python", "-c", code)).stdout.split():
        path = Path(line).resolve()
        assert installed.site in path.parents, line
        assert ROOT not in path.parents, line
    script = (installed.env / "bin" / "chaser-bt").read_text().splitlines()[0]
    assert script == f"#!{installed.env / 'bin' / 'python'}", script


@pytest.mark.slow
def test_the_build_warns_of_nothing(installed):
    """No deprecation (the licence is an SPDX expression) and no data folder setuptools would leave out."""
    warnings = [line.strip() for line in installed.build_log.splitlines() if "Warning" in line]
    assert not warnings, "\n".join(warnings)
    assert "License-Expression: BSD-3-Clause" in (installed.site / f"{installed.wheel.name.split('-py3')[0]}.dist-info"
                                                  / "METADATA").read_text()


@pytest.mark.slow
def test_version(installed):
    assert _check(installed.chaser_bt("--version")).stdout == f"chaser-bt {PYPROJECT['project']['version']}\n"


@pytest.mark.slow
def test_the_wheel_holds_every_tree_scenario_and_weights_file(installed):
    trees = installed.site / "chaser_bt" / "shipped" / "trees"
    for folder, shipped in ((ROOT / "trees", trees), (ROOT / "sitl" / "scenarios", installed.site / "sitl" / "scenarios"),
                            (ROOT / "chaser_bt" / "vision" / "weights", installed.site / "chaser_bt" / "vision" / "weights")):
        wanted = {p.relative_to(folder) for p in folder.rglob("*") if p.suffix in (".yaml", ".xml", ".pt", ".onnx")}
        assert wanted, folder
        for name in wanted:
            assert (shipped / name).is_file(), f"{name} is not in the wheel"
            assert (shipped / name).stat().st_size == (folder / name).stat().st_size, name


@pytest.mark.slow
def test_the_detector_loads_its_shipped_weights(installed):
    code = ("from chaser_bt.vision.detector.inference import Detector; import numpy as np; d = Detector(); "
            "d(np.zeros((240, 320, 3), np.uint8)); print(d.weights); print(d.backend)")
    weights, backend = _check(installed.run("python", "-c", code)).stdout.split()
    assert Path(weights) == installed.site / "chaser_bt" / "vision" / "weights" / "tiny_yolo.pt"
    assert backend == "onnx-int8"  # the int8 copy is no older than the weights once installed, as in the checkout


@pytest.mark.slow
def test_list_names_the_shipped_trees_and_scenarios(installed):
    out = _check(installed.chaser_bt("list")).stdout
    trees, scenarios = out.split("shipped scenarios")
    for name in ("chase", "chase_telemetry", "patrol", "sar", "takeoff_land"):
        assert f"  {name} " in trees, out
    assert f"{installed.site / 'chaser_bt' / 'shipped' / 'trees' / 'chase.yaml'} (also chase.xml)" in trees
    for name in ("chase", "chase_radar_off", "patrol", "sar", "search_only"):
        assert f"  {name} " in scenarios, out
    assert str(installed.site / "sitl" / "scenarios" / "patrol.yaml") in scenarios


@pytest.mark.slow
def test_validate_and_show_by_name_and_by_path(installed):
    shipped = installed.site / "chaser_bt" / "shipped" / "trees"
    assert _check(installed.chaser_bt("validate", "chase")).stdout == f"{shipped / 'chase.yaml'}: ok\n"  # its subtrees too
    assert _check(installed.chaser_bt("validate", "sar.xml")).stdout == f"{shipped / 'sar.xml'}: ok\n"
    assert "RTL" in _check(installed.chaser_bt("show", "patrol")).stdout
    shutil.copy(shipped / "takeoff_land.yaml", installed.work / "mine.yaml")  # a path still works
    assert _check(installed.chaser_bt("validate", "mine.yaml")).stdout == "mine.yaml: ok\n"
    assert _check(installed.chaser_bt("validate", str(installed.work / "mine.yaml"))).returncode == 0


@pytest.mark.slow
def test_an_unknown_name_is_one_line_listing_the_shipped_ones(installed):
    done = installed.chaser_bt("validate", "chse")
    assert done.returncode == 2
    lines = [line for line in done.stderr.splitlines() if line.startswith("chaser-bt: ")]
    assert lines == ["chaser-bt: argument TREE: no tree file or shipped tree named 'chse' (did you mean chase?); "
                     "shipped trees: chase, chase_telemetry, patrol, sar, takeoff_land"], done.stderr
    done = installed.chaser_bt("rehearse", "patrol", "--scenario", "nowhere")
    assert done.returncode == 2 and "shipped scenarios: chase, chase_radar_off, " in done.stderr, done.stderr


@pytest.mark.slow
def test_rehearse_by_name(installed):
    done = _check(installed.chaser_bt("rehearse", "takeoff_land", "--scenario", "patrol", "--no-camera", "--json",
                                      "--progress", "never"))
    report = json.loads(done.stdout)
    assert (report["outcome"], report["tree"], report["scenario"]) == ("landed", "TakeoffLand", "patrol")


@pytest.mark.slow
def test_rehearse_the_chase_by_name_with_its_camera(installed):
    """The shipped chase, its scenario, the rendered camera and the shipped detector: 10 simulated seconds."""
    done = installed.chaser_bt("rehearse", "chase", "--scenario", "chase", "--time-limit", "10", "--json",
                               "--progress", "never", "--camera-size", "320x240", timeout=300)
    assert done.returncode in (0, 1), done.stderr  # 1: the time limit ended it before the chase did
    report = json.loads(done.stdout)
    assert (report["tree"], report["scenario"], report["outcome"]) == ("Chase", "chase", "timeout"), report
    assert "camera" in report["sensors"] and "radar" in report["sensors"], report
