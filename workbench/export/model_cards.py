"""The exported model card (``MODEL_CARD.md``): what a bundle is, what it was trained on, how well it does on new
runs, and where it does not know."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from training import (
    ModelBundle,
    estimate_headline,
    estimate_table,
    majority_words,
    parameter_count,
    unseen_words,
)

from ..cycle import ChecksSummary, SessionFigure, estimate_disagrees
from ..expectations import SHORTEST_STRETCH_S, card_accuracy


def _estimate_section(m: dict) -> list[str]:
    """Per terrain the figure that exists for the labels the session has, and which it is
    (``training.figures.estimates``)."""
    estimate = m.get("estimate")
    if not estimate:
        return _held_out_section(m)
    words = estimate_headline(estimate) or "not measurable"
    balanced = estimate.get("balanced_accuracy")
    return [
        "## On the labelled pieces, held out",
        "",
        "What the fit measured on the labels themselves, each predicted by a model fitted without it. It describes "
        "where the labels are: suggestions place them where the model was unsure, so after a few rounds it runs far "
        "below the session's accuracy above; the per-terrain table shows which terrains those places confuse.",
        "",
        f"**{words}**" + (f", balanced accuracy {balanced:.1%}" if balanced is not None else "") + ".",
        "",
        f"Beside it, {majority_words(estimate)} on the same steps." if majority_words(estimate) else "",
        "",
        f"{estimate['note'][:1].upper()}{estimate['note'][1:]}." if estimate["note"] else "",
        "",
        "A terrain labelled in two logs or more is measured on held-out logs: each of its labelled steps predicted by "
        "a model fitted without any label or signal of its log. A terrain labelled in one log cannot be (holding the "
        "log out removes the terrain); it gets a same-run figure: contiguous blocks of its log held out, a guard "
        "wider than the model's input between them and the training time. Same-run figures flatter what a new run "
        "will score: its surface, speed and mounting were in training.",
        "",
        *estimate_table(estimate),
        "",
    ]


def _session_section(figure: SessionFigure | None, logs: int) -> list[str]:
    """How right the session is at export, from the person's uniform checks of this version
    (``cycle.session_figures``)."""
    if figure is None or figure.version is None:
        return []
    how = (
        "measured by the person's spot checks of this version (pieces drawn at random from the time nobody "
        "labelled, each a test before it trained anything), corrected by the model's confidence over all that time "
        "(prediction-powered inference; `labeling.powered_accuracy`). It is the session's figure, not the robot's: "
        "the next section is."
    )
    if figure.figure is not None:
        head = f"**{figure.words()}** of the time nobody labelled in the session's {logs} logs is named right, {how}"
    else:
        head = (
            f"**{figure.words()}**: no spot check of this version yet, so no figure for the session. "
            f"`workbench suggest SESSION --verify --out FILE` writes uniform checks to label ({figure.plan_words()})."
        )
    return ["## How right the session is", "", head, ""]


def _unseen_section(m: dict) -> list[str]:
    """What the model that ships is expected to score on a run it never saw (``training.figures.unseen_runs``)."""
    got = m.get("unseen_runs")
    words = unseen_words(got)
    if words is None:
        return []
    per_run = got.get("per_run") or {}
    spread = (
        f" Per held-out run: {min(per_run.values()):.0%} to {max(per_run.values()):.0%}." if len(per_run) > 1 else ""
    )
    return [
        "## On the robot's next run",
        "",
        f"**{words}**.{spread}",
        "",
        "Each run with labels held out in turn: a model fitted without any label or stretch of it predicted it, "
        "scored on its labels and on the terrain the session's scores were sure of over its unlabelled time. This is "
        "what to expect of this bundle on a run it never saw; the figures below describe the session's labels. The "
        "interval resamples runs: one run that looks like another terrain is wrong all through.",
        "",
    ]


def _checks_section(checks: ChecksSummary | None, m: dict) -> list[str]:
    """What the person's checks said: each label made where a model already answered, before it trained on it."""
    if checks is None or checks.all is None:
        return []
    lines = [
        "## Your checks",
        "",
        "Each label made in the page (or imported from `workbench suggest`'s file) first tested the model the person "
        "was looking at, on time it had not trained on. Spot checks are drawn at random from the unlabelled time: "
        "their share right is a fair estimate there; the checks of ranked suggestions are where the model was "
        "unsure, drifted or unchecked, and run low. Earlier models answered the earlier checks.",
        "",
        f"- all: {checks.all.words()}",
    ]
    if checks.spot is not None:
        lines.append(f"- spot checks: {checks.spot.words('spot checks')}")
    if checks.suggested is not None:
        lines.append(f"- suggestions and manual labels: {checks.suggested.words()}")
    card = card_accuracy(m)
    if estimate_disagrees(card, checks.spot):
        lines.append(
            f"- **the estimate above ({100 * card:.0f} %) lies outside the spot checks' interval by 10 points or "
            "more: trust the spot checks on these runs**"
        )
    return [*lines, ""]


