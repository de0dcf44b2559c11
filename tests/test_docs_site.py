"""The documentation site builds in strict mode, its generated reference is complete, and the tutorial works.

The site (mkdocs.yml, `make docs`) is built whole, strictly: a broken link, a missing anchor or a page left
out of the navigation fails the build, and a small throw-away site shows that the validation settings
really do fail on them. The tutorial (docs/tutorial.md) is followed as a reader would: its YAML files are
written into a scratch folder and every `chaser-bt` command it shows, in its console blocks and in its
prose, is run there, its output compared with what the page shows.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from chaser_bt.cli import _parser

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial.md"
ENV = dict(os.environ, NO_MKDOCS_2_WARNING="1", PYTHONPATH=str(ROOT))  # no theme banner on stderr


def _docs_site():
    """tools/docs_site.py, the generator and hook (tools/ is not a package)."""
    spec = importlib.util.spec_from_file_location("docs_site", ROOT / "tools" / "docs_site.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# -- the site ---------------------------------------------------------------------------------------


@pytest.mark.slow  # 10-40 s: mkdocstrings renders every module's docstrings
def test_the_site_builds_in_strict_mode(tmp_path):
    site = tmp_path / "site"
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
                          cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-5000:]
    assert "WARNING" not in done.stderr, done.stderr[-5000:]
    pages = {p.relative_to(site).as_posix() for p in site.rglob("index.html")}
    for page in ("index.html", "tutorial/index.html", "reference/cli/index.html", "reference/nodes/index.html",
                 "reference/scenario-keys/index.html", "report/index.html", "reference/api/index.html"):
        assert page in pages
    for package, _ in _docs_site().API_PACKAGES:  # mkdocstrings rendered each package's docstrings
        html = (site / "reference" / "api" / package / "index.html").read_text()
        assert 'class="doc doc-object doc-module"' in html, package
        assert ":::" not in html and ":class:`" not in html, package
    assert "chaser-bt campaign" in (site / "reference" / "cli" / "index.html").read_text()
    assert "acceptance_radius_m" in (site / "reference" / "nodes" / "index.html").read_text()


def _nav_pages(nav) -> set[str]:
    if isinstance(nav, str):
        return {nav}
    if isinstance(nav, dict):
        return set().union(*(_nav_pages(v) for v in nav.values()))
    return set().union(*(_nav_pages(v) for v in nav))


def test_the_navigation_names_every_page_in_docs():
    named = _nav_pages(yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"])
    on_disk = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert on_disk <= named, f"add {sorted(on_disk - named)} to nav in mkdocs.yml"
    generated = set(_docs_site().pages())
    assert not generated & on_disk, "generated pages are never written into docs/"
    assert generated <= named, f"nav in mkdocs.yml misses {sorted(generated - named)}"


def _tiny_site(tmp_path: Path, page: str) -> subprocess.CompletedProcess:
    """A two-page site with this project's strictness and link validation, ``page`` as its home page."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text(page)
    (docs / "other.md").write_text("# Other\n\n## A section\n\nBack [home](index.md).\n")
    tiny = {"site_name": "tiny", "strict": config["strict"], "validation": config["validation"],
            "theme": {"name": "mkdocs"}, "plugins": [], "nav": ["index.md", "other.md"]}
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(tiny))
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--site-dir", str(tmp_path / "site")],
                          cwd=tmp_path, env=ENV, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("page,broken", [
    ("# Home\n\nSee [the other page](other.md#a-section).\n", None),
    ("# Home\n\nSee [a page that is not there](missing.md).\n", "missing.md"),
    ("# Home\n\nSee [a section that is not there](other.md#no-such-section).\n", "no-such-section"),
    ("# Home\n\nSee [a repository file that is not there](../trees/no_such_tree.yaml).\n", "no_such_tree.yaml"),
], ids=["sound", "missing page", "missing anchor", "missing file outside docs"])
def test_the_strict_build_fails_on_a_broken_link(tmp_path, page, broken):
    done = _tiny_site(tmp_path, page)
    if broken is None:
        assert done.returncode == 0, done.stderr
    else:
        assert done.returncode != 0, f"a link to {broken} passed the strict build"
        assert broken in done.stderr and "in strict mode" in done.stdout + done.stderr


