"""``evaluate loop``'s report: per strategy and round, where the labels went and what they did to the new logs, to
the far runs the shipped model never saw, and what the workbench said of each new log."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from .loop_said import said_table

if TYPE_CHECKING:
    from .session_loop import LoopRound, LoopSettings


def _pct(x: float | None) -> str:
    return "–" if x is None or x != x else f"{100 * x:.1f}"


def loop_report(
    name: str,
    arms: dict[str, list[LoopRound]],
    settings: LoopSettings,
    *,
    family: str,
    new: Sequence[str],
    new_s: float,
    seconds: float,
    majority: tuple[str, float] = ("–", float("nan")),
) -> str:
    """Markdown: per strategy and round, where the labels went and what they did to the new logs."""
    lines = [
        f"# Session {name}: the loop on {len(new)} log(s) nobody had labelled ({new_s / 60:.1f} min)",
        "",
        f"{settings.rounds} round(s) of {settings.per_round} suggestions, the person labelling each as a "
        f"`{settings.person}`; after each round stage 2 of the {family} family from scratch on every label (as the "
        f"Retrain ends). Accuracy on the new logs' time nobody labelled, against the reference. {seconds:.0f} s.",
        "",
        f"Always the most common labelled terrain ({majority[0]}) would score {_pct(majority[1])} % on that time "
        "at the start.",
        "",
        "| strategy | round | labelled s (in new logs) | picks in new logs | in the worst new log | accuracy (%) | "
        "balanced (%) | the fit's figure on the labelled pieces (%) | checks in new logs right (spot checks) | the "
        "shipped model on far runs (%) (balanced; mean per run) | its figure for runs it never saw (%) (90 % "
        "interval) | answers changed (%): the most the round moved it |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for strategy, rounds in arms.items():
        for r in rounds:
            picks = f"{r.picks_new} of {r.picks}" if r.round else "–"
            worst = f"{r.picks_worst} ({r.worst})" if r.round else "–"
            checks = f"{r.checks[0]} of {r.checks[1]} ({r.spot[0]} of {r.spot[1]})" if r.checks[1] else "–"
            far = "–" if r.far is None else f"{_pct(r.far[0])} ({_pct(r.far[1])}; {_pct(_per_run(r.far_per_log))})"
            acc, low, high = r.unseen
            unseen = "–" if acc is None else _pct(acc) + ("" if low is None else f" ({_pct(low)}–{_pct(high)})")
            lines.append(
                f"| {strategy} | {r.round} | {r.labelled_s:.0f} ({r.new_s:.0f}) | {picks} | {worst} | "
                f"{_pct(r.accuracy)} | {_pct(r.balanced)} | {_pct(r.estimate)} | {checks} | {far} | {unseen} | "
                f"{_pct(r.changed)} |"
            )
    lines += ["", "Per new log after the last round (accuracy, %):", ""]
    names = list(new)
    lines += ["| strategy | " + " | ".join(names) + " |", "| --- |" + " --- |" * len(names)]
    for strategy, rounds in arms.items():
        last = rounds[-1].per_log
        lines.append(f"| {strategy} | " + " | ".join(_pct(last.get(n)) for n in names) + " |")
    far_names = list(next(iter(arms.values()))[-1].far_per_log)
    if far_names:
        lines += ["", "The shipped model per far run (kept out of the session), before the loop and after it (%):", ""]
        head = [*far_names, "mean per run"]
        lines += ["| strategy | " + " | ".join(head) + " |", "| --- |" + " --- |" * len(head)]
        for strategy, rounds in arms.items():
            first, last = rounds[0].far_per_log, rounds[-1].far_per_log
            cells = [f"{_pct(first.get(n))} → {_pct(last.get(n))}" for n in far_names]
            cells.append(f"{_pct(_per_run(first))} → {_pct(_per_run(last))}")
            lines.append(f"| {strategy} | " + " | ".join(cells) + " |")
    verified = {k: v[-1].verified for k, v in arms.items() if v[-1].verified is not None}
    if verified:
        lines += [
            "",
            "The workbench's figure for the session before the first round and after each, from verification checks "
            "(uniform pieces of the new logs' time nobody labelled, stratified by log, as spot checks of that round's "
            "model; never labelled, counted apart from the rounds'), corrected by its confidence (the status line's "
            "figure):",
            "",
            "| strategy | round | checks | the checks alone right (%) | estimate (%) (90 % interval) | truth (%) | "
            "covers |",
            "| --- | --- | --- | --- | --- | --- | --- |",
        ]
        for strategy, rounds in arms.items():
            for r in rounds:
                v = r.verified
                if v is None:
                    continue
                lines.append(
                    f"| {strategy} | {r.round} | {v.checks} | {_pct(v.checks_right)} | {_pct(v.accuracy)} "
                    f"({_pct(v.low)}–{_pct(v.high)}) | {_pct(v.truth)} | {'yes' if v.covers else '**no**'} |"
                )
        lines += [
            "",
            "Per new log after the last round, the Data tab's figure from the same checks (those that fell in it):",
            "",
            "| strategy | log | checks | estimate (%) (90 % interval) | truth (%) | covers | misses by (points) |",
            "| --- | --- | --- | --- | --- | --- | --- |",
        ]
        for strategy, v in verified.items():
            for name, (acc, low, high, n, truth) in v.per_run.items():
                if acc is None:
                    lines.append(f"| {strategy} | {name} | 0 | not checked | {_pct(truth)} | – | – |")
                    continue
                miss = max(0.0, low - truth, truth - high)  # type: ignore[operator]
                lines.append(
                    f"| {strategy} | {name} | {n} | {_pct(acc)} ({_pct(low)}–{_pct(high)}) | {_pct(truth)} | "
                    f"{'yes' if miss < 1e-9 else '**no**'} | {100 * miss:.1f} |"
                )
            covered, checked = v.runs_covered()
            lines.append(f"| {strategy} | all | | {covered} of {checked} runs' intervals cover the truth | | | |")
    lines += ["", *said_table({k: [(r.per_log, r.said) for r in v] for k, v in arms.items()})]
    return "\n".join(lines) + "\n"


def _per_run(per_log: dict[str, float]) -> float | None:
    """The mean of the far runs' accuracies, each run counted once (beside the mean over every step)."""
    return sum(per_log.values()) / len(per_log) if per_log else None