def _held_out_section(m: dict) -> list[str]:
    """The honest figure, when the fit measured it: accuracy on logs whose labels and signals trained nothing."""
    held = m.get("held_out_logs")
    if not held:
        return []
    return [
        "## Held-out logs",
        "",
        f"Each labelled step predicted by a model fitted without any label or signal of its log ({held['folds']} "
        f"folds over the {held['logs']} labelled logs). Expect this on logs the model never saw.",
        "",
        f"- accuracy: {held['accuracy']:.1%}",
        f"- macro-F1: {held['macro_f1']:.3f}",
        "",
        "| terrain | recall |",
        "| --- | --- |",
        *[f"| {c} | {r:.1%} |" for c, r in held.get("per_class_recall", {}).items()],
        "",
    ]


def _logs(n: int) -> str:
    """``"1 log with no label is"``, ``"3 logs with no label are"``: the card's subject and its verb."""
    return f"{n} log with no label is" if n == 1 else f"{n} logs with no label are"


def _drift_section(
    bundle: ModelBundle,
    drifted: Mapping[str, float] | None,
    unlabelled: Mapping[str, tuple[float, int]] | None = None,
    agreement: float | None = None,
    members: tuple[float, int] | None = None,
) -> list[str]:
    """The drift score and the temperature: what they mean and how much of the session lies past the line."""
    if bundle.drift is None:
        return []
    q = bundle.drift.quantile
    lines = [
        "## Where the model does not know",
        "",
        "Each step gets a drift score: how far its input lies, in the classifier's embedding, from the labelled "
        f"frames (the mean distance to the {bundle.drift.neighbours} nearest), in units of the distance that only "
        f"{1 - q:.0%} of held-out labelled time exceeds. Above 1 the step is unlike anything labelled: the figures "
        "above were measured on labelled time, so they do not hold there. `workbench classify` writes the score in "
        "a `drift` column and warns for a file mostly above 1; the UI draws it as the drift row and suggests such "
        "time first.",
        "",
    ]
    if drifted:
        total = float(np.mean(list(drifted.values())))
        worst = sorted(drifted.items(), key=lambda kv: -kv[1])[:10]
        lines += [
            f"In this session, {total:.0%} of the logs' time (mean over {len(drifted)} logs) scores above 1.",
            "",
            "| log | time above 1 |",
            "| --- | --- |",
            *[f"| {name} | {share:.0%} |" for name, share in worst],
            "",
        ]
    if members is not None:
        lines += [
            f"By their members' agreement, the {_logs(members[1])} expected to score "
            f"**{members[0]:.0%}**: how often two of the ensemble's members name the same terrain there, the figure "
            "the Data tab and `workbench classify` give first (on BorealTC's held-out runs within 10 points of what "
            "a run scored on 62 % of them, the drift's figure below on 46 %; it reads high where every member is "
            "wrong alike; docs/model.md).",
            "",
        ]
    if unlabelled:
        weight = np.asarray([n for _, n in unlabelled.values()], np.float64)
        expected = float(np.average([e for e, _ in unlabelled.values()], weights=weight))
        lines += [
            f"At their drift, the {_logs(len(unlabelled))} expected to score **{expected:.0%}** "
            "(each log's steps read through the relation between drift and accuracy measured on held-out labelled "
            "blocks; `workbench classify` prints the same per file). Nearer what new runs score than a same-run "
            "figure, and still above it where every terrain is labelled in one run (docs/model.md).",
            "",
        ]
        if agreement is not None:
            lines += [
                f"Their predictions agree with the most predicted terrain of their stretch on **{agreement:.0%}** of "
                f"their steps (stretches between change points, none under {SHORTEST_STRETCH_S:g} s): where each "
                "stretch is one terrain, they score at most that, and that where each stretch's most predicted "
                "terrain is right (docs/model.md).",
                "",
            ]
    cal = bundle.metrics.get("calibration") or {}
    if cal.get("on"):
        lines += [
            f"The ensemble's probabilities are calibrated: every member's logits are divided by "
            f"{cal['temperature']:.2f}, fitted on {cal['n']:,} predictions of {cal['on']} (temperature scaling).",
            "",
        ]
    return lines


