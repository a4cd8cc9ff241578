"""The estimate a fit reports: per terrain, the figure that exists for the labels the session has, and which it is.

A terrain labelled in two logs or more is measured on held-out logs: each of its steps predicted by a model that
never saw its log. A terrain labelled in one log cannot be: holding its log out removes it from training. It gets a
same-run figure (blocks of its log held out, :mod:`.blocking`), which flatters what a new run will score; where
some terrains have both figures, the gap between them says by how much.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

HELD_OUT = "held-out logs"
SAME_RUN = "same run"
MIXED = "held-out logs and same run"
NOT_MEASURED = "not measurable"
MISSED_RECALL = 0.5  # a terrain whose measured recall is below this is named: the model misses it


def _recall(true: np.ndarray, pred: np.ndarray, k: int) -> float | None:
    mask = true == k
    return float((pred[mask] == k).mean()) if mask.any() else None


def terrain_estimate(
    classes: Sequence[str],
    logs_per_class: Mapping[int, int],
    same_run: tuple[np.ndarray, np.ndarray],
    held_out: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict:
    """Per terrain the figure that exists, and one headline over them.

    Args:
        classes: The ``K`` class names.
        logs_per_class: Labelled logs of each class index (classes never labelled are left out).
        same_run: Truth and prediction ``(N,)`` of every step that blocked folds could score (a step of a terrain
            its fold's model never trained on is not in it).
        held_out: The same from folds over logs, for terrains labelled in two logs or more (steps of a terrain
            missing from a fold's training logs left out), or ``None`` when no fit held logs out.

    Returns:
        ``accuracy`` and ``balanced_accuracy`` over each terrain's chosen figure (``None`` when no terrain could
        be measured), ``kind`` (which figures it rests on), ``per_terrain`` (name -> ``recall``, ``by``, ``logs``,
        ``same_run``, ``held_out``), ``gap`` (mean same-run minus held-out-logs recall over the terrains measured
        both ways, ``None`` when none is) with ``gap_terrains``, ``majority`` (the terrain most common among the
        steps measured and the accuracy of always answering it: the baseline), and ``note``, one line for the
        person deciding whether to label more (first, when the model is no better than that baseline).
    """
    s_true, s_pred = (np.asarray(a) for a in same_run)
    h_true, h_pred = (np.asarray(a) for a in held_out) if held_out is not None else (np.zeros(0), np.zeros(0))
    per: dict[str, dict] = {}
    chosen_true, chosen_pred, gaps = [], [], []
    for k, name in enumerate(classes):
        if logs_per_class.get(k, 0) == 0:
            continue
        same, held = _recall(s_true, s_pred, k), _recall(h_true, h_pred, k)
        if held is not None:
            by, recall, src = HELD_OUT, held, (h_true, h_pred)
        elif same is not None:
            by, recall, src = SAME_RUN, same, (s_true, s_pred)
        else:
            by, recall, src = NOT_MEASURED, None, None
        if src is not None:
            mask = src[0] == k
            chosen_true.append(src[0][mask])
            chosen_pred.append(src[1][mask])
        if same is not None and held is not None:
            gaps.append(same - held)
        per[name] = {"recall": recall, "by": by, "logs": int(logs_per_class[k]), "same_run": same, "held_out": held}
    kinds = {e["by"] for e in per.values()} - {NOT_MEASURED}
    kind = HELD_OUT if kinds == {HELD_OUT} else SAME_RUN if kinds == {SAME_RUN} else MIXED if kinds else NOT_MEASURED
    majority = None
    if chosen_true:
        t, p = np.concatenate(chosen_true), np.concatenate(chosen_pred)
        accuracy = float((t == p).mean())
        balanced = float(np.mean([e["recall"] for e in per.values() if e["recall"] is not None]))
        counts = np.bincount(t.astype(np.int64), minlength=len(classes))
        # always answering the most common terrain of the same steps: the figure a model must beat to mean anything
        majority = {"terrain": classes[int(counts.argmax())], "accuracy": float(counts.max() / len(t))}
    else:
        accuracy = balanced = None
    gap = float(np.mean(gaps)) if gaps else None
    return {
        "accuracy": accuracy,
        "balanced_accuracy": balanced,
        "kind": kind,
        "per_terrain": per,
        "gap": gap,
        "gap_terrains": len(gaps),
        "majority": majority,
        "note": _note(per, kind, gap, len(gaps), below=_below_majority(accuracy, majority)),
    }


def _below_majority(accuracy: float | None, majority: Mapping | None) -> str:
    """``"below always answering grass (76 %)"`` when the accuracy is not above the majority baseline, else empty."""
    if accuracy is None or majority is None or accuracy > majority["accuracy"]:
        return ""
    return f"no better than always answering {majority['terrain']} ({100 * majority['accuracy']:.0f} %)"


def majority_words(estimate: Mapping) -> str | None:
    """``"always the most common terrain (grass): 76 %"``; ``None`` for an estimate without one (saved before it
    existed, or nothing measured)."""
    m = estimate.get("majority")
    if not m:
        return None
    return f"always the most common terrain ({m['terrain']}): {100 * m['accuracy']:.0f} %"


def missed_terrains(estimate: Mapping, *, below: float = MISSED_RECALL) -> list[tuple[str, float]]:
    """The terrains whose measured recall is under ``below`` (name, recall), worst first: the ones a person should
    label more of. Read from ``per_terrain``, so an estimate saved before this existed gives them too."""
    per = estimate.get("per_terrain") or {}
    low = [(n, float(e["recall"])) for n, e in per.items() if e.get("recall") is not None and e["recall"] < below]
    return sorted(low, key=lambda x: x[1])


def terrain_recalls(estimate: Mapping | None, classes: Sequence[str]) -> np.ndarray:
    """Each of ``classes``' measured recall in ``estimate["per_terrain"]``, ``(K,)``, NaN where none was measured:
    what the suggestions read to ask for a missed terrain."""
    per = (estimate or {}).get("per_terrain") or {}
    return np.asarray(
        [r if (r := (per.get(c) or {}).get("recall")) is not None else np.nan for c in classes], np.float64
    )


def missed_words(missed: Sequence[tuple[str, float]]) -> str:
    """``"the model misses sand (15 % recall), grass (40 %)"``; empty when nothing is missed."""
    if not missed:
        return ""
    named = [f"{n} ({100 * r:.0f} % recall)" if i == 0 else f"{n} ({100 * r:.0f} %)" for i, (n, r) in enumerate(missed)]
    return "the model misses " + _names(named)


def _note(per: Mapping[str, dict], kind: str, gap: float | None, gap_terrains: int, *, below: str = "") -> str:
    one_log = sorted(n for n, e in per.items() if e["by"] == SAME_RUN)
    unmeasured = sorted(n for n, e in per.items() if e["by"] == NOT_MEASURED)
    parts = [f"the model is {below}"] if below else []
    missed = missed_terrains({"per_terrain": per})
    if missed:  # first: what the person can fix by labelling
        parts.append(f"{missed_words(missed)}: label more of {'it' if len(missed) == 1 else 'them'}")
    if kind == HELD_OUT:
        parts.append("measured on held-out logs: expect about this on new runs")
    elif one_log:
        who = "every terrain is" if kind == SAME_RUN else f"{_names(one_log)} {'is' if len(one_log) == 1 else 'are'}"
        if gap is not None:
            drop = (
                f"on the {gap_terrains} terrain{'s' if gap_terrains > 1 else ''} measured both ways new runs scored "
                f"{100 * gap:.0f} points {'lower' if gap >= 0 else 'higher'} than the same run"
            )
        else:
            drop = "by how much is measurable once a terrain is labelled in two logs"
        parts.append(f"{who} labelled in one log only: same-run figure, new runs may score lower ({drop})")
    if unmeasured:
        parts.append(f"{_names(unmeasured)}: one labelled piece, not measurable")
    return "; ".join(parts)


def _names(names: Sequence[str]) -> str:
    return ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")


def estimate_headline(estimate: Mapping) -> str | None:
    """The estimate in a few words: ``"82 % on held-out logs"``, ``"95 % same run"``, or for a mix
    ``"88 % (3 terrains on held-out logs, 2 same run)"``; ``None`` when nothing could be measured."""
    acc = estimate.get("accuracy")
    if acc is None or acc != acc:
        return None
    kind = estimate.get("kind")
    if kind == HELD_OUT:
        return f"{100 * acc:.0f} % on held-out logs"
    if kind == SAME_RUN:
        return f"{100 * acc:.0f} % same run"
    by = [e["by"] for e in estimate.get("per_terrain", {}).values()]
    return f"{100 * acc:.0f} % ({by.count(HELD_OUT)} terrains on held-out logs, {by.count(SAME_RUN)} same run)"


def estimate_table(estimate: Mapping) -> list[str]:
    """Markdown rows, one per terrain: its recall, which figure it is, the logs it is labelled in, both figures."""

    def pct(x: float | None) -> str:
        return "–" if x is None else f"{100 * x:.1f} %"

    lines = [
        "| terrain | recall | measured by | labelled logs | same run | held-out logs |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for name, e in estimate.get("per_terrain", {}).items():
        lines.append(
            f"| {name} | {pct(e['recall'])} | {e['by']} | {e['logs']} | {pct(e['same_run'])} | {pct(e['held_out'])} |"
        )
    return lines
