"""The first screen of a session scored before: tracks, suggestions and the status line drawn from what the session
kept, the camera frame following the cursor, and the model's stretch accepted with one key (and undone)."""

from __future__ import annotations

import os
import re
import shutil
import sqlite3
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from sessions import Session
from tests.conftest import REPO

from .conftest import ARTIFACTS, UI_WAIT_MS, Server, close_notifications, open_tab, save_screenshot, shared_page
from .test_workbench_ui import TINY, blur, open_workbench, rows, set_cursor, tiny_trained_session, wait_until

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def scored_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two short demo walks with their camera, a few labels, tiny models, and one scoring kept in the session (as
    a server leaves it when it stops)."""
    from workbench.ui import SharedState

    path = tiny_trained_session(tmp_path_factory.mktemp("first"), seed=5, labelled=0.1)
    with Session.open(path) as s:
        state = SharedState(s)
        wait_until(lambda: state.scored and state.queue and not state.busy, timeout=120, what="the first scoring")
        state.stop()
    return path


def kept_files(path: Path) -> dict[str, float]:
    return {str(p): p.stat().st_mtime for p in (path / "cache").glob("scores-*/*")}


@dataclass(frozen=True)
class Screen:
    """One server on a copy of the scored session and one page, shared by this module's tests in file order (a file
    runs on one pytest worker, in order): a page load is 5 s of software WebGL in headless Chromium, and what each
    test checks needs the page as a person leaves it, not a new one."""

    path: Path
    kept: dict[str, float]  # the kept scoring's files before the server started
    server: Server
    page: object


@pytest.fixture(scope="module")
def screen(scored_session: Path, tmp_path_factory: pytest.TempPathFactory, browser) -> Iterator[Screen]:
    with shared_page(scored_session, tmp_path_factory.mktemp("screen"), browser, *TINY, before=kept_files) as shared:
        yield Screen(*shared)


def test_the_first_screen_is_drawn_from_the_kept_scoring(screen: Screen) -> None:
    session_path, kept, server, page = screen.path, screen.kept, screen.server, screen.page
    assert any(p.endswith("queue.json") for p in kept)
    started = time.monotonic()
    page.goto(server.url)
    page.get_by_text("segments suggested").wait_for(timeout=30_000)  # the queue, without a scoring pass
    page.get_by_text(re.compile(r"^default v\d+")).first.wait_for(timeout=UI_WAIT_MS)  # the status line: the model
    page.get_by_role("button", name="Retrain", exact=True).wait_for(timeout=UI_WAIT_MS)
    page.get_by_role("button", name="Export", exact=True).wait_for(timeout=UI_WAIT_MS)
    page.locator("img[data-frame]").wait_for(timeout=UI_WAIT_MS)  # the camera, at the cursor
    drawn = time.monotonic() - started
    (ARTIFACTS / "first-screen.txt").parent.mkdir(exist_ok=True)
    (ARTIFACTS / "first-screen.txt").write_text(f"suggestions, status line and camera drawn {drawn:.1f} s after goto\n")
    close_notifications(page)
    shot = save_screenshot(page, "first-screen")
    if os.environ.get("WORKBENCH_DOCS_SCREENSHOT"):  # `make screenshot`: the README's picture
        shutil.copyfile(shot, REPO / "docs" / "workbench.png")
    assert re.search(r"\d+ labels · \d+ s · \d+ terrains", page.inner_text("body"))
    time.sleep(1.0)
    assert kept_files(session_path) == kept  # nothing was scored again: the kept files were neither redone nor lost
    assert "scoring logs" not in page.inner_text("body")


def shown_at(page) -> float:
    """The time of the camera frame on screen, from its caption."""
    caption = page.get_by_text(re.compile(r"frame \d+ of \d+ at")).first.inner_text()
    return float(re.search(r"at ([\d.]+) s", caption).group(1))


def test_the_camera_frame_follows_the_cursor(screen: Screen) -> None:
    page = screen.page
    if "cursor 0.00 s" not in page.inner_text("body"):  # the first test did not get as far as the page
        open_workbench(page, screen.server.url)
    frame = page.locator("img[data-frame]")
    frame.wait_for(timeout=UI_WAIT_MS)
    numbers = []
    for cursor in (2.0, 12.0, 25.0):
        set_cursor(page, cursor)
        wait_until(lambda c=cursor: abs(shown_at(page) - c) <= 0.35, timeout=30, what=f"the frame at {cursor} s")
        numbers.append(int(frame.get_attribute("data-frame")))
    assert numbers == sorted(numbers) and len(set(numbers)) == 3
    before = frame.get_attribute("src")
    page.keyboard.press("ArrowRight")  # the cursor moves 1/20 of the window: 1.5 s at 30 s, three frames on
    wait_until(lambda: frame.get_attribute("src") != before, timeout=30, what="a new frame after the arrow key")
    save_screenshot(page, "camera-follows-cursor")


def test_a_predicted_stretch_is_accepted_with_one_key_and_undone(screen: Screen) -> None:
    session_path, page = screen.path, screen.page
    before = rows(session_path)
    if "walk_000" not in page.inner_text("body"):
        open_workbench(page, screen.server.url)
    set_cursor(page, 0.0)  # J finds the model's first stretch after the cursor: the one a new page shows first
    open_tab(page, "Label")
    blur(page)
    page.keyboard.press("j")
    page.get_by_text(re.compile(r"Stretch \d+ of \d+")).first.wait_for(timeout=UI_WAIT_MS)
    close_notifications(page)
    save_screenshot(page, "stretch-review")
    page.keyboard.press("y")
    accepted = wait_until(lambda: rows(session_path, "s.source = 'accepted'"), what="the accepted stretch in SQLite")
    labelled = {(g, a, b) for g, a, b, _, _ in before}
    classes = {r[3] for r in before}  # the classifier was trained on exactly these terrains
    assert len({r[3] for r in accepted}) == 1 and accepted[0][3] in classes
    for g, a, b, _, _ in accepted:  # only unlabelled time
        assert not any(g == h and a < y and x < b for h, x, y in labelled), (accepted, sorted(labelled))
    page.get_by_text("Accepted").first.wait_for(timeout=UI_WAIT_MS)
    save_screenshot(page, "stretch-accepted")
    close_notifications(page)
    blur(page)
    page.keyboard.press("u")
    wait_until(lambda: rows(session_path) == before, what="the acceptance undone")
    # Shift+Y labels the stretch on screen with the terrain chosen instead (issue 65, item 3): a counted check
    with sqlite3.connect(session_path / "session.sqlite") as conn:
        second = conn.execute("SELECT name FROM terrains ORDER BY position").fetchall()[1][0]
    blur(page)
    page.keyboard.press("2")
    page.keyboard.press("Shift+Y")
    added = wait_until(lambda: set(rows(session_path)) - set(before), what="the stretch labelled as chosen")
    assert {(r[3], r[4]) for r in added} == {(second, "manual")}, added

    def last_check() -> tuple:
        with sqlite3.connect(session_path / "session.sqlite") as conn:
            return conn.execute("SELECT kind, terrain FROM checks ORDER BY id DESC LIMIT 1").fetchone()

    # the label is saved first and its check right after (a check that cannot be kept never costs the label): wait
    # for the check, as the segment was waited for
    wait_until(lambda: last_check() == ("manual", second), what=f"a manual check of {second}")
    assert not rows(session_path, "s.source = 'accepted'")  # the plain Y binding did not fire beside it
    close_notifications(page)
    blur(page)
    page.keyboard.press("u")
    wait_until(lambda: rows(session_path) == before, what="the stretch's label undone")
