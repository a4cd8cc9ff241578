"""The documentation as a reader meets it: a README that fits a screen or two with its picture, links that lead
somewhere, and an architecture page whose paths are the code's."""

from __future__ import annotations

import re

from tests.conftest import REPO

PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)\s]+)\)")


def test_the_readme_is_a_front_door_with_its_screenshot() -> None:
    readme = REPO / "README.md"
    assert readme.stat().st_size <= 15 * 1024, f"README.md is {readme.stat().st_size} bytes: move detail to docs/"
    picture = REPO / "docs" / "workbench.png"
    assert "](docs/workbench.png)" in readme.read_text()
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and picture.stat().st_size > 10_000


def test_the_design_notes_read_in_a_quarter_hour() -> None:
    """The decisions that hold, each with the figure that chose it: at most 400 lines (screens not kept are one line
    each at its end; their history is in git and the results' notebooks)."""
    lines = (REPO / "docs" / "design-notes.md").read_text().splitlines()
    assert len(lines) <= 400, f"docs/design-notes.md is {len(lines)} lines"
    assert "## Screened and not kept" in lines


def test_every_relative_link_resolves() -> None:
    broken = []
    for page in PAGES:
        for target in LINK.findall(page.read_text()):
            if target.startswith(("http://", "https://", "mailto:", "#")):
                continue
            path = (page.parent / target.split("#")[0]).resolve()
            if not path.exists():
                broken.append(f"{page.relative_to(REPO)} -> {target}")
    assert not broken, broken


def test_the_architecture_page_is_short_and_names_files_that_exist() -> None:
    """Every repository path the page names exists, except the files its worked example tells a newcomer to create
    (the third family's room and its test)."""
    page = REPO / "docs" / "architecture.md"
    text = page.read_text()
    assert len(text.splitlines()) <= 250
    named = set(re.findall(r"`((?:sessions|training|labeling|workbench|tests|benchmarks)/[\w/.<>-]*)`", text))
    to_create = ("training/spectral_logreg", "tests/training/test_logreg_family.py")
    missing = [
        p for p in sorted(named) if "<" not in p and not p.startswith(to_create) and not (REPO / p.rstrip("/")).exists()
    ]
    assert not missing, missing
    assert len(named) > 20  # the page names the code it describes


def test_every_path_the_pages_name_exists() -> None:
    """A path in a code span of README or docs/ (one of the project's folders, a file with its suffix) is there: a
    renamed module or a room made of a file leaves no stale name behind. A script named "at" a commit is of that
    commit (kept by git, not the tree); the architecture page's worked example names files a newcomer creates."""
    span = re.compile(r"`((?:sessions|training|labeling|workbench|tests|benchmarks|docs)/[\w/.-]*)`(?! at [0-9a-f]{7})")
    to_create = ("training/spectral_logreg", "tests/training/test_logreg_family.py")
    missing = [
        f"{page.relative_to(REPO)}: {p}"
        for page in PAGES
        for p in sorted(set(span.findall(page.read_text())))
        if not p.startswith(to_create) and not (REPO / p.rstrip("/")).exists()
    ]
    assert not missing, missing


def test_the_results_are_pages_by_question_and_the_code_names_no_issue() -> None:
    """A newcomer asking "how fast?" or "how good is the loop?" finds one page per question in benchmarks/results/
    (raw outputs under raw/<question>/), none named by an issue they never saw; the code says the reason or the
    figure, not an issue number."""
    results = REPO / "benchmarks" / "results"
    entries = sorted(p.name for p in results.iterdir() if p.name != ".gitkeep")
    assert len(entries) <= 8, entries
    assert not [e for e in entries if e.startswith("issue")], entries
    assert not [p for p in (results / "raw").rglob("issue-*")]
    named = re.compile(r"\b[Ii]ssues? \d+|\bissue-\d+")
    found = [
        f"{path.relative_to(REPO)}:{i}"
        for package in ("sessions", "training", "labeling", "workbench")
        for path in sorted((REPO / package).rglob("*"))
        if path.is_file() and path.suffix in {".py", ".js", ".css", ".html", ".md", ".json"}
        for i, line in enumerate(path.read_text(errors="replace").splitlines(), 1)
        if named.search(line)
    ]
    assert not found, found
