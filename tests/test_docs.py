"""The README is a front page (at most 300 lines; the two commands and the install cost on its
first screen); its measured figures and the site's generated pages are what
tools/measure_docs.py renders from the stored measurements; the site builds with every MkDocs
warning an error (make docs)."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README_MAX_LINES = 300
FIRST_SCREEN_LINES = 40


def _measure_docs():
    spec = importlib.util.spec_from_file_location("measure_docs",
                                                  ROOT / "tools" / "measure_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_readme_is_a_front_page():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines"
    first = "\n".join(lines[:FIRST_SCREEN_LINES])
    for command in ("make run", "make test"):
        assert command in first, f"{command!r} is not in the README's first screen"
    measured = _measure_docs()
    cost = measured.install_cost(measured.load())
    assert "not measured" not in cost, "run tools/measure_docs.py install"
    assert cost in first, "the install's time and size are not on the README's first screen"


def test_the_measured_figures_are_the_stored_ones():
    """Nobody edits a measured figure by hand: the README's block and docs/generated/*.md are
    exactly what the stored measurements render to."""
    measured = _measure_docs()
    figures = measured.load()
    readme = (ROOT / "README.md").read_text()
    block = readme.split(measured.README_BEGIN)[1].split(measured.README_END)[0]
    assert block.strip() == measured.readme_block(figures).strip()
    for name, page in measured.PAGES.items():
        assert (measured.GENERATED / name).read_text() == page(figures), name
    for part in ("install_warm", "run", "walk"):
        assert part in figures, f"docs/generated/measured.json has no {part} figures"


def test_the_site_builds_strictly(tmp_path):
    pytest.importorskip("mkdocs", reason="the docs extra is not installed (make installs it)")
    pytest.importorskip("pymdownx", reason="the docs extra is not installed (make installs it)")
    built = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                            str(tmp_path / "site")], cwd=ROOT, capture_output=True, text=True,
                           timeout=120)
    assert built.returncode == 0, built.stderr
    assert "WARNING" not in built.stderr, built.stderr
    page = (tmp_path / "site" / "getting-started" / "index.html").read_text()
    assert "--8<--" not in page and "cache warm" in page  # the snippets were included
