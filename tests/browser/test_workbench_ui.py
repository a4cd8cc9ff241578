"""The workbench in a real browser: label through the widgets and hotkeys, retrain, take a suggestion, download the
label file, and see another browser's label appear. Tiny models (hidden 8, a few epochs) over two short demo logs."""

from __future__ import annotations

import base64
import io
import re
import shutil
import sqlite3
import time
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from PIL import Image

from sessions import Session
from tests.conftest import new_session
from training import TrainConfig

from .conftest import UI_WAIT_MS, Server, open_tab, save_screenshot, shared_page

pytestmark = pytest.mark.browser
TINY = ("--hidden", "8", "--stage1-epochs", "2", "--stage2-epochs", "3")


def tiny_trained_session(root: Path, *, seed: int, labelled: float) -> Path:
    """Two short demo walks (with their camera) in a session at ``root / "base"``, ``labelled`` of the time labelled
    in 2 s pieces, and tiny models of both stages."""
    from workbench.cycle import train_classifier, train_predictor
    from workbench.demo import generate_demo_logs, seed_labels

    logs = generate_demo_logs(root / "logs", n_logs=2, minutes=0.6, seed=seed)
    path = root / "base"
    with new_session(path) as s:
        s.ingest(logs)
        seed_labels(s, labelled, seed=0, segment_s=2.0)
        train_predictor(s, config=TrainConfig(max_epochs=2, piece=256), hidden=8)
        train_classifier(s, config=TrainConfig(max_epochs=3, k_folds=2), hidden=8)
    return path


@pytest.fixture(scope="module")
def base_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_trained_session(tmp_path_factory.mktemp("ui"), seed=3, labelled=0.15)


@dataclass(frozen=True)
class Workbench:
    """One server on a copy of the trained session and one page, shared by this module's tests in file order (a
    file runs on one pytest worker, in order): each goes on from the page the one before left, as a person does,
    and a page load is 5 s of software WebGL in headless Chromium."""

    path: Path
    server: Server
    page: object


@pytest.fixture(scope="module")
def workbench(base_session: Path, tmp_path_factory: pytest.TempPathFactory, browser) -> Iterator[Workbench]:
    with shared_page(base_session, tmp_path_factory.mktemp("workbench"), browser, *TINY) as (path, _, server, page):
        yield Workbench(path, server, page)


def opened(workbench: Workbench):
    """The shared page, opened on the workbench (again, when an earlier test stopped before it was)."""
    page = workbench.page
    if "walk_000" not in page.inner_text("body"):
        open_workbench(page, workbench.server.url)
    return page


def rows(path: Path, where: str = "1") -> list[tuple]:
    with sqlite3.connect(path / "session.sqlite") as conn:
        return conn.execute(
            "SELECT s.log_id, s.start, s.stop, t.name, s.source FROM segments s JOIN terrains t ON t.id = s.terrain_id"
            f" WHERE {where} ORDER BY s.id"
        ).fetchall()


def free_seconds(path: Path, log_id: int, length: float, *, after: float = 1.0) -> float:
    """Start (s, whole) of an unlabelled stretch of ``length`` seconds in a log (100 Hz demo logs)."""
    taken = sorted((a / 100, b / 100) for g, a, b, _, _ in rows(path) if g == log_id)
    t = after
    for a, b in taken:
        if t + length <= a:
            break
        t = max(t, float(int(b) + 1))
    return t


def shown_log(page, path: Path) -> int:
    """The id of the log the page shows (from the legend's name): an earlier test may have left another log on
    screen (a suggestion's), and a range typed there must be free in that log."""
    name = re.search(r"(\S+) · [\d.]+–[\d.]+ s of \d+ s", page.inner_text("body")).group(1)
    with sqlite3.connect(path / "session.sqlite") as conn:
        return conn.execute("SELECT id FROM logs WHERE name = ?", (name,)).fetchone()[0]


def wait_until(check, timeout: float = 30.0, what: str = "condition"):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = check()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {what}")


