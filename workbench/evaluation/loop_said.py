"""What the workbench says of each new log in ``evaluate loop``: the figure its Data tab
shows (its members' agreement, else the accuracy expected at the log's drift, else the bound by its stretches), the
person's checks in it, and whether it warns, beside the truth. A log passes when its figure lies within ``WITHIN`` of
the truth or the workbench warns about it by name."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from sessions import LogInfo, Session

from ..cycle import SessionScores, checks_summary
from ..expectations import file_expectation

WITHIN = 0.05  # the target: the estimate within 5 points of the truth, or a warning naming the log


def said_of_logs(
    session: Session,
    scores: SessionScores,
    logs: Sequence[LogInfo],
    points: Mapping[int, np.ndarray],
    *,
    covered: Callable[[Session, LogInfo], np.ndarray],
) -> dict[str, dict]:
    """Per log name: ``figure``, ``expected``, ``agreement`` (``None`` where not measured), ``checks`` ``[right,
    n]`` (every counted check in it) and ``warning`` (its line or ``None``), as the Data tab computes them: only
    the active classifier's own checks can contradict its figure; and ``confidence``, the model's mean top
    probability on the log's time nobody labelled (``covered``: a log's labelled steps), measured beside it."""
    version = session.active_model("classifier")
    metrics = version.metrics if version is not None else {}
    checks = checks_summary(session).per_log
    fresh = {} if version is None else checks_summary(session, classifier=version.id).per_log  # as the Data tab
    out = {}
    for x in logs:
        s = scores.scores.get(x.id)
        if s is None or s.probs is None:
            continue
        e = file_expectation(
            x.name,
            s.drift,
            metrics,
            predicted=s.probs.argmax(1),
            change_points=points.get(x.id),
            rate_hz=x.rate_hz,
            checks=fresh.get(x.id),
            members=s.agreement,
            labelled=[(g.start, g.stop) for g in session.segments(x.id)],  # as the Data tab
        )
        c = checks.get(x.id)
        free = ~covered(session, x)
        out[x.name] = {
            # the model's own mean confidence on the log's time nobody labelled: a figure beside the Data tab's
            "confidence": float(s.probs[free].max(axis=1).mean()) if free.any() else None,
            "figure": None if e is None else e.figure,
            "expected": None if e is None else e.expected,
            "agreement": None if e is None else e.agreement,
            "checks": [c.right, c.n] if c is not None else [0, 0],
            "warning": None if e is None else e.warning(),
        }
    return out


def _pct(x: float | None) -> str:
    return "–" if x is None or x != x else f"{100 * x:.1f}"


def said_table(arms: Mapping[str, Sequence[tuple[Mapping[str, float], Mapping[str, dict]]]]) -> list[str]:
    """Markdown lines: per strategy and new log after the last round, the truth beside what the workbench says, and
    per strategy how many logs pass (figure within ``WITHIN`` of the truth, or warned of by name).

    Args:
        arms: Per strategy, its rounds as ``(accuracy per log, said per log)``; the last one is reported.
    """
    lines = [
        "What the workbench says of each new log after the last round (the Data tab's figure: its members' agreement,",
        "else expected at its drift, else bounded by its stretches); a log passes when that figure is within "
        f"{100 * WITHIN:.0f} points of the truth or a warning names it:",
        "",
        "| strategy | log | accuracy (%) | the workbench's figure (%) | its mean confidence (%) | checks in it right | "
        "warning | passes |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    summary = []
    for strategy, rounds in arms.items():
        truth, said = rounds[-1]
        passed = 0
        for name, acc in truth.items():
            s = said.get(name, {})
            figure, warned = s.get("figure"), s.get("warning") is not None
            ok = warned or (figure is not None and abs(figure - acc) <= WITHIN + 1e-9)
            passed += ok
            right, n = s.get("checks", [0, 0])
            checks = f"{right} of {n}" if n else "–"
            lines.append(
                f"| {strategy} | {name} | {_pct(acc)} | {_pct(figure)} | {_pct(s.get('confidence'))} | {checks} | "
                f"{'yes' if warned else 'no'} | "
                f"{'yes' if ok else '**no**'} |"
            )
        summary.append(f"{strategy}: {passed} of {len(truth)} new logs pass")
    return [*lines, "", *summary]
