"""``train --model auto``: fit every family that reads the default stage 1, keep the one the session's own held-out
evidence favours, and say why.

Which family wins differs by robot (a wearable gait set: MiniRocket 78.6 % against the default's 75.3; a quadruped
and BorealTC's runs: the default), so the choice is made per session, from the estimates the fits already make:
both families are fitted on the same labels with the same folds, so their estimates are of the same kind (held-out
logs, held-out blocks or same run) and compare directly. Balanced accuracy decides (a family that only answers the
common terrain better does not win); another family replaces the registry's first only when it leads by at least
``MARGIN`` (the fold figures' noise at a few labelled logs is of that order), so a tie keeps the default. Every fit
stays a version: the Train tab can make the other one active.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, replace

import training
from sessions import ModelVersion, Session

from .stage2_fit import train_classifier

MARGIN = 0.01  # balanced accuracy another family must lead the first by to be kept


@dataclass(frozen=True)
class FamilyChoice:
    """The fits of ``--model auto`` and the one kept.

    Attributes:
        kept: The version made active.
        fitted: Every version fitted, in registry order (``kept`` among them).
        why: One sentence: each family's figure and the rule that chose.
    """

    kept: ModelVersion
    fitted: tuple[ModelVersion, ...]
    why: str


def auto_families() -> tuple[str, ...]:
    """The families ``auto`` chooses among: those over the default's stage 1 (the next-frame predictor), so the
    session's one stage 1 serves them all; the registry's first (the default) first."""
    return tuple(n for n in training.family_names() if training.family(n).stage1 == "next-frame")


def evidence(metrics: Mapping) -> tuple[float | None, str]:
    """A version's held-out evidence: its balanced accuracy (its accuracy where the balanced figure is missing), and
    the words saying what was measured; ``None`` when nothing was."""
    estimate = metrics.get("estimate") or {}
    value = estimate.get("balanced_accuracy")
    words = "balanced"
    if value is None or value != value:
        value, words = estimate.get("accuracy"), "accuracy"
    if value is None or value != value:
        return None, "not measurable"
    return float(value), f"{words} {100 * value:.1f} % ({training.estimate_headline(estimate)})"


def train_best_classifier(session: Session, **fit) -> FamilyChoice:
    """Fit stage 2 of every :func:`auto_families` family from scratch; the best by :func:`evidence` is active.

    Args:
        session: The session (its active predictor must be the default's stage 1).
        **fit: Passed on to :func:`train_classifier` (``progress``, ``cancel``, ``window``).
    """
    names = auto_families()
    progress = fit.pop("progress", None)
    t0 = time.monotonic()

    def overall(i: int) -> training.ProgressFn | None:
        """Family ``i``'s progress as a share of every family's (each taken as long as the others), so a bar and its
        time left run once from 0 to 100 %."""
        if progress is None:
            return None
        return lambda p: progress(
            replace(p, fold=i * p.folds + max(p.fold, 1), folds=len(names) * p.folds, elapsed_s=time.monotonic() - t0)
        )

    fitted = tuple(
        train_classifier(session, model=name, warm_start=False, progress=overall(i), **fit)
        for i, name in enumerate(names)
    )
    scored = [(evidence(v.metrics), name, v) for name, v in zip(names, fitted, strict=True)]
    (first_value, _), first_name, kept = scored[0]
    measured = [(value, name, v) for (value, _), name, v in scored[1:] if value is not None]
    best = max(measured, key=lambda s: s[0], default=None)
    said = "; ".join(f"{name} {words}" for (_, words), name, _ in scored)
    if best is not None and (first_value is None or best[0] >= first_value + MARGIN):
        kept = best[2]
        rule = f"kept {best[1]}, ahead of {first_name} by {100 * MARGIN:g} point(s) or more"
    elif best is not None:
        rule = f"kept {first_name}: no other family led it by {100 * MARGIN:g} point(s) or more"
    else:
        rule = f"kept {first_name}: no other family could be measured"
    session.activate_model(kept.id)
    kept = next(v for v in session.model_versions("classifier") if v.id == kept.id)
    return FamilyChoice(kept, fitted, f"{said}: {rule}")