def open_workbench(page, url: str) -> None:
    page.goto(url)
    page.get_by_text("walk_000", exact=False).first.wait_for(timeout=30_000)
    page.get_by_text("cursor 0.00 s").wait_for(timeout=30_000)
    # headless Chromium renders WebGL in software and viser says so in a notification over the tabs: close it
    warning = page.get_by_text("Software WebGL rendering detected")
    try:
        warning.wait_for(timeout=3_000)
        warning.locator("xpath=ancestor::div[contains(@class,'Notification-root')]//button").first.click()
    except Exception:
        pass


def set_cursor(page, seconds: float) -> None:
    box = page.locator(
        "xpath=//label[text()='Cursor (s)']/ancestor::div[contains(@class,'mantine-Flex-root')][1]"
        "//input[contains(@class,'NumberInput-input')]"
    )
    box.fill(str(seconds))
    box.press("Tab")
    page.get_by_text(f"cursor {seconds:.2f} s").wait_for(timeout=UI_WAIT_MS)
    blur(page)


def press_b(page, cursor: float) -> None:
    """B, and wait until the page shows the range starting at the cursor: the server answers B by redrawing the
    cursor box, and an answer that lands while the next cursor is being typed puts the old value back."""
    page.keyboard.press("b")
    page.get_by_text(re.compile(rf"range {cursor:.2f}–")).first.wait_for(timeout=UI_WAIT_MS)


def blur(page) -> None:
    """Focus leaves any input, so hotkeys go to the page."""
    page.evaluate("document.activeElement && document.activeElement.blur()")


