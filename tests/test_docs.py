"""The README is a front page (at most 300 lines; the two commands and the install cost on its
first screen); its measured figures and the site's generated pages are what
tools/measure_docs.py renders from the stored measurements; the site builds with every MkDocs
warning an error (make docs)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest
from tool_support import load_tool

ROOT = Path(__file__).resolve().parent.parent
README_MAX_LINES = 300
FIRST_SCREEN_LINES = 40
# the development's records: each figure there is stated with its conditions, measured once
HISTORY_PAGES = {"performance-history.md", "profile.md", "push-ceiling.md"}
# figures only a measurement gives: an error as an RMS, a time in µs or ns, a throughput, a
# real-time factor or speed-up, a wall-clock or CPU time, a share of periods
MEASURED_FIGURE = re.compile(
    r"\d ?(mm|°) RMS|RMS[^|\n]{0,40}?\d ?mm|\d ?(µs|ns)\b|\d ?(rows|records|points)/s"
    r"|\d(\.\d+)?× (real time|faster)|\d ?s of (wall-clock|CPU)"
    r"|\d ?% of (the )?(periods|the operating time)")



def test_the_readme_is_a_front_page():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines"
    first = "\n".join(lines[:FIRST_SCREEN_LINES])
    for command in ("make run", "make test"):
        assert command in first, f"{command!r} is not in the README's first screen"
    measured = load_tool("measure_docs")
    cost = measured.install_cost(measured.load())
    assert "not measured" not in cost, "run tools/measure_docs.py install"
    assert cost in first, "the install's time and size are not on the README's first screen"


def test_the_measured_figures_are_the_stored_ones():
    """Nobody edits a measured figure by hand: the README's block and docs/generated/*.md are
    exactly what the stored measurements render to."""
    measured = load_tool("measure_docs")
    figures = measured.load()
    readme = (ROOT / "README.md").read_text()
    block = readme.split(measured.README_BEGIN)[1].split(measured.README_END)[0]
    assert block.strip() == measured.readme_block(figures).strip()
    for name, page in measured.PAGES.items():
        assert (measured.GENERATED / name).read_text() == page(figures), name
    for part in ("install_warm", "run", "walk", "teleop", "push", "bench"):
        assert part in figures, f"docs/generated/measured.json has no {part} figures"


def _user_pages() -> list[Path]:
    """The pages a user reads: the README and the site's pages outside the history."""
    return [ROOT / "README.md", *(page for page in sorted((ROOT / "docs").glob("*.md"))
                                  if page.name not in HISTORY_PAGES)]


def test_every_generated_figure_is_shown():
    """Each of tools/measure_docs.py's pages is included by a user page (a measurement nobody
    reads would let the hand-typed figure it replaced come back)."""
    included = "\n".join(page.read_text() for page in _user_pages())
    for name in load_tool("measure_docs").PAGES:
        assert f'--8<-- "docs/generated/{name}"' in included, f"no page includes {name}"


def _typed_figures(line: str) -> list[str]:
    """The measured-looking figures in a line of a user page; the paper's figures are quoted as
    the paper's, and a target (RMS <= 10 mm) is no measurement."""
    return [match.group(0) for match in MEASURED_FIGURE.finditer(line)
            if "paper" not in line[:match.start()]
            and not re.search(r"[<>≤≥]", line[max(0, match.start() - 8):match.end()])]


def test_no_measured_figure_is_typed_by_hand():
    """A user page states no measured figure of its own (an RMS error, a µs time, a
    throughput, a speed-up, a wall-clock time): those come from docs/generated/ or live on a
    history page with their conditions."""
    typed = [f"{page.relative_to(ROOT)}:{number}: {figure!r}" for page in _user_pages()
             for number, line in enumerate(page.read_text().splitlines(), 1)
             for figure in _typed_figures(line)]
    assert not typed, "measured figures typed by hand (generate them with " \
        "tools/measure_docs.py or move them to a history page):\n" + "\n".join(typed)


def test_the_guard_sees_a_typed_figure():
    """The check above catches the kinds of figure the pages used to type by hand, and not a
    parameter, a target or the paper's figure."""
    for text in ("measures 4.9 mm RMS as the robot", "the bit's RMS error 2.6 mm",
                 "one call takes 4.3 µs", "583 ns/pose", "281,500 rows/s",
                 "3.23× real time", "19.9 s of CPU", "inside in 98 % of the periods"):
        assert _typed_figures(text), text
    for text in ("the 1.21 N m wrist limit", "a 150 × 100 mm hole", "every 5 ms",
                 "its cost per hand per period (target <= 30 µs)",
                 "T1 = 0.5 s", "0.18 rad tracking error", "the 5 mm grid",
                 "(position RMS <= 10 mm over the reachable time)",
                 "the paper's real robot cut with 17 mm RMS"):
        assert not _typed_figures(text), text


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
