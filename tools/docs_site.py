"""The documentation site's generated pages, and the MkDocs hook that serves them.

mkdocs.yml names this file under ``hooks:``, so ``mkdocs build`` (``make docs``) generates the reference
pages in memory on every build; nothing generated is ever written into docs/ or committed:

- ``reference/cli.md``: every command's ``--help``, from the argparse parser the ``chaser-bt`` command uses;
- ``reference/nodes.md``: every node a tree can use with its ports, from the behaviours' port declarations
  (the registry ``chaser-bt nodes`` prints);
- ``reference/scenario-keys.md``: the scenario format, ``sitl/scenarios/README.md`` as it stands;
- ``reference/api/*.md``: one page per package, each a mkdocstrings directive that renders its docstrings.

One page lives in docs/ and is still made on every build: ``results.md``, the measured results, which
``tools/results_page.py`` writes from the record of measurements (``benchmarks/results/*.jsonl``); the build
serves it as the record makes it now, whatever the committed copy says (:func:`results_page`).

The hook also rewrites links from docs/ to repository files outside docs/ (``../trees/chase.yaml``), which
MkDocs cannot serve: see :func:`on_page_markdown`. ``python tools/docs_site.py DIR`` writes the generated
pages into DIR, to read them without building the site.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import posixpath
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO_README = ROOT / "sitl" / "scenarios" / "README.md"
RESULTS_PAGE = "results.md"  # committed in docs/, made again from benchmarks/results/ on every build

# The API reference: (page, package, what it is), in the order the navigation lists them.
API_PACKAGES = (
    ("chaser_bt.tree", "trees: the loader, the validator, the registry, ports, control nodes and decorators"),
    ("behaviours", "the tree's leaves: each wraps one algorithm and one vehicle command"),
    ("chaser_bt.mission", "the runner: ticking a tree against a vehicle, and how a run ends"),
    ("chaser_bt.vehicle", "the MAVLink link to ArduCopter and the vehicle's state"),
    ("chaser_bt.radar", "the ground radar: datagrams, correlators, calibration, the feed"),
    ("chaser_bt.vision", "on-board vision: detector, trackers, projection, range, pipeline"),
    ("chaser_bt.search", "probabilistic search: belief, sensor model, receding-horizon and max-belief"),
    ("chaser_bt.control", "follow control: PID loops, sticks, the chase geometry"),
    ("chaser_bt.ground", "streaming to the ground and the operator's signed uplink"),
)
HELP_COLUMNS = 100  # --help is wrapped to this width, whatever terminal builds the site


# -- the pages --------------------------------------------------------------------------------------


def cli_reference() -> str:
    """Every command's ``--help``, in the order ``chaser-bt --help`` lists them."""
    from chaser_bt.cli import _parser

    with _columns(HELP_COLUMNS):
        top = _parser([])
        names = list(_subcommands(top))
        out = [
            "# Command line",
            "",
            "Generated from the `chaser-bt` command's own parser: each section is that command's `--help`.",
            "Exit codes are the same for every command: 0 done, 1 the mission failed or the vehicle could not be",
            "flown, 2 bad input, 130 interrupted.",
            "",
            "```text",
            top.format_help().rstrip(),
            "```",
        ]
        for name in names:
            # Commands that live in sitl/ build their real parser only when named, so build it for each.
            sub = _subcommands(_parser([name]))[name]
            out += ["", f"## `chaser-bt {name}`", "", "```text", sub.format_help().rstrip(), "```"]
    return "\n".join(out) + "\n"