def test_label_with_hotkeys_retrain_suggest_and_download(workbench: Workbench) -> None:
    session_path = workbench.path
    before = rows(session_path)
    page = opened(workbench)
    # label 2 s of the first log as terrain 2 (grass) with the keyboard: cursor, B, cursor, E, 2, Enter
    t = free_seconds(session_path, 1, 2.0)
    set_cursor(page, t)
    press_b(page, t)
    set_cursor(page, t + 2)
    page.keyboard.press("e")
    page.get_by_text(f"range {t:.2f}–{t + 2:.2f} s").wait_for(timeout=UI_WAIT_MS)
    page.keyboard.press("2")
    page.keyboard.press("Enter")
    page.get_by_text("Saved").first.wait_for(timeout=UI_WAIT_MS)
    added = [r for r in rows(session_path) if r not in before]
    assert added == [(1, round(100 * t), round(100 * t) + 200, "grass", "manual")]
    save_screenshot(page, "workbench-main")

    # Retrain from the Train tab: the label is of a terrain the active models never saw, so the default family fits
    # stage 2 from scratch (no quick phase to refine: tests/workbench/test_default_family.py has that one), and its
    # version appears in the page as the active one
    open_tab(page, "Train")
    versions_before = len(Session.open(session_path).model_versions())
    page.get_by_role("button", name="Retrain (R)").click()
    page.get_by_text(f"v{versions_before + 1}", exact=True).first.wait_for(timeout=120_000)
    page.get_by_text("done in").first.wait_for(timeout=60_000)
    active = Session.open(session_path).active_model("classifier")
    assert active.id == versions_before + 1 and active.config["model"] == "default"
    assert active.config["warm_start"] is False
    save_screenshot(page, "workbench-train")

    # the Data tab's download is the bundle taught by the session (issue 98): fitted once, kept beside the active
    # version, and the Train tab says which version ships
    open_tab(page, "Data")
    with page.expect_download(timeout=180_000) as download:
        page.get_by_role("button", name="Model bundle, taught by the session (zip: PyTorch, ONNX, card)").click()
    names = zipfile.ZipFile(download.value.path()).namelist()
    assert "bundle/MODEL_CARD.md" in names and "classifier_stream.onnx" in names
    taught = next(v for v in Session.open(session_path).model_versions("classifier") if "taught_from" in v.config)
    assert taught.config["taught_from"] == active.id and not taught.active
    open_tab(page, "Train")
    page.get_by_text(f"ships (taught by the session from v{active.id})").first.wait_for(timeout=UI_WAIT_MS)
    save_screenshot(page, "workbench-train-taught")

    # take a suggestion with its hotkeys: N shows it, A labels it with the model's guess
    open_tab(page, "Suggest")
    page.get_by_text("segments suggested").wait_for(timeout=60_000)
    # each suggestion of the table shows its camera frame, small (the demo walks have a camera)
    thumbs = page.locator("img.wb-thumb")
    thumbs.first.wait_for(timeout=UI_WAIT_MS)
    picture = Image.open(io.BytesIO(base64.b64decode(thumbs.first.get_attribute("src").split(",", 1)[1])))
    assert picture.format == "JPEG" and picture.width == 112 and thumbs.count() >= 2
    blur(page)
    page.keyboard.press("n")
    page.get_by_text("model's guess").wait_for(timeout=UI_WAIT_MS)
    # the 1 s piece sits in a window of CONTEXT_S (10 s), clipped only at the ends of the log
    shown = re.search(r"([\d.]+)–([\d.]+) s of (\d+) s", page.get_by_text(" s of ").first.inner_text())
    a, b, duration = (float(x) for x in shown.groups())
    assert abs(b - a - 10.0) < 0.15 or a == 0.0 or b >= duration - 0.5, shown.group(0)
    save_screenshot(page, "workbench-suggest")
    page.keyboard.press("a")
    wait_until(lambda: rows(session_path, "s.source = 'suggestion'"), what="the accepted suggestion in SQLite")
    # suggestions are half to all of SUGGESTION_S (1 s = 100 samples here), but never shorter than what one
    # prediction of the classifier reads (the default family's 1.6 s span: 160 samples), nor cut under it
    ((_, start, stop, _, _),) = rows(session_path, "s.source = 'suggestion'")
    assert 160 <= stop - start < 320

    # V: the queue becomes this version's verification checks, the plan said before the person starts; a label
    # there is a spot check of the active version, and the status line's session figure rests on it
    blur(page)
    page.keyboard.press("v")
    page.get_by_text("verification checks: uniform pieces").wait_for(timeout=60_000)
    page.get_by_text(re.compile(r"verifying: the session: .* would bring it to ±5 points")).wait_for(timeout=UI_WAIT_MS)
    blur(page)
    page.keyboard.press("n")
    page.get_by_text("verification: a piece drawn at random").first.wait_for(timeout=UI_WAIT_MS)
    page.keyboard.press("a")
    version = Session.open(session_path).active_model("classifier").id
    wait_until(
        lambda: [c for c in Session.open(session_path).checks() if c.kind == "spot check" and c.classifier == version],
        what="the verification check in SQLite",
    )
    page.get_by_text(re.compile(r"the session: ≈ \d+ % \(90 % interval .*from 1 check of this version")).first.wait_for(
        timeout=60_000
    )
    save_screenshot(page, "workbench-verify")

    # download the label file through the browser
    open_tab(page, "Data")
    with page.expect_download(timeout=30_000) as info:
        page.get_by_role("button", name="Labels (CSV)").click()
    text = Path(info.value.path()).read_text()
    assert "walk_000" in text and "grass" in text
    assert len(text.strip().splitlines()) == 1 + len(rows(session_path))


