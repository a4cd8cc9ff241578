"""The paper family's Retrain on long logs, where its stage 2's consistency term applies: its cost and what it buys.

The QCAT-scale retrain bench (``bench_retrain.py``) cuts its session into trials too short to hold a pair of
neighbouring windows, so the consistency term (``TrainConfig.consistency``) costs nothing there. Real fleets record
walks of minutes, where every optimiser step of stage 2 also runs 32 pairs of unlabelled windows. This bench measures
what that costs a person who presses Retrain, on a session of demo walks of about 5 minutes each (why the term
is off by default). It takes about 45 minutes on 2 cores, so it is not one of ``make bench``'s benches (the
product's figures); run it by hand. The default family's Retrain on long walks is
``bench_retrain_long.py``. What this one does:

- A person has labelled ``SETUP_LABELS`` one-second stretches inside the walks' terrain patches and trained; they
  label ``NEW_LABELS`` more and press Retrain. Both stages use the paper's width (hidden 200, k = 5).
- **The term on (weight 3, ``workbench train --consistency 3``)** against **the reference, labels only (weight 0,
  the default)**, from the same active model in the same process:
  - the UI's Retrain (``TrainJob`` without its refining phase): pressed → the scores of the log on screen
    refreshed, then every log rescored;
  - the from-scratch stage 2 of the Retrain's refining phase, timed alone.
- **Accuracy**: per-timestep accuracy on every sample nobody labelled, against the walks' reference terrains, after
  each of the four trainings.
"""

from __future__ import annotations

import tempfile
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from common import Row, fmt_s, hosted_like_the_server, parse_args, record
from walk_session import HIDDEN, labelled_after_training, unlabelled_accuracy, walk_session

from sessions import Session
from training import TrainConfig
from workbench import cycle
from workbench.cycle import compute_scores
from workbench.retrain import RETRAIN
from workbench.ui import SharedState, TrainJob

WEIGHT = 3.0  # the weight the BorealTC simulation measured (the default is 0: labels only)


def retrain(session: Session, config: TrainConfig, shown: int) -> tuple[float, float, float]:
    """The UI's Retrain without its refining phase: seconds to the log on screen, to every log, and the accuracy."""
    state = SharedState(session)
    while not state.scored or state.busy:
        time.sleep(0.05)
    state.set_viewed("bench", shown)
    before = session.active_model("classifier").id
    n_logs = len(session.logs())
    events: list[tuple[float, int]] = []
    done = threading.Event()

    def heard(event: str) -> None:
        if event == "scores" and state.scores.classifier not in (None, before):
            events.append((time.perf_counter(), len(state.scores.scores)))
            if len(state.scores.scores) == n_logs:
                done.set()

    state.subscribe(heard)
    job = TrainJob(state, hidden=HIDDEN, classifier_config=config, refine=False)
    t0 = time.perf_counter()
    job.start()
    done.wait(3600)
    while job.running:
        time.sleep(0.05)
    acc = unlabelled_accuracy(session, state.scores)
    state.stop()
    return events[0][0] - t0, events[-1][0] - t0, acc


def main() -> None:
    args = parse_args(__doc__)
    n_logs, minutes = (3, 1.0) if args.quick else (8, 5.0)
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        session, logs = walk_session(folder, n_logs=n_logs, minutes=minutes)
        total = sum(x.n_samples for x in logs)
        # the term is the paper family's: its classifier, which every Retrain after keeps
        setup = labelled_after_training(session, rng, model="paper", config=RETRAIN.classifier)
        labelled = sum(s.length for s in session.segments())
        shown = logs[-1].id
        runs = {}
        for weight in (0.0, WEIGHT):  # the reference first: the term's run cannot profit from a warmer cache
            config = replace(RETRAIN.classifier, consistency=weight)
            session.activate_model(setup.id)
            torch.manual_seed(0)
            t_view, t_all, acc_quick = hosted_like_the_server(lambda c=config: retrain(session, c, shown))
            torch.manual_seed(0)
            t = time.perf_counter()
            cycle.train_classifier(session, config=config, hidden=HIDDEN, warm_start=False)
            t_scratch = time.perf_counter() - t
            acc_scratch = unlabelled_accuracy(session, compute_scores(session))
            pairs = int(session.active_model("classifier").config["consistency_pairs"])
            runs[weight] = (t_view, t_all, acc_quick, t_scratch, acc_scratch, pairs)
            print(
                f"consistency {weight:g}: view {t_view:.1f} s, all {t_all:.1f} s, quick {100 * acc_quick:.2f} %, "
                f"from scratch {t_scratch:.1f} s, {100 * acc_scratch:.2f} %",
                flush=True,
            )
    on, off = runs[WEIGHT], runs[0.0]
    where = (
        f"{len(logs)} walks, {total / logs[0].rate_hz / 60:.0f} min, {labelled / logs[0].rate_hz:.0f} s "
        f"labelled, {on[5]} pairs"
    )
    rows = [
        Row(
            f"Retrain pressed → log in view refreshed, consistency {WEIGHT:g} ({where})",
            f"{fmt_s(on[0])} (all logs: {fmt_s(on[1])})",
            f"labels only (consistency 0): {fmt_s(off[0])} (all logs: {fmt_s(off[1])})",
            f"{on[0] / off[0]:.2f}× the time",
            "≤ 15 s",
            bool(on[0] <= 15.0),
            f"unlabelled time: {100 * on[2]:.2f} % with the term, {100 * off[2]:.2f} % without",
        ),
        Row(
            f"Retrain's refining phase: stage 2 from scratch, consistency {WEIGHT:g} ({where})",
            fmt_s(on[3]),
            f"labels only (consistency 0): {fmt_s(off[3])}",
            f"{on[3] / off[3]:.2f}× the time",
            "–",
            None,
            f"unlabelled time: {100 * on[4]:.2f} % with the term, {100 * off[4]:.2f} % without",
        ),
    ]
    record("paper_consistency", rows, device=args.device)


if __name__ == "__main__":
    main()
