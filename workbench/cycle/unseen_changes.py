"""Whether labelling more made the model that ships worse, as far as the session can tell.

Inside a session labels only add: the session's own runs get righter. The model that ships can still get worse on
runs it never saw (on BorealTC with one labelled run per terrain, four rounds of suggestions took the bundle on runs
kept out of the session from 77.8 to 66.9 %, benchmarks/results/loop.md). Each fit from scratch states its figure
for such a run (``metrics["unseen_runs"]``); a new version whose figure lies below the interval of the last version
that stated one is said so, in the Retrain's line and by ``workbench train``.
"""

from __future__ import annotations

from sessions import ModelVersion, Session
from training import unseen_fell


def unseen_change(session: Session, version: ModelVersion) -> str | None:
    """One line when ``version``'s figure for a run it never saw fell below the interval of the latest earlier
    classifier version that stated one; ``None`` when it did not, or either has no such figure."""
    after = version.metrics.get("unseen_runs")
    earlier = compared_version(session, version)
    return unseen_fell(earlier.metrics["unseen_runs"], after) if earlier is not None else None


def compared_version(session: Session, version: ModelVersion) -> ModelVersion | None:
    """The version ``version``'s figure is compared with: the latest earlier one of the session's own line that
    stated a figure (a taught version kept for the export is not in that line)."""
    earlier = [
        v
        for v in session.model_versions("classifier")
        if v.id < version.id and v.metrics.get("unseen_runs") and "taught_from" not in v.config
    ]
    return earlier[-1] if earlier else None
