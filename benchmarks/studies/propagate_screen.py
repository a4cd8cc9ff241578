"""Kept: a run's labels vote over its own frames with `w = exp(-(near/1.0)^2) · (1 - trust · max p)`. On walks never
used for the choice (seed 2): 93.0 % with all labels and 91.7 % with one terrain's, against the model's 91.6 %
(benchmarks/results/raw/loop/propagate-demo-s2-2026-11-27.txt).

The screen behind ``labeling.propagate`` (issue 65, item 3): how a run's own labels should be blended with the
model's answer on that run. Kept: ``w = exp(-(near / 1.0)^2) * (1 - trust * max p)``.

    python benchmarks/studies/propagate_screen.py demo|spliced|new-runs [--seed S] [--per-new N]

Each session: some runs labelled at 10 % in 5 s pieces, the others new with ``--per-new`` random 1 s labels inside
each (a person's first checks), stage 1 and a classifier trained on every label; then each new run's unlabelled time
is scored by the model alone, the vote of its labels alone (nearest labelled frames of the run, with time), and
blends of the two, with all of the run's labels and with those of its most labelled terrain only (a run labelled in
one terrain must not be painted with it). ``trust`` stands at the model's own estimate (no check of the run) and at
0.5 (checks found it wrong). ``demo``: 8 demo walks of 3 min; ``spliced`` and ``new-runs``: BorealTC as
``benchmarks/studies/loop_borealtc.py`` builds it. Minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))

from study_common import label_runs  # noqa: E402


def build(folder: Path, layout: str, *, seed: int, per_new: int) -> None:
    """The session: labelled runs, new runs with ``per_new`` random 1 s labels (author ``person``), both stages."""
    from loop_borealtc import build as boreal

    from sessions import Session
    from workbench import cycle
    from workbench.demo import generate_demo_logs

    if layout == "demo":
        files = generate_demo_logs(folder.parent / "logs", n_logs=8, minutes=3.0, seed=seed)
        with Session.create(folder) as s:
            logs = s.ingest(files)
            for name in sorted({t for x in logs for _, _, t in s.reference(x.id)}):
                s.add_terrain(name)
            label_runs(s, logs[:4], seed=seed)
    else:
        _, reference = boreal(folder, layout, per_terrain=1, changes=26, seed=seed)
        if reference is not None:
            with Session.open(folder) as s:
                s.import_reference(reference)
    rng = np.random.default_rng(seed)
    with Session.open(folder) as s:
        labelled = {g.log_id for g in s.segments()}
        for x in [x for x in s.logs() if x.id not in labelled]:
            ref, n, added = s.reference(x.id), round(x.rate_hz), 0
            while added < per_new:
                a = int(rng.integers(0, x.n_samples - n))
                _, r1, terrain = next(r for r in ref if r[0] <= a < r[1])
                stop = min(a + n, r1)
                if not any(g.start < stop and a < g.stop for g in s.segments(x.id)):
                    s.add_segment(x.id, a, stop, terrain, author="person", source="loop")
                    added += 1
        cycle.train_stage1(s)
        cycle.train_classifier(s, warm_start=False)


def screen(folder: Path) -> None:
    """Print each variant's accuracy on each new run's unlabelled time."""
    import labeling
    from sessions import Session
    from workbench import cycle

    s = Session.open(folder)
    terrains = [t.name for t in s.terrains()]
    scores = cycle.compute_scores(s, votes=False)
    model_classes = np.array([terrains.index(c) for c in scores.classes])
    p_version, bundle = cycle.active_predictor(s)
    logs = [x for x in s.logs() if x.id in scores.scores]
    outs = cycle.stage1_outputs(s, p_version, bundle, logs)
    authors: dict[int, set[str]] = {}
    for g in s.segments():
        authors.setdefault(g.log_id, set()).add(g.author)
    new = [x for x in logs if authors.get(x.id) == {"person"}]
    card = float((s.active_model("classifier").metrics.get("estimate") or {}).get("accuracy") or 0.8)
    rows: dict[tuple[str, str], dict[str, float]] = {}
    for labels_of in ("all", "one terrain"):
        for x in new:
            o = outs[x.id]
            frame_of = o.step_frames()
            segs = s.segments(x.id)
            if labels_of == "one terrain":
                most = max({g.terrain for g in segs}, key=lambda t: sum(g.length for g in segs if g.terrain == t))
                segs = [g for g in segs if g.terrain == most]
            steps = np.full(x.n_samples, -1)
            covered = np.zeros(x.n_samples, bool)
            for g in s.segments(x.id):
                covered[g.start : g.stop] = True
            for g in segs:
                steps[g.start : g.stop] = list(scores.classes).index(g.terrain)
            n = len(o.frame_hidden)
            low, high = np.full(n, 10**9), np.full(n, -2)
            np.minimum.at(low, frame_of, steps)
            np.maximum.at(high, frame_of, steps)
            frames = np.where((low == high) & (low >= 0), low, -1)
            votes = labeling.run_votes(
                np.asarray(o.frame_hidden), frames, len(scores.classes), times_s=np.arange(n) * o.config.hop / x.rate_hz
            ).rows(frame_of)
            truth = np.full(x.n_samples, -1)
            for a, b, t in s.reference(x.id):
                truth[a:b] = terrains.index(t)
            keep = (truth >= 0) & ~covered
            p = scores.scores[x.id].probs
            peak = p.max(axis=1, keepdims=True)

            def right(q: np.ndarray, keep=keep, truth=truth) -> float:
                return float((model_classes[q.argmax(axis=1)][keep] == truth[keep]).mean())

            r = rows.setdefault((labels_of, x.name), {})
            r["model"], r["vote alone"] = right(p), right(votes.votes)
            r["w = 1 - max p"] = right(labeling.blend_votes(p, labeling.RunVotes(votes.votes, np.zeros(len(p)))))
            for s0 in (0.5, 1.0, 1.5):
                for name, trust in (("estimate", card), ("0.5", 0.5)):
                    w = np.exp(-((votes.near[:, None] / s0) ** 2)) * (1 - trust * peak)
                    r[f"near {s0}, trust {name}"] = right((1 - w) * p + w * votes.votes)
    columns = list(rows)
    print("| variant | " + " | ".join(f"{c[1]} ({c[0]})" for c in columns) + " | mean, all | mean, one terrain |")
    print("| --- |" + " --- |" * (len(columns) + 2))
    for key in next(iter(rows.values())):
        values = [rows[c][key] for c in columns]
        mean_all = np.mean([rows[c][key] for c in columns if c[0] == "all"])
        mean_one = np.mean([rows[c][key] for c in columns if c[0] != "all"])
        cells = " | ".join(f"{100 * v:.1f}" for v in values)
        print(f"| {key} | {cells} | {100 * mean_all:.1f} | {100 * mean_one:.1f} |")
    s.close()


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("layout", choices=["demo", "spliced", "new-runs"])
    args.add_argument("--seed", type=int, default=0)
    args.add_argument("--per-new", type=int, default=12)
    opts = args.parse_args()
    data = ROOT.parent / "shared" / "data" / "borealtc"
    if opts.layout != "demo" and not data.is_dir():
        print(f"skipped: {data} is absent (BorealTC is not shipped with the project)")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        build(Path(tmp) / "s", opts.layout, seed=opts.seed, per_new=opts.per_new)
        screen(Path(tmp) / "s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
