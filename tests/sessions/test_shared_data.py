"""Every file of ../shared/data/ is ingested or refused with one clear line; nothing else ever escapes."""

from __future__ import annotations

from pathlib import Path

import pytest

from sessions import IngestError, Session
from tests.conftest import SHARED_DATA, shared_data, snapshot

MCAP_SETS = ("mcap-conformance", "rosbag2-mcap")


def _mcaps(name: str) -> list[Path]:
    return sorted((SHARED_DATA / name).rglob("*.mcap")) if (SHARED_DATA / name).exists() else []


@pytest.mark.parametrize("name", MCAP_SETS)
def test_every_mcap_is_ingested_or_refused_cleanly(tmp_path: Path, name: str, capfd) -> None:
    files = _mcaps(name) or [shared_data(name)]
    session = Session.create(tmp_path / "s")
    reasons: dict[str, int] = {}
    for path in files:
        before = snapshot(session.path)
        try:
            session.ingest([path])
        except IngestError as err:
            msg = str(err)
            assert msg.startswith(str(path)) and "\n" not in msg, msg
            assert snapshot(session.path) == before, f"{path}: refused, yet the session changed"
            key = err.reason.split(" (")[0].split(":")[0]
            reasons[key] = reasons.get(key, 0) + 1
    out, err_out = capfd.readouterr()
    assert out == "" and err_out == "", "a library printed to the terminal during ingest"
    # None of these carry robot sensors: refusing for that reason is the right answer.
    assert sum(reasons.values()) == len(files)
    assert set(reasons) == {"no usable sensor channel"}, reasons
    if name == "mcap-conformance":
        assert len(files) == 416


def test_the_conformance_variants_the_indexed_reader_fails_on_are_still_read(tmp_path: Path) -> None:
    """112 variants break mcap's indexed reader; the streaming fallback must read their messages."""
    folder = shared_data("mcap-conformance", "TenMessages")
    session = Session.create(tmp_path / "s")
    for path in sorted(folder.glob("*-chx*.mcap")):
        with pytest.raises(IngestError, match=r"example: cannot decode: message encoding 'a' is not supported"):
            session.ingest([path])  # the channel was reached: its messages were read


def test_rosbag2_reasons_name_the_topics(tmp_path: Path) -> None:
    session = Session.create(tmp_path / "s")
    bag = shared_data("rosbag2-mcap", "rosbag2_tests", "resources", "mcap", "bag_with_topics_and_service_events")
    with pytest.raises(IngestError) as err:
        session.ingest(sorted(bag.glob("*.mcap")))
    assert "/test_service1/_service_event: cannot decode: a service or action schema" in str(err.value)
    wrong = shared_data("rosbag2-mcap", "rosbag2_tests", "resources", "mcap", "wrong_rmw_test")
    with pytest.raises(IngestError, match="message encoding 'wrong_format' is not supported"):
        session.ingest(sorted(wrong.glob("*.mcap")))


def test_a_whole_borealtc_terrain_folder(tmp_path: Path) -> None:
    session = Session.create(tmp_path / "s")
    logs = session.ingest([shared_data("borealtc", "ASPHALT")])
    assert [x.name for x in logs] == [f"ASPHALT_{i:02d}" for i in range(7)]
    assert all(x.reference_terrain == "asphalt" and x.n_channels == 10 for x in logs)