def node_catalogue() -> str:
    """Every registered node with its kind, summary and ports, from their declarations."""
    from chaser_bt.tree import default_registry
    from chaser_bt.tree.display import _port_note
    from chaser_bt.tree.ports import type_name

    registry = default_registry()
    ids = sorted(registry.ids())
    kinds: dict[str, list[str]] = {}
    for node_id in ids:
        kinds.setdefault(registry.get(node_id).kind.name.lower(), []).append(node_id)
    out = [
        "# Node catalogue",
        "",
        "Every node a tree can use, generated from the port declarations the validator checks trees against",
        "(the same list as `chaser-bt nodes`). A port's default is shown after `=`; `{key}` is a blackboard",
        "entry, `(required)` a port the tree must set, and the bounds in brackets are checked when the tree is",
        "validated. How ports, blackboard references and remapping work: [Mission trees](../trees.md).",
        "",
        "| kind | nodes |",
        "|---|---|",
    ]
    for kind in sorted(kinds):
        out.append(f"| {kind} | " + ", ".join(f"[{n}](#{_anchor(n)})" for n in kinds[kind]) + " |")
    for node_id in ids:
        node = registry.get(node_id)
        out += ["", f"## {node_id}", "", f"*{node.kind.name.lower()}*: {_prose(node.description)}"]
        rows = [(d, name, port) for d, ports in (("in", node.input_ports), ("out", node.output_ports))
                for name, port in ports.items()]
        if rows:
            out += ["", "| port | direction | type | default | meaning |", "|---|---|---|---|---|"]
            for direction, name, port in rows:
                note = _port_note(port).strip().removeprefix("= ")
                out.append(f"| `{name}` | {direction} | `{type_name(port.data_type)}` | "
                           f"{_cell(f'`{note}`' if note else '')} | {_cell(_prose(port.description))} |")
    return "\n".join(out) + "\n"


def scenario_keys(repo_base: str | None = None) -> str:
    """The scenario format: sitl/scenarios/README.md, its links made to work from the site."""
    text = SCENARIO_README.read_text()
    intro = ("Scenario files set up the built-in simulator for `chaser-bt rehearse`, `campaign` and `sitl`. "
             "This page is `sitl/scenarios/README.md`, the format's definition, as it stands in the repository.\n\n")
    title, _, body = text.partition("\n")
    text = f"{title}\n\n{intro}{body.lstrip()}"
    return rewrite_links(text, SCENARIO_README.parent, "reference/scenario-keys.md", ROOT / "docs", repo_base)


def api_pages() -> dict[str, str]:
    """One page per package: its docstring, then every public module, class and function under it."""
    pages = {}
    index = [
        "# API",
        "",
        "The Python API, generated from the docstrings. Packages, with what each does:",
        "",
        "| package | what |",
        "|---|---|",
    ]
    for package, what in API_PACKAGES:
        pages[f"reference/api/{package}.md"] = f"# `{package}`\n\n::: {package}\n"
        index.append(f"| [`{package}`]({package}.md) | {what} |")
    index += ["", "Which package may import which: [Architecture](../../architecture.md)."]
    pages["reference/api/index.md"] = "\n".join(index) + "\n"
    return pages


