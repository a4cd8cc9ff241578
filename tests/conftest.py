"""Shared fixtures: temporary sessions, a snapshot of a session's state, small generated logs, shared data."""

from __future__ import annotations

import os
import shutil
import sqlite3
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path

import pytest

from sessions import Session
from tests.promise_report import pytest_runtest_logreport, pytest_terminal_summary  # noqa: F401 (hooks)
from tests.schedule import pytest_collection_modifyitems  # noqa: F401 (hook)

# Under pytest-xdist each worker is one process of two on two cores: torch (libgomp) in each must use one thread
# and sleep rather than spin between parallel regions, or the two slow each other many times over. Set before any
# test imports torch; the CLI children the tests start inherit it.
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("WORKBENCH_SHARED_DATA", REPO.parent / "shared" / "data"))


def shared_data(*parts: str) -> Path:
    """A path under ``../shared/data``; skips the test with the reason when it is absent (a user's clone)."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data not available: {path} (tests that read ../shared/data/ skip without it)")
    return path


def snapshot(session_path: Path) -> tuple:
    """Everything a session holds: every table's rows and the files in its folder (names and sizes)."""
    conn = sqlite3.connect(f"file:{session_path / 'session.sqlite'}?mode=ro", uri=True)
    try:
        tables = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
        rows = {t: conn.execute(f"SELECT * FROM {t} ORDER BY rowid").fetchall() for t in tables}
    finally:
        conn.close()
    files = sorted(
        (str(p.relative_to(session_path)), p.stat().st_size)
        for p in session_path.rglob("*")
        if p.is_file() and not p.name.startswith("session.sqlite")
    )
    return rows, files


TEST_TERRAINS = ("concrete", "grass", "gravel", "mulch", "dirt", "sand")


def children_of_a_killed_parent(start: Callable[[], None], pids: Path, count: int) -> list[int]:
    """Fork a parent that runs ``start`` (which forks ``count`` children, each writing its pid as a line of
    ``pids``), SIGKILL the parent once every child has written, and return the children's pids."""
    import signal
    import time

    parent = os.fork()
    if parent == 0:
        try:
            start()
        finally:
            os._exit(0)
    try:
        deadline = time.monotonic() + 60
        while (not pids.exists() or len(pids.read_text().split()) < count) and time.monotonic() < deadline:
            time.sleep(0.05)
        children = [int(p) for p in pids.read_text().split()]
        assert len(children) == count
    finally:
        os.kill(parent, signal.SIGKILL)
        os.waitpid(parent, 0)
    return children


def ended_within(pids: list[int], seconds: float) -> bool:
    """Whether every process of ``pids`` has ended (or is a zombie) within ``seconds``."""
    import time

    deadline = time.monotonic() + seconds
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not any(_alive(p) for p in pids)


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has ended (its parent, init, reaps it)


def add_terrains(s: Session, names: tuple[str, ...] = TEST_TERRAINS) -> Session:
    """Add the terrains a test labels with (those the session lacks)."""
    have = {t.name for t in s.terrains()}
    for name in names:
        if name not in have:
            s.add_terrain(name)
    return s


def new_session(path: Path, terrains: tuple[str, ...] = TEST_TERRAINS) -> Session:
    """``Session.create`` with the terrains a test labels with."""
    return add_terrains(Session.create(path), terrains)


@pytest.fixture
def quick_stage1(monkeypatch: pytest.MonkeyPatch) -> None:
    """The default family's stage 1 fitted in 60 AdamW steps instead of 600, for tests of what the CLI wires
    together (the fit itself: tests/training/test_frame_predictor.py); its stage 2 reads the frames, not stage 1."""
    from workbench.cycle import frame_stage1

    monkeypatch.setattr(frame_stage1, "FramePredictorFit", partial(frame_stage1.FramePredictorFit, steps=60))


@pytest.fixture
def session(tmp_path: Path) -> Session:
    """A new session with the demo's six terrains, the names these tests label with (a new session has none)."""
    s = Session.create(tmp_path / "session")
    add_terrains(s)
    yield s
    s.close()


@pytest.fixture(scope="session")
def demo_mcap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One 90 s demo walk as MCAP (with its .truth.json sidecar)."""
    from workbench.demo import generate_walk, write_walk

    out = tmp_path_factory.mktemp("demo") / "walk.mcap"
    return write_walk(generate_walk(3, 90.0), out, seed=3)


# Browser fixtures, shared by tests/browser/ and tests/safety/: one session-wide Playwright (a second one in the same
# process fails, "Sync API inside the asyncio loop").
from tests.browser.conftest import CHROMIUM, CHROMIUM_FLAGS, Server, save_screenshot  # noqa: E402


@pytest.fixture
def serve() -> Iterator:
    servers: list[Server] = []

    def start(session: Path, *extra: str) -> Server:
        servers.append(Server(session, *extra))
        return servers[-1]

    yield start
    for s in servers:
        s.stop()


@pytest.fixture(scope="session")
def browser():
    if not Path(CHROMIUM).exists() and shutil.which("chromium") is None:
        pytest.skip("Debian chromium is not installed (make test installs it: apt-get install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("the playwright Python package is not installed (pip install -e '.[dev]')")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
        yield b
        b.close()


@pytest.fixture(autouse=True, scope="module")
def _fork_servers_end_with_the_module() -> Iterator[None]:
    """A module's ``fork_client`` servers end with it, so their CPU counts in that module's (``suite_cpu.py``)."""
    yield
    from tests.fork_client import ForkServer

    ForkServer.stop()


def pytest_configure(config: pytest.Config) -> None:
    from tests import suite_cpu  # its hooks beside this file's: the suite's CPU at the end of every run

    if not config.pluginmanager.is_registered(suite_cpu):
        config.pluginmanager.register(suite_cpu, "workbench-suite-cpu")


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if report.when == "call":
        item.browser_failed = report.failed
    return report


@pytest.fixture
def page(browser, request):
    context = browser.new_context(viewport={"width": 1400, "height": 850})
    page = context.new_page()
    yield page
    if getattr(request.node, "browser_failed", False):
        save_screenshot(page, f"failed-{request.node.name}")  # what the page showed when the test failed
    context.close()
