"""The documentation site (mkdocs.yml, docs/): every Python block runs as written, every
page of the nav exists, the CLI help it shows is the CLI's, and the API reference lists
the top level's public names.

A block preceded by ``<!-- no-run -->`` is not run (it needs a browser or a peer library);
one preceded by ``<!-- requires: MODULE -->`` runs only where MODULE imports (an extra).
Snippet lines (``--8<-- "path"``, pymdownx.snippets) are expanded as the build does."""

from __future__ import annotations

import importlib.util
import os
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
SNIPPET = re.compile(r'^([ \t]*)--8<-- "([^":]+)(?::(\d+):(\d+))?"[ \t]*$', flags=re.MULTILINE)
BLOCK = re.compile(r"(?:<!--\s*([\w:. -]+?)\s*-->\n)?```python\n(.*?)```", flags=re.DOTALL)


def expand(text: str) -> str:
    """The page's text with its snippet lines replaced by the files they name."""

    def include(match: re.Match) -> str:
        lines = (ROOT / match.group(2)).read_text().splitlines()
        if match.group(3):
            lines = lines[int(match.group(3)) - 1 : int(match.group(4))]
        return "\n".join(match.group(1) + line for line in lines)

    return SNIPPET.sub(include, text)


def blocks() -> list:
    """``(id, marker, code)`` of every Python block of every page."""
    found = []
    for page in sorted(DOCS.rglob("*.md")):
        text = expand(page.read_text())
        for index, match in enumerate(BLOCK.finditer(text)):
            name = f"{page.relative_to(DOCS)}:{index}"
            found.append(pytest.param(match.group(1) or "", match.group(2), id=name))
    return found


BLOCKS = blocks()


@pytest.mark.parametrize(("marker", "code"), BLOCKS)
def test_docs_python_block_runs(marker, code, capsys, monkeypatch):
    if marker == "no-run":
        pytest.skip("marked no-run: needs a browser or a peer library")
    if marker.startswith("requires:"):
        for module in marker.split(":", 1)[1].split():
            if importlib.util.find_spec(module) is None:
                pytest.skip(f"needs {module} (an extra)")
    monkeypatch.chdir(ROOT)  # blocks name files relative to the checkout: tasks/...
    exec(compile(code, "docs block", "exec"), {"__name__": "__docs__"})
    assert capsys.readouterr().out  # each block prints what it shows


def test_docs_have_python_blocks():
    assert len(BLOCKS) >= 10
    skipped = [b for b in BLOCKS if b.values[0] == "no-run"]
    assert len(skipped) <= 3, "no-run is for blocks that need a browser or a peer only"


def nav_pages() -> list[str]:
    return re.findall(
        r"^\s*-\s+(?:[^:\n]+:\s+)?([\w./-]+\.md)\s*$",
        (ROOT / "mkdocs.yml").read_text(),
        flags=re.MULTILINE,
    )


def test_every_nav_page_exists():
    pages = nav_pages()
    assert len(pages) >= 20
    missing = [page for page in pages if not (DOCS / page).is_file()]
    assert not missing, f"mkdocs.yml's nav names pages that docs/ lacks: {missing}"


def test_every_page_is_in_the_nav():
    pages = set(nav_pages())
    orphans = [
        str(p.relative_to(DOCS))
        for p in DOCS.rglob("*.md")
        if str(p.relative_to(DOCS)) not in pages
    ]
    assert not orphans, f"pages outside mkdocs.yml's nav: {orphans}"


def test_snippets_exist():
    for page in DOCS.rglob("*.md"):
        for match in SNIPPET.finditer(page.read_text()):
            assert (ROOT / match.group(2)).is_file(), f"{page}: {match.group(2)}"


def test_reference_lists_the_top_level():
    """The reference page of the top level renders (or links, for a module) exactly the
    names of ``qpik.__all__``."""
    import qpik

    page = (DOCS / "reference" / "qpik.md").read_text()
    shown = set(re.findall(r"`qpik\.(\w+)`|::: qpik\.(\w+)", page))
    shown = {a or b for a, b in shown}
    modules = {"tasks", "limits", "scene", "analysis", "statics", "baselines"}
    assert not set(qpik.__all__) - shown - modules - {"__version__"}
    rendered = set(re.findall(r"^::: qpik\.(\w+)\s*$", page, flags=re.MULTILINE))
    linked = {module for module in modules if f"({module}.md)" in page}
    assert rendered | linked == set(qpik.__all__)


def test_cli_help_pages_are_the_cli():
    """docs/cli-help/*.txt is what ``qpik [COMMAND] --help`` prints (regenerate them with
    ``python docs/hooks/cli_help.py``); compared word by word, since line breaks depend on
    the Python version's argparse."""
    sys.path.insert(0, str(DOCS / "hooks"))
    try:
        import cli_help
    finally:
        sys.path.pop(0)
    saved = os.environ.get("COLUMNS")
    try:
        for command in [None, *cli_help.COMMANDS]:
            written = (DOCS / "cli-help" / f"{command or 'qpik'}.txt").read_text().split()
            assert cli_help.help_text(command).split() == written, (
                f"docs/cli-help/{command or 'qpik'}.txt is stale: run python docs/hooks/cli_help.py"
            )
    finally:
        if saved is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = saved


@pytest.mark.parametrize(
    "names",
    [
        ["priorities.png"],
        pytest.param(["self_motion.png", "talos.png"], marks=pytest.mark.slow),
    ],
)
def test_the_figures_script_draws_its_figures(tmp_path, names):
    """docs/make_figures.py runs and draws non-empty PNGs (one here: matplotlib takes about
    5 s a figure; the others in the slow run, and self_motion.png's example is drawn by
    tests/package/test_examples.py)."""
    pytest.importorskip("matplotlib")
    import subprocess

    script = Path(__file__).resolve().parents[2] / "docs" / "make_figures.py"
    subprocess.run([sys.executable, str(script), "--out", str(tmp_path), "--only", *names],
                   check=True, capture_output=True)  # fmt: skip
    for name in names:
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
