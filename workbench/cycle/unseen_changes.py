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
    earlier = [v for v in session.model_versions("classifier") if v.id < version.id and v.metrics.get("unseen_runs")]
    return unseen_fell(earlier[-1].metrics["unseen_runs"], after) if earlier else None