def test_links_to_repository_files_are_rewritten_and_missing_ones_kept():
    site = _docs_site()
    docs = ROOT / "docs"
    text = ("[chase tree](../trees/chase.yaml), [`trees/patrol.yaml`](../trees/patrol.yaml), "
            "[gone](../trees/gone.yaml), [design](design.md#1-what-chaser-bt-is), [web](https://example.org/a.md)\n"
            "```yaml\n[not a link](../trees/chase.yaml)\n```\n")
    plain = site.rewrite_links(text, docs, "campaign.md", docs, None)
    assert "chase tree (`trees/chase.yaml`)" in plain and "`trees/patrol.yaml`," in plain
    assert "[gone](../trees/gone.yaml)" in plain  # left for MkDocs to report
    assert "[design](design.md#1-what-chaser-bt-is)" in plain and "[web](https://example.org/a.md)" in plain
    assert "[not a link](../trees/chase.yaml)" in plain  # code is left alone
    linked = site.rewrite_links(text, docs, "campaign.md", docs, "https://github.com/o/r/{kind}/main")
    assert "[chase tree](https://github.com/o/r/blob/main/trees/chase.yaml)" in linked
    nested = site.rewrite_links("[design](docs/design.md)", ROOT, "reference/scenario-keys.md", docs, None)
    assert nested == "[design](../design.md)"


def test_the_generated_reference_covers_every_command_and_node():
    site = _docs_site()
    cli = site.cli_reference()
    commands = next(a for a in _parser([])._actions if a.__class__.__name__ == "_SubParsersAction").choices
    for name in commands:
        assert f"## `chaser-bt {name}`" in cli, name
    assert "usage: chaser-bt campaign" in cli  # the lazily built commands' real parsers, not placeholders
    from chaser_bt.tree import default_registry

    nodes = site.node_catalogue()
    for node_id in default_registry().ids():
        assert f"\n## {node_id}\n" in nodes, node_id
    assert "| `waypoint` | in | `list[float]` | `(required) [3 items]` |" in nodes
    assert site.scenario_keys().startswith("# Simulator scenarios\n")


# -- the tutorial -----------------------------------------------------------------------------------


def _tutorial_files() -> dict[str, str]:
    """The files the tutorial has the reader write: each YAML block opens with a comment naming its path."""
    files = {}
    for block in re.findall(r"```yaml\n(.*?)```", TUTORIAL.read_text(), re.S):
        name = re.match(r"# (\S+\.yaml): ", block)
        assert name, f"a YAML block of the tutorial does not name its file:\n{block}"
        files[name.group(1)] = block
    return files


def _tutorial_commands() -> list[list[str]]:
    """Every `chaser-bt` command the tutorial shows, in its order: console blocks and prose alike."""
    text = TUTORIAL.read_text()
    found = []
    for match in re.finditer(r"```console\n(.*?)```|`(chaser-bt [^`]+)`", text, re.S):
        lines = match.group(1).splitlines() if match.group(1) else [match.group(2)]
        found += [shlex.split(line.removeprefix("$ ")) for line in lines if line.strip()]
    return found


def _shown_after(marker: str) -> str:
    """The text block that follows ``marker`` in the tutorial."""
    text = TUTORIAL.read_text()
    return re.search(re.escape(marker) + r".*?```text\n(.*?)```", text, re.S).group(1)


def _write_tutorial_files(folder: Path) -> None:
    for name, content in _tutorial_files().items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(content)


def _cli(argv: list[str], capsys) -> tuple[int, str]:
    args = _parser(argv).parse_args(argv)
    status = args.handler(args)
    captured = capsys.readouterr()
    return status, captured.out + captured.err


HANDLED = {"validate", "show", "nodes", "rehearse", "campaign", "sitl", "run"}


def test_the_tutorial_shows_commands_this_test_follows():
    commands = _tutorial_commands()
    assert [c[0] for c in commands] == ["chaser-bt"] * len(commands)
    assert {c[1] for c in commands} <= HANDLED, "teach tests/test_docs_site.py the tutorial's new command"
    assert {"validate", "rehearse", "campaign"} <= {c[1] for c in commands}
    assert set(_tutorial_files()) == {"my-mission/field.yaml", "my-mission/hop.yaml"}


