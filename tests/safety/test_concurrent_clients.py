"""Promise 4: several people at once. N clients speaking viser's protocol label, relabel and delete concurrently
while a retrain runs: no label lost or duplicated, every client ends up showing the same label set, and saves keep
being answered. The summary line carries the server's click -> committed times under that load (target: p99 <= 50 ms)
beside what the clients saw; ``benchmarks/speed/bench_labels.py`` measures the same save without the load."""

from __future__ import annotations

import re
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from sessions import Session
from tests.browser.conftest import free_port
from tests.conftest import new_session
from tests.safety.viser_client import ViserClient

SEGMENT = re.compile(r"segment (\d+)")
SUMMARY = re.compile(r"<b>(\d+)</b> segments labelled in the session")


@dataclass
class Acts:
    """What one client was told: segments it added (id -> terrain), relabelled (id -> terrain), deleted."""

    added: dict[int, str] = field(default_factory=dict)
    relabelled: dict[int, str] = field(default_factory=dict)
    deleted: set[int] = field(default_factory=set)
    save_ms: list[float] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)


def person(url: str, region_s: float, ops: int, seed: int, acts: Acts) -> ViserClient:
    """Labels 1 s stretches in its own region; now and then relabels or deletes one of its own."""
    rng = np.random.default_rng(seed)
    client = ViserClient(url)
    client.wait_widget("Save label (Enter)")
    at = region_s
    terrain_now = "concrete"  # the Terrain dropdown starts on the first terrain; a relabel moves it
    for _ in range(ops):
        mine = sorted(set(acts.added) - acts.deleted)
        roll = rng.random()
        t0 = time.perf_counter()
        pressed: list[float] = []  # when Save was pressed: the latency is Save -> acknowledgement
        try:
            title, body = act(client, acts, mine, roll, rng, at, pressed)
        except TimeoutError as exc:
            acts.errors.append(
                f"no answer within 20 s to action {roll:.2f} after {time.perf_counter() - t0:.1f} s "
                f"(at {time.strftime('%H:%M:%S')}): {exc}"
            )
            return client
        if title == "Relabelled":
            terrain_now = body.split("→ ")[1].split(";")[0]
        if title == "Saved":
            acts.save_ms.append(1e3 * (time.perf_counter() - pressed[0]))
            acts.added[int(SEGMENT.search(body).group(1))] = terrain_now
        if roll >= 0.4 or not mine:
            at += 1.5
        if title in ("Not done", "Something went wrong"):
            acts.errors.append(f"{title}: {body}")
    return client


def act(
    client: ViserClient, acts: Acts, mine: list[int], roll: float, rng, at: float, pressed: list[float]
) -> tuple[str, str]:
    """One action: delete (20 %) or relabel (20 %) one of this person's segments, else label a new stretch."""
    if mine and roll < 0.2:
        seg = int(rng.choice(mine))
        title, body = client.click("Delete", ("Deleted",), Segment=option(client, seg))
        if title == "Deleted":
            acts.deleted.add(int(SEGMENT.search(body).group(1)))  # what the server says it deleted
        return title, body
    if mine and roll < 0.4:
        seg, terrain = int(rng.choice(mine)), str(rng.choice(["dirt", "sand", "gravel"]))
        title, body = client.click(
            "Relabel as chosen terrain", ("Relabelled",), Segment=option(client, seg), Terrain=terrain
        )
        if title == "Relabelled":
            acts.relabelled[int(SEGMENT.search(body).group(1))] = terrain
        return title, body
    return client.label(at, at + 1.0, sent=lambda: pressed.append(time.perf_counter()))


def option(client: ViserClient, seg: int) -> str:
    """The Segment dropdown's entry for ``seg``, as a person picks it (once this client's list shows it)."""
    uuid = client.wait_widget("Segment")
    found: list[str] = []

    def listed() -> bool:
        found[:] = [o for o in client.props[uuid].get("options", ()) if o.startswith(f"#{seg} ")]
        return bool(found)

    client.wait_until(listed)
    return found[0]


def trained(folder: Path, *, people: int, ops: int) -> Path:
    """A session at ``folder / "s"``: one walk long enough for every person's region, two labels, tiny models."""
    from tests.workbench.cycle.test_cycle import TINY
    from workbench import cycle
    from workbench.demo import generate_walk, write_walk

    seconds = max(120.0, 20 + people * region_width(ops) + 20)  # generating and ingesting scale with it: 800 s is 5 s
    mcap = write_walk(generate_walk(6, seconds), folder / "walk.mcap", seed=6)
    with new_session(folder / "s") as s:
        (log,) = s.ingest([mcap])
        s.add_segment(log.id, 100, 300, "grass", author="seed")
        s.add_segment(log.id, 500, 700, "concrete", author="seed")
        cycle.train_predictor(s, config=TINY, hidden=8)
        cycle.train_classifier(s, config=TINY, hidden=8)
    return folder / "s"