def test_a_second_browser_sees_the_first_ones_label(workbench: Workbench, browser) -> None:
    session_path = workbench.path
    first = opened(workbench)
    second = browser.new_context(viewport={"width": 1400, "height": 900}).new_page()
    open_workbench(second, workbench.server.url)
    open_tab(second, "Label")
    n = len(rows(session_path))
    second.get_by_text(f"{n} segments labelled").wait_for(timeout=UI_WAIT_MS)
    t = free_seconds(session_path, shown_log(first, session_path), 2.5)
    set_cursor(first, t)
    press_b(first, t)
    set_cursor(first, t + 2.5)
    first.keyboard.press("e")
    first.get_by_text(f"range {t:.2f}–{t + 2.5:.2f} s").wait_for(timeout=UI_WAIT_MS)  # the server has the range
    first.keyboard.press("4")
    first.keyboard.press("Enter")
    # the label in SQLite, then in the second page's count (the first test checks the "Saved" notification, which
    # leaves after 4 s: a page starved by the other worker once missed it)
    wait_until(lambda: len(rows(session_path)) == n + 1, what="the first page's label in SQLite")
    second.get_by_text(f"{n + 1} segments labelled").wait_for(timeout=UI_WAIT_MS)
    assert len(rows(session_path)) == n + 1
    # the second browser kept its own view: its cursor did not move with the first one's
    assert "cursor 0.00 s" in second.inner_text("body")
    second.context.close()


def test_upload_ingests_a_log_and_refuses_a_broken_file(workbench: Workbench, tmp_path: Path) -> None:
    from workbench.demo import generate_demo_logs

    extra = generate_demo_logs(tmp_path / "more", n_logs=1, minutes=0.3, seed=9)[0]
    good = tmp_path / "field_run.mcap"
    shutil.copy(extra, good)
    bad = tmp_path / "broken.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 100)
    session_path = workbench.path
    page = opened(workbench)
    open_tab(page, "Data")
    upload = page.locator("input[type=file]").first
    upload.set_input_files(str(bad))
    page.get_by_text("Not done").first.wait_for(timeout=30_000)
    error = page.get_by_text("Not done").first.locator("xpath=ancestor::div[contains(@class,'Notification-root')]")
    assert "broken.mcap" in error.inner_text()  # one clear line naming the file and the reason
    assert len(Session.open(session_path).logs()) == 2
    assert not (session_path / "uploads" / "broken.mcap").exists()
    upload.set_input_files(str(good))
    page.get_by_text("Ingested").first.wait_for(timeout=60_000)
    page.get_by_text("3 logs").wait_for(timeout=UI_WAIT_MS)
    assert [x.name for x in Session.open(session_path).logs()][-1] == "field_run"


def test_the_map_shows_the_paths_and_a_click_on_it_moves_the_cursor(workbench: Workbench) -> None:
    """M turns the 3D view into the map of the log on screen (its path coloured by terrain, the other runs of its
    GNSS frame under it, a marker at the cursor); a click on the ground puts the cursor at the nearest pose."""
    import numpy as np

    from workbench.ui import map_bounds, map_paths

    page = opened(workbench)
    with Session.open(workbench.path) as s:
        log = s.log(shown_log(page, workbench.path))
        nothing = type("NoScores", (), {"scores": {}, "classes": ()})()
        mine, others = map_paths(s, nothing, log, s.segments(log.id))
    assert mine is not None and mine.frame == "wgs84" and others  # the demo walks carry a GNSS fix
    lo, hi = map_bounds(mine, others)
    distance = np.hypot(*(mine.xy - (lo + hi) / 2).T)  # from the map's centre, where the camera looks
    near = {f"{t:.2f}" for t in mine.times[distance <= distance.min() + 0.3]}
    blur(page)
    page.keyboard.press("m")
    page.get_by_role("button", name="Robot (M)").wait_for(timeout=UI_WAIT_MS)
    time.sleep(2)  # software WebGL draws the paths
    save_screenshot(page, "workbench-map")
    box = page.locator("canvas").first.bounding_box()
    assert box["width"] >= 300  # the traces panel made room for the map
    page.mouse.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)

    def cursor() -> str | None:
        found = re.search(r"cursor ([\d.]+) s", page.inner_text("body"))
        return found.group(1) if found and found.group(1) in near else None

    wait_until(cursor, what=f"the cursor at a pose nearest the click ({sorted(near)})")
    page.keyboard.press("m")  # the robot again, the traces their width
    page.get_by_role("button", name="Map (M)").wait_for(timeout=UI_WAIT_MS)