def test_the_tutorial_files_check_and_load_as_shown(tmp_path, monkeypatch, capsys):
    from sitl.world.scenario import load_scenario

    monkeypatch.chdir(tmp_path)
    _write_tutorial_files(tmp_path)
    scenario = load_scenario(tmp_path / "my-mission" / "field.yaml")
    assert scenario.name == "my-field"
    for argv in (c[1:] for c in _tutorial_commands() if c[1] in ("validate", "show", "nodes")):
        status, out = _cli(argv, capsys)
        assert status == 0, out
        if argv[0] == "validate":
            assert out.strip() == _shown_after("`chaser-bt validate my-mission/hop.yaml`").strip()
        elif argv[0] == "show":
            assert out.strip() == _shown_after("`chaser-bt show my-mission/hop.yaml`").strip()
    # The mistake the tutorial makes on purpose, and what it shows validation saying about it.
    tree = tmp_path / "my-mission" / "hop.yaml"
    tree.write_text(tree.read_text().replace("altitude_m: 15}", "altitude: 15}").replace("duration_s: 10}", "duration_s: -10}"))
    status, out = _cli(["validate", "my-mission/hop.yaml"], capsys)
    assert status == 2
    assert out.strip().splitlines() == _shown_after("break the tree on purpose").strip().splitlines()


def test_the_tutorial_rehearsal_lands_and_reports_as_shown(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    _write_tutorial_files(tmp_path)
    (rehearse,) = [c[1:] for c in _tutorial_commands() if c[1] == "rehearse"]
    assert "--no-camera" in rehearse
    started = time.monotonic()
    status, out = _cli(rehearse, capsys)
    assert status == 0, out
    assert time.monotonic() - started < 60
    for line in _shown_after("the first lines say how it ended").strip().splitlines():
        assert line.split() in [o.split() for o in out.splitlines()], line
    report = tmp_path / rehearse[rehearse.index("--report") + 1]
    for name in ("report.md", "report.json", "overhead.png", "relative_geometry.png", "trace.npz"):
        assert (report / name).is_file(), name
    import json

    result = json.loads((report / "report.json").read_text())
    assert result["outcome"] == "landed" and result["message"] == "Land: landed and disarmed"
    assert 45 < result["landed_dist_m"] < 55 and 14 < result["max_alt_m"] < 16  # what section 5 says


def _chaser_bt(argv: list[str], cwd: Path, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", "import sys; from chaser_bt.cli import main; sys.exit(main())", *argv],
                          cwd=cwd, env=ENV, capture_output=True, text=True, **kw)


@pytest.mark.slow
def test_the_tutorial_campaign_and_mavlink_flight_work_as_shown(tmp_path):
    _write_tutorial_files(tmp_path)
    commands = {c[1]: c[1:] for c in _tutorial_commands()}
    done = _chaser_bt(commands["campaign"], tmp_path, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "success 3/3" in done.stdout
    out = tmp_path / commands["campaign"][commands["campaign"].index("--out") + 1]
    for name in ("campaign.md", "campaign.json", "cdfs.png", "overhead.png", "runs"):
        assert (out / name).exists(), name
    again = _chaser_bt(commands["campaign"], tmp_path, timeout=600)
    assert again.returncode == 0 and "(0 flown now)" in again.stdout, again.stdout  # it resumes

    # The simulator on its own, then `run` against it: on a free port rather than the tutorial's 5760.
    sitl = subprocess.Popen([sys.executable, "-c", "import sys; from chaser_bt.cli import main; sys.exit(main())",
                             *commands["sitl"], "--tcp-port", "0", "--udp-port", "0"],
                            cwd=tmp_path, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        port = None
        for line in sitl.stdout:
            if found := re.search(r"tcp:127\.0\.0\.1:(\d+)", line):
                port = found.group(1)
                break
        assert port, "the simulator printed no port"
        run = [w.replace("tcp:127.0.0.1:5760", f"tcp:127.0.0.1:{port}") for w in commands["run"]]
        assert run != commands["run"], "the tutorial's run no longer connects to tcp:127.0.0.1:5760"
        flown = _chaser_bt(run, tmp_path, timeout=300)
        assert flown.returncode == 0, flown.stderr[-3000:]
        assert "completed: Land: landed and disarmed" in flown.stdout + flown.stderr
        assert "FENCE_ENABLE = 0" in flown.stderr  # the warning the tutorial mentions
    finally:
        sitl.terminate()
        sitl.wait(timeout=30)