def region_width(ops: int) -> float:
    """Seconds of the walk one person labels in: each action moves on by at most 1.5 s."""
    return 1.5 * ops + 5


def run_people(path: Path, people: int, ops: int) -> tuple[int, list[float], list[float]]:
    """Returns the number of labels checked, Save -> acknowledgement times seen by the clients, and the server's
    click -> committed times (the Save handler's ``add_label``: the figure the issue's 50 ms p99 is about)."""
    from training import TrainConfig
    from workbench.ui import WorkbenchApp

    session = Session.open(path)
    app = WorkbenchApp(session, port=free_port(), hidden=8, max_epochs=(2, 30))
    app.job.classifier_config = TrainConfig(max_epochs=30, patience=30, k_folds=3)  # a retrain that lasts
    app.job.warm_epochs = None
    commit_ms: list[float] = []
    add_label = app.state.add_label

    def timed_add_label(*args, **kwargs):
        t = time.perf_counter()
        try:
            return add_label(*args, **kwargs)
        finally:
            commit_ms.append(1e3 * (time.perf_counter() - t))

    app.state.add_label = timed_add_label  # type: ignore[method-assign]
    clients: list[ViserClient] = []
    try:
        before = {seg.id: seg for seg in session.segments()}
        versions = len(session.model_versions("classifier"))
        app.job.start()
        acts = [Acts() for _ in range(people)]
        width = region_width(ops)  # each person labels in a region of their own
        threads = [
            threading.Thread(target=lambda i=i: clients.append(person(app.url, 20 + width * i, ops, i, acts[i])))
            for i in range(people)
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join(300)
        assert app.job.running or len(session.model_versions("classifier")) > versions  # it overlapped the labelling
        for a in acts:
            assert not a.errors, a.errors
        # every acknowledged change is in the session, and nothing else changed
        want = dict(before)
        now = {seg.id: seg for seg in session.segments()}
        for a in acts:
            for seg_id in a.added:
                if seg_id not in a.deleted:
                    assert seg_id in now, f"acknowledged segment {seg_id} is gone"
                    want[seg_id] = now[seg_id]
                    assert now[seg_id].terrain == a.relabelled.get(seg_id, a.added[seg_id])
            for seg_id in a.deleted:
                assert seg_id not in now, f"deleted segment {seg_id} is back"
        assert set(now) == set(want), f"unexpected segments: {set(now) ^ set(want)}"
        assert len({(s.start, s.stop) for s in now.values()}) == len(now), "a label is stored twice"
        # every client's page ends up showing that label set
        for c in clients:
            c.wait_until(lambda c=c: any(int(x) == len(now) for x in SUMMARY.findall(_summary(c))), timeout=30)
        deadline = time.monotonic() + 300
        while app.job.running and time.monotonic() < deadline:
            time.sleep(0.2)
        assert app.job.status.state == "done", app.job.status
        return len(now), [ms for a in acts for ms in a.save_ms], commit_ms
    finally:
        for c in clients:
            c.close()
        app.stop()
        session.close()


def _summary(client: ViserClient) -> str:
    return " ".join(str(p.get("content", "")) for p in client.props.values() if "segments labelled" in str(p))


def test_two_people_briefly(tmp_path: Path, promise) -> None:
    promise(summary(2, 8, *run_people(trained(tmp_path, people=2, ops=8), people=2, ops=8)))


@pytest.mark.slow
def test_four_people_label_edit_and_delete_during_a_retrain(tmp_path: Path, promise) -> None:
    promise(summary(4, 12, *run_people(trained(tmp_path, people=4, ops=12), people=4, ops=12)))


@pytest.mark.slow
def test_eight_people_for_longer(tmp_path: Path, promise) -> None:
    promise(summary(8, 60, *run_people(trained(tmp_path, people=8, ops=60), people=8, ops=60)))


def summary(people: int, ops: int, n: int, save_ms: list[float], commit_ms: list[float]) -> str:
    s50, s99 = np.percentile(save_ms, [50, 99])
    c50, c99 = np.percentile(commit_ms, [50, 99])
    return (
        f"promise 4 (several people at once): {people} clients x {ops} actions during a retrain, 0 failures, "
        f"{n} labels checked; label save click -> committed p50 {c50:.1f} ms, p99 {c99:.1f} ms (server); "
        f"Save -> acknowledgement p50 {s50:.0f} ms, p99 {s99:.0f} ms (client, incl. the round trip)"
    )
