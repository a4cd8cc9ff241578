"""The served page in a real browser: it lists the session's logs and follows changes made elsewhere."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import new_session
from workbench.cli import main

from .conftest import UI_WAIT_MS, open_tab, save_screenshot

pytestmark = pytest.mark.browser


def _listeners(port: int) -> set[str]:
    """Local addresses of sockets listening on ``port``, from the kernel's own tables (Linux)."""
    found = set()
    for table, width in (("/proc/net/tcp", 8), ("/proc/net/tcp6", 32)):
        if not Path(table).exists():
            continue
        for line in Path(table).read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            addr, _, hex_port = local.partition(":")
            if state == "0A" and int(hex_port, 16) == port:  # 0A: LISTEN
                found.add(addr.rjust(width, "0"))
    return found


def test_serve_binds_loopback_by_default(tmp_path: Path, serve) -> None:
    if not Path("/proc/net/tcp").exists():
        pytest.skip("needs Linux /proc/net/tcp to see which address a socket listens on")
    new_session(tmp_path / "s").close()
    server = serve(tmp_path / "s")
    listeners = _listeners(server.port)
    assert listeners, "nothing listens on the server's port"
    # 0100007F is 127.0.0.1 (little-endian hex); IPv6 loopback ::1 is the same, 32 hex digits wide
    assert listeners <= {"0100007F", "00000000000000000000000001000000"}, listeners


def test_a_new_session_asks_for_terrains_and_the_page_follows_a_log_ingested_elsewhere(
    tmp_path: Path, serve, page
) -> None:
    """One server and page for three facts (a page load is 5 s of software WebGL): ``--map`` opens the page on the
    map; a session without terrains asks for one and takes it from the page; the page lists the logs and shows one
    another process ingests without a reload."""
    from sessions import Session
    from workbench.demo import generate_demo_logs

    logs = generate_demo_logs(tmp_path / "logs", n_logs=3, minutes=0.2, seed=4)
    session = tmp_path / "s"
    assert main(["new", str(session)]) == 0
    assert main(["ingest", str(session), str(logs[0]), str(logs[1])]) == 0
    server = serve(session, "--map")
    page.goto(server.url)
    page.get_by_text("walk_000").first.wait_for(timeout=30_000)
    # --map: the page opened on the map of the walk's GNSS path (unscored: grey), M gives the robot back
    page.get_by_role("button", name="Robot (M)").wait_for(timeout=UI_WAIT_MS)
    open_tab(page, "Label")
    page.get_by_text("No terrains yet.").wait_for(timeout=UI_WAIT_MS)  # the hint, with its Terrains folder open
    save_screenshot(page, "no-terrains-yet")
    name = page.locator(
        "xpath=//label[text()='Name']/ancestor::div[contains(@class,'mantine-Flex-root')][1]//input"
    ).first
    name.fill("wet-floor")
    name.press("Tab")
    page.get_by_role("button", name="Add terrain").click()
    page.get_by_text("No terrains yet.").wait_for(state="hidden", timeout=UI_WAIT_MS)
    with Session.open(session) as s:
        assert [t.name for t in s.terrains()] == ["wet-floor"]

    open_tab(page, "Data")
    page.get_by_text("walk_001").first.wait_for(timeout=30_000)
    body = page.inner_text("body")
    assert "Terrain workbench" in body and "walk_000" in body and "2 logs" in body
    assert "wet-floor" in body
    assert "walk_002" not in body
    save_screenshot(page, "serve-logs")
    # another process ingests a log while the page is open: the page shows it without a reload
    assert main(["ingest", str(session), str(logs[2])]) == 0
    page.get_by_text("walk_002").first.wait_for(timeout=15_000)
    assert "3 logs" in page.inner_text("body")


def test_sigterm_stops_the_server_as_ctrl_c_does_and_leaves_no_socket_folder(
    tmp_path: Path, serve, monkeypatch
) -> None:
    """`kill`, systemd and `docker stop` send SIGTERM: the server stops cleanly (exit 0, no traceback) and removes its
    private socket's folder from the temp directory, where it used to leave one per server."""
    temp = tmp_path / "temp"
    temp.mkdir()
    monkeypatch.setenv("TMPDIR", str(temp))  # the server's temp directory, to see what it leaves there
    new_session(tmp_path / "s").close()
    server = serve(tmp_path / "s")
    assert [p.name for p in temp.iterdir() if p.name.startswith("workbench-")], "the server made no socket folder"
    server.stop()  # SIGTERM
    assert server.proc.returncode == 0, server.output()
    assert "Traceback" not in server.output()
    assert not [p for p in temp.iterdir() if p.name.startswith("workbench-")]
