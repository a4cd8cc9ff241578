"""The model that ships is taught by the session (issue 98, item 2): fitted once, kept beside the active version."""

from __future__ import annotations

from pathlib import Path

import pytest

from sessions import Session
from workbench import cycle
from workbench.cli import main
from workbench.export import export_all

from .test_cycle import TINY
from .test_default_family import trained_demo_session

pytestmark = pytest.mark.usefixtures("fast_window_fits")  # what the fits do, not how well


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Session:
    s = trained_demo_session(tmp_path_factory.mktemp("taught"), seed=7, label_seed=2)
    yield s
    s.close()


def _versions(s: Session) -> list[int]:
    return [v.id for v in s.model_versions("classifier")]


def test_the_export_ships_a_taught_version_beside_the_active_one_and_fits_it_once(
    session: Session, tmp_path: Path, capsys
) -> None:
    active = session.active_model("classifier")
    before = _versions(session)
    starts = session.path / "cache" / "fit-starts"
    kept = sorted(starts.glob("*.safetensors"))  # the session's fit: each network it trained on the labels alone
    code = main(["export", str(session.path), "--out", str(tmp_path / "a")])
    printed = capsys.readouterr().out
    assert code == 0, printed
    # the taught fit's networks on the labels alone are the session fit's (their keys the same): it kept no new
    # one, so it trained none again, only its refits (tests/training/test_fit_starts.py: read, and the same result)
    assert kept and sorted(starts.glob("*.safetensors")) == kept
    assert "fitting stage 2 taught by the session" in printed
    (taught_id,) = set(_versions(session)) - set(before)
    taught = next(v for v in session.model_versions("classifier") if v.id == taught_id)
    # taught from the active version, never made active: the session scores and suggests with its own model
    assert taught.config["taught"] is True and taught.config["taught_from"] == active.id
    assert not taught.active and session.active_model("classifier").id == active.id
    assert taught.config["known_stretches"] > 0  # the session's scores were sure somewhere, and taught there
    assert f"model bundle v{taught_id}, taught by the session from v{active.id}" in printed
    card = (tmp_path / "a" / "bundle" / "MODEL_CARD.md").read_text()
    assert f"This bundle: v{taught_id}, taught by the session from v{active.id}: stage 2 fitted" in card
    shipped = (tmp_path / "a" / "bundle" / "classifier.safetensors").read_bytes()
    assert shipped == (session.path / taught.path / "classifier.safetensors").read_bytes()
    # a second export, nothing changed: the kept version ships again, no second fit
    assert main(["export", str(session.path), "--out", str(tmp_path / "b")]) == 0
    printed = capsys.readouterr().out
    assert "fitting" not in printed and f"model bundle v{taught_id}, taught" in printed
    assert _versions(session) == [*before, taught_id]
    assert (tmp_path / "b" / "bundle" / "classifier.safetensors").read_bytes() == shipped
    # --untaught: the active version as it is
    assert main(["export", str(session.path), "--out", str(tmp_path / "c"), "--untaught"]) == 0
    assert (
        f"model bundle v{active.id}, the session's active version (not taught: --untaught)" in capsys.readouterr().out
    )
    assert _versions(session) == [*before, taught_id]


def test_a_label_changed_since_makes_the_next_export_teach_again(session: Session, tmp_path: Path) -> None:
    export_all(session, tmp_path / "first")
    kept = cycle.kept_taught(session)
    assert kept is not None
    log = session.logs()[1]
    session.add_segment(log.id, 0, 250, session.terrains()[0].name, author="test", source="manual")
    assert cycle.kept_taught(session) is None  # its labels are not today's
    written = dict((p.name, what) for p, what in export_all(session, tmp_path / "second"))
    again = cycle.kept_taught(session)
    assert again is not None and again.id > kept.id and again.config["taught_from"] == kept.config["taught_from"]
    assert f"v{again.id}, taught by the session" in written["bundle"]
    session.undo(author="test")
    assert cycle.kept_taught(session).id == kept.id  # the labels as they were: the version taught from them


def test_a_taught_version_is_not_in_the_sessions_line_of_versions(session: Session, tmp_path: Path) -> None:
    """A Retrain's warning compares a new version's figure with the session's last one, not the export's."""
    from workbench.cycle.unseen_changes import compared_version

    export_all(session, tmp_path / "x")
    later = cycle.train_classifier(session, warm_start=False)
    versions = session.model_versions("classifier")
    newest = max((v for v in versions if v.id < later.id), key=lambda v: v.id)
    assert "taught_from" in newest.config and newest.metrics.get("unseen_runs")  # the newest before it is taught
    own = [v for v in versions if v.id < later.id and "taught_from" not in v.config]
    assert compared_version(session, later).id == own[-1].id


def test_a_second_pass_is_taught_by_the_first_taught_versions_scores(session: Session) -> None:
    """``passes=2`` (the loop's ``combined-taught-twice``): the first pass kept as the one-pass version, the second
    taught from the session scored with it."""
    twice, which = cycle.shipped_version(session, passes=2)
    once = cycle.kept_taught(session)
    assert once is not None and once.config["teach_passes"] == 1 and twice.config["teach_passes"] == 2
    assert twice.id > once.id and "taught by the session" in which
    assert cycle.shipped_version(session, passes=2)[0].id == twice.id  # kept: no third fit


def test_train_and_export_on_a_full_disk_are_refused_before_the_work_in_one_line(
    session: Session, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """Issue 99, item 7: with 0.5-2 MB free `train` fitted for 36 s and ended in an internal SafetensorError, and
    `export` in an internal [Errno 28]; both now say so first, exit 2, and nothing changes."""
    import shutil
    from types import SimpleNamespace

    versions = _versions(session)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: SimpleNamespace(total=1 << 40, used=1 << 40, free=1 << 20))
    assert main(["train", str(session.path), "--stage", "classifier"]) == 2
    assert "no space left for a new model version: 1.0 MB free on its disk" in capsys.readouterr().err
    assert main(["export", str(session.path), "--out", str(tmp_path / "x")]) == 2
    assert "no space left for the export: 1.0 MB free on its disk" in capsys.readouterr().err
    assert _versions(session) == versions and not (tmp_path / "x").exists()


def test_a_family_that_learns_from_labels_alone_ships_its_active_version(session: Session, tmp_path: Path) -> None:
    paper = cycle.train_classifier(session, model="paper", config=TINY, hidden=8)
    before = _versions(session)
    written = dict((p.name, what) for p, what in export_all(session, tmp_path / "p"))
    assert f"v{paper.id}, the session's active version (not taught: the paper family learns" in written["bundle"]
    assert _versions(session) == before