def results_page(repo_base: str | None = None) -> str:
    """docs/results.md as the record of measurements makes it now (tools/results_page.py), links made servable."""
    spec = importlib.util.spec_from_file_location("results_page", ROOT / "tools" / "results_page.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    docs = ROOT / "docs"
    return rewrite_links(module.render(module.load()), docs, RESULTS_PAGE, docs, repo_base)


def pages(config=None) -> dict[str, str]:
    """Every generated page, by its path under the site's docs folder (``config``: the MkDocs config)."""
    return {
        "reference/cli.md": cli_reference(),
        "reference/nodes.md": node_catalogue(),
        "reference/scenario-keys.md": scenario_keys(_repo_base(config)),
        **api_pages(),
    }


# -- links to repository files ------------------------------------------------------------------------

_LINK = re.compile(r"(?<!!)\[(?P<text>[^\]\n]*)\]\((?P<target>[^)\s]+)\)")
_FENCE = re.compile(r"^(```|~~~).*?^\1", re.S | re.M)


def rewrite_links(markdown: str, source_dir: Path, page_uri: str, docs_dir: Path, repo_base: str | None) -> str:
    """Links in ``markdown`` (a file in ``source_dir``) to repository files outside ``docs_dir``, made servable.

    A relative link whose target exists in the repository but outside docs/ (``../trees/chase.yaml``)
    becomes a link into the repository's web view when ``repo_base`` is set, else the file's path as
    code (the text stays, the link goes: the site cannot serve the file). A link into docs/ is made
    relative to ``page_uri``, the page's place in the site. Links that point nowhere are left as
    they are, so that MkDocs reports them and a strict build fails. Fenced code is left alone.
    """
    page_dir = posixpath.dirname(page_uri)

    def one(match: re.Match) -> str:
        text, target = match.group("text"), match.group("target")
        if re.match(r"[a-z][a-z0-9+.-]*:|#|/", target, re.I):  # a URL, an anchor on this page, an absolute path
            return match.group(0)
        path, _, anchor = target.partition("#")
        resolved = (source_dir / path).resolve()
        if not resolved.exists() or not resolved.is_relative_to(ROOT):
            return match.group(0)
        if resolved.is_relative_to(docs_dir.resolve()):  # a page of the site
            inside = resolved.relative_to(docs_dir.resolve()).as_posix()
            link = posixpath.relpath(inside, page_dir or ".") + (f"#{anchor}" if anchor else "")
            return f"[{text}]({link})"
        in_repo = resolved.relative_to(ROOT).as_posix()
        if repo_base:
            kind = "tree" if resolved.is_dir() else "blob"
            return f"[{text}]({repo_base.format(kind=kind)}/{in_repo}{'#' + anchor if anchor else ''})"
        return text if text.strip("`") == in_repo else f"{text} (`{in_repo}`)"

    out, last = [], 0
    for fence in _FENCE.finditer(markdown):
        out.append(_LINK.sub(one, markdown[last:fence.start()]))
        out.append(fence.group(0))
        last = fence.end()
    out.append(_LINK.sub(one, markdown[last:]))
    return "".join(out)


def _repo_base(config) -> str | None:
    """``{repo_url}/{kind}/{branch}``, or None where mkdocs.yml names no repository."""
    url = config and config.get("repo_url")
    if not url:
        return None
    branch = (config.get("extra") or {}).get("repo_branch", "main")
    return f"{url.rstrip('/')}/{{kind}}/{branch}"


# -- the MkDocs hook ----------------------------------------------------------------------------------


def on_files(files, config):
    """Add the generated pages to the build (in memory: docs/ is never written)."""
    from mkdocs.structure.files import File

    for uri, content in pages(config).items():
        if files.get_file_from_path(uri) is not None:
            raise RuntimeError(f"docs/{uri} exists, but the site generates it: remove docs/{uri}")
        files.append(File.generated(config, uri, content=content))
    committed = files.get_file_from_path(RESULTS_PAGE)
    if committed is not None:
        files.remove(committed)
    files.append(File.generated(config, RESULTS_PAGE, content=results_page(_repo_base(config))))
    return files


def on_page_markdown(markdown, page, config, files):
    """Links from a page in docs/ to repository files outside it: see :func:`rewrite_links`."""
    if page.file.generated_by is not None:  # generated pages rewrote their own
        return markdown
    source = Path(page.file.abs_src_path).parent
    return rewrite_links(markdown, source, page.file.src_uri, Path(config["docs_dir"]), _repo_base(config))


# -- docstrings -------------------------------------------------------------------------------------

try:
    import griffe
except ImportError:  # generating the pages alone (main) needs no griffe
    griffe = None

if griffe is not None:

    class SphinxRoles(griffe.Extension):
        """The docstrings' reST roles (:class:`~a.b.C`, :func:`f`) as Markdown code, as Sphinx would show them.

        mkdocs.yml loads it into mkdocstrings' Python handler (``extensions:``).
        """

        def on_instance(self, *, obj, **kwargs) -> None:  # runs on every object as it is read
            if obj.docstring is not None:
                obj.docstring.value = _prose(obj.docstring.value)


# -- helpers ------------------------------------------------------------------------------------------


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


@contextlib.contextmanager
def _columns(n: int):
    """argparse wraps --help to $COLUMNS: fix it while the help is formatted."""
    before = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(n)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = before


def _prose(text: str) -> str:
    """A docstring's reST roles (:class:`~a.b.C`) as Markdown code (`C`)."""
    return re.sub(r":[a-z]+:`~?([^`]+)`", lambda m: f"`{m.group(1).rsplit('.', 1)[-1] if m.group(0).count('~') else m.group(1)}`", text)


def _cell(text: str) -> str:
    """Text safe in a Markdown table cell."""
    return text.replace("|", "\\|").replace("\n", " ")


def _anchor(heading: str) -> str:
    """The id MkDocs' table of contents gives a heading (its default slugify)."""
    from markdown.extensions.toc import slugify

    return slugify(heading, "-")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="write the site's generated pages into a folder, to read them")
    parser.add_argument("out", type=Path, help="folder to write into (created; e.g. build/docs-generated)")
    args = parser.parse_args(argv)
    for uri, content in pages().items():
        path = args.out / uri
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(content)
        print(path)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