def model_card(
    bundle: ModelBundle,
    *,
    version: int,
    session: str,
    drifted: Mapping[str, float] | None = None,
    unlabelled: Mapping[str, tuple[float, int]] | None = None,
    unlabelled_agreement: float | None = None,
    unlabelled_members: tuple[float, int] | None = None,
    checks: ChecksSummary | None = None,
    figure: SessionFigure | None = None,
    logs: int = 0,
    which: str | None = None,
    terrain_map: str | None = None,
) -> str:
    """A Markdown description of a bundle: what it is, what it was trained on, how well it does, and where it does
    not know (``drifted``: per log name, the share of its time with a drift score above 1; ``unlabelled``: per log
    with no label, the accuracy expected at its drift and its steps; ``unlabelled_agreement``: the share of those
    logs' steps predicted as their stretch's most predicted terrain; ``unlabelled_members``: the mean of the
    steps' members' agreement over the logs with no label (``labeling.member_agreement``) and how many they are;
    ``checks``: what the person's checks said, test then train; ``figure``: how right the session is, from the
    spot checks of this version, over its ``logs`` logs; ``which``: which of the session's versions it is, taught or
    not, as ``cycle.shipped_version`` says; ``terrain_map``: the picture of the logs' paths beside the card, and
    what it shows)."""
    m, family = bundle.metrics, bundle.stage2_family()
    lines = [
        f"# Terrain classifier v{version}",
        "",
        f"From session `{session}`. {family.describe(bundle)} {parameter_count(bundle):,} parameters.",
        "",
        *([f"This bundle: {which}.", ""] if which else []),
        "## Inputs",
        "",
        f"{len(bundle.channels)} channels at {bundle.rate_hz:g} Hz, in this order (raw units; the model normalises):",
        "",
        ", ".join(f"`{c}`" for c in bundle.channels),
        "",
        "## Training data",
        "",
        f"- stage 1: {bundle.info.get('logs', '?')} logs, {bundle.info.get('timesteps', 0):,} timesteps",
        f"- stage 2: {m.get('n_segments', '?')} labelled segments, {m.get('labelled_seconds', 0):.0f} s "
        f"({m.get('labelled_fraction', 0):.1%} of the time)",
        "",
        *_session_section(figure, logs),
        *_unseen_section(m),
        *_estimate_section(m),
        *_checks_section(checks, m),
        *_drift_section(bundle, drifted, unlabelled, unlabelled_agreement, unlabelled_members),
        *(["## Where each terrain was", "", terrain_map, ""] if terrain_map else []),
        "## Out-of-fold metrics (same logs)",
        "",
        "Each labelled step predicted, in a pass over its whole log, by the fold model that did not train on it "
        "(the default family holds out blocks of labelled time, so these are same-run figures for every terrain). "
        "The other labelled time of the same logs did train that model, so these figures flatter what to expect on "
        "logs the model never saw; `workbench evaluate session SESSION --reference FILE` measures that, holding out "
        "whole logs.",
        "",
        f"- accuracy: {m.get('accuracy', float('nan')):.1%}",
        f"- macro-F1: {m.get('macro_f1', float('nan')):.3f}",
        "",
        "| terrain | recall |",
        "| --- | --- |",
        *[f"| {c} | {r:.1%} |" for c, r in m.get("per_class_recall", {}).items()],
        "",
        "Confusion matrix (rows: true, columns: predicted):",
        "",
        "| | " + " | ".join(bundle.classes) + " |",
        "| --- " * (len(bundle.classes) + 1) + "|",
        *[
            f"| {c} | " + " | ".join(str(v) for v in row) + " |"
            for c, row in zip(bundle.classes, m.get("confusion", []), strict=False)
        ],
        "",
        "## Use",
        "",
        "```python",
        "from training import StreamingClassifier, load_bundle",
        "clf = StreamingClassifier(load_bundle('bundle'))",
        "probs = clf.step(sample)   # one raw sample (channels above) -> probabilities of " + ", ".join(bundle.classes),
        "```",
        "",
        family.onnx_usage(bundle),
    ]
    return "\n".join(lines) + "\n"
