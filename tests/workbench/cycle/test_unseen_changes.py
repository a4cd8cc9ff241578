"""A new version whose figure for a run it never saw falls below the last stated interval is said so."""

from __future__ import annotations

from dataclasses import dataclass, field

from sessions import ModelVersion
from workbench.cycle import unseen_change


def _version(i: int, unseen: dict | None) -> ModelVersion:
    metrics = {"unseen_runs": unseen} if unseen else {}
    return ModelVersion(i, "classifier", f"models/{i}", "2026-11-29", {}, metrics, False)


@dataclass
class _Versions:
    """The one method of a session unseen_change reads."""

    kept: list[ModelVersion] = field(default_factory=list)

    def model_versions(self, stage: str | None = None) -> list[ModelVersion]:
        return [v for v in self.kept if stage in (None, v.stage)]


def test_the_fall_is_measured_against_the_latest_version_that_stated_a_figure() -> None:
    stated = _version(2, {"accuracy": 0.8, "low": 0.7, "high": 0.9, "runs": 5})
    quick = _version(3, None)  # a quick fine-tune states none: the fit before it is the one compared
    fell, kept = _version(4, {"accuracy": 0.6, "low": 0.5, "high": 0.7, "runs": 5}), _version(4, {"accuracy": 0.75})
    session = _Versions([_version(1, {"accuracy": 0.2, "low": 0.1, "high": 0.3, "runs": 5}), stated, quick])
    said = unseen_change(session, fell)  # type: ignore[arg-type]
    assert said is not None and "≈ 60 %" in said and "(70–90 %)" in said
    assert unseen_change(session, kept) is None  # type: ignore[arg-type]
    assert unseen_change(_Versions([quick]), fell) is None  # type: ignore[arg-type]  # nothing stated before
    assert unseen_change(session, quick) is None  # type: ignore[arg-type]
