"""What a pick in a run that changes terrain every few seconds should cover, and how its label should carry.

    python benchmarks/studies/changing_run_screen.py [--seed S] [--picks 24 48]

The hard stand-in of ``loop_borealtc.py spliced --motor-only --piece-s 5 30 --per-terrain 3``: BorealTC's motor
files alone (6.5 Hz), the session's other runs labelled at 10 % in 5 s pieces, one run spliced from pieces of 5-30 s
of runs kept out of it, nobody labelled. Stage 1 and a classifier are trained once; then ``--picks`` places that
many picks at random centres in the spliced run, labelled from the truth (one label per terrain inside, as a careful
person does), each as long as a variant says:

- ``1 s`` (the queue before), ``one window`` (the classifier's input span, what a pick is now at the least),
- ``stretch <= L s``: the stretch between the log's change points around the centre, at most ``L`` s,
- ``person's stretch``: one window, then on across the model's stretch around it while the truth stays the same
  terrain (``labeling.stretch_oracle``, the loop's ``--person stretch``).

Each variant is scored without a refit and after stage 2 is fitted again on every label, each with the run's vote
as the workbench blends it today (``labeling.run_votes`` over stage 1's embedding with time, ``blend_votes`` at the
run's trust), with a shorter time scale, and bounded by change points (a stretch that holds labels is voted by them
alone, as near as a labelled frame), the vote alone, and the blend at the trust of the card's estimate and of 1
(the model's confidence alone decides). Accuracy is on the spliced run's time the variant left unlabelled, and on the
whole run (its labels counted as what the session knows). The change points' own quality is printed first: how
many of the run's true changes they find within 2 s, and the ceiling of a stretch answered by its majority.
Minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import itertools
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))

DATA = ROOT.parent / "shared" / "data" / "borealtc"


def stretch_ids(n: int, points: np.ndarray) -> np.ndarray:
    """``(T,)`` each sample's stretch between change points."""
    return np.searchsorted(np.asarray(points), np.arange(n), side="right")


def bounded(q: np.ndarray, near: np.ndarray, steps: np.ndarray, sid: np.ndarray, k: int) -> tuple:
    """The vote ``q`` ``(T, K)`` with each stretch that holds labelled steps voted by their shares alone, as near
    as a labelled step."""
    q, near = q.copy(), near.copy()
    lab = steps >= 0
    for st in np.unique(sid[lab]):
        m = sid == st
        share = np.bincount(steps[m & lab], minlength=k).astype(np.float64)
        q[m] = share / share.sum()
        near[m] = 0.0
    return q, near


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("--seed", type=int, default=1)
    args.add_argument("--picks", type=int, nargs="+", default=[48])
    opts = args.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return 0
    from loop_borealtc import build

    import labeling
    from sessions import Session
    from workbench import cycle

    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "s"
        _, reference, _ = build(
            base, "spliced", per_terrain=3, changes=26, seed=opts.seed, motor_only=True, piece_s=(5.0, 30.0)
        )
        with Session.open(base) as s:
            s.import_reference(reference)
            cycle.train_stage1(s)
            cycle.train_classifier(s, warm_start=False)
            labelled_logs = {g.log_id for g in s.segments()}
            x = next(x for x in s.logs() if x.id not in labelled_logs)
            terrains = [t.name for t in s.terrains()]
            truth = np.full(x.n_samples, -1)
            for a, b, t in s.reference(x.id):
                truth[a:b] = terrains.index(t)
            points = cycle.signal_change_points(s, x)
            scores = cycle.compute_scores(s, votes=False)
            span = scores.span
            card = float((s.active_model("classifier").metrics.get("estimate") or {}).get("accuracy") or 0.8)
        rate = x.rate_hz
        true_changes = np.flatnonzero(np.diff(truth)) + 1
        found = [np.min(np.abs(points - c)) <= 2 * rate for c in true_changes] if len(points) else []
        sid = stretch_ids(x.n_samples, points)
        major = sum(np.bincount(truth[sid == i][truth[sid == i] >= 0]).max() for i in np.unique(sid))
        print(
            f"{x.name}: {x.n_samples} samples at {rate:.1f} Hz ({x.n_samples / rate:.0f} s), {len(true_changes)} "
            f"true changes, {len(points)} change points; {sum(found)} of {len(true_changes)} true changes within 2 s "
            f"of one; each stretch answered by its true majority: {100 * major / (truth >= 0).sum():.1f} %; "
            f"one window = {span} samples; the card's estimate {100 * card:.1f} %"
        )
        p0 = scores.scores[x.id].probs
        classes = list(scores.classes)
        truth_c = np.array([classes.index(terrains[t]) if t >= 0 else -1 for t in truth])
        rows: list[str] = []
        for n_picks in opts.picks:
            rng = np.random.default_rng(opts.seed)
            centres: list[int] = []
            while len(centres) < n_picks:
                c = int(rng.integers(span, x.n_samples - span))
                if all(abs(c - d) >= span for d in centres):
                    centres.append(c)
            right_first = sum(
                int(np.bincount(p0[max(0, c - span // 2) : c + span // 2].argmax(1)).argmax()) == truth_c[c]
                for c in centres
            )
            trust = labeling.run_trust(right_first, n_picks, prior=card)
            stretches = labeling.predicted_stretches(p0, window=max(1, round(rate)), min_len=max(1, round(2 * rate)))

            def extent(c: int, variant: str, stretches=stretches) -> list[tuple[int, int]]:
                if variant == "1 s":
                    a = c - round(rate) // 2
                    return [(a, a + round(rate))]
                a = c - span // 2
                if variant == "one window":
                    return [(a, a + span)]
                if variant == "person's stretch":
                    around = next(z for z in stretches if z.start <= c < z.stop)
                    return [
                        (lo, hi)
                        for _, lo, hi, _ in labeling.stretch_oracle(
                            (0, a, a + span), [truth], (around.start, around.stop)
                        )
                    ]
                most = round(float(variant.split("<=")[1].split()[0]) * rate)
                lo = int(points[points <= c].max()) if (points <= c).any() else 0
                hi = int(points[points > c].min()) if (points > c).any() else x.n_samples
                lo, hi = max(lo, c - most // 2), min(hi, c + most // 2)
                return [(lo, max(hi, lo + span))]

            for variant in ("1 s", "one window", "stretch <= 5 s", "stretch <= 10 s", "person's stretch"):
                steps = np.full(x.n_samples, -1)
                for c in centres:
                    for lo, hi in extent(c, variant):
                        for _, a, b, k in labeling.oracle((0, max(0, lo), min(x.n_samples, hi)), [truth_c]):
                            steps[a:b] = np.where(steps[a:b] < 0, k, steps[a:b])
                folder = Path(tmp) / f"v{n_picks}-{variant.replace(' ', '_').replace('<=', 'le')}"
                shutil.copytree(base, folder)
                with Session.open(folder) as s:
                    edges = np.flatnonzero(np.diff(np.r_[-2, steps, -2]))
                    for a, b in itertools.pairwise(edges):
                        if steps[a] >= 0:
                            s.add_segment(x.id, int(a), int(b), classes[steps[a]], author="person", source="loop")
                    outs = cycle.stage1_outputs(s, *cycle.active_predictor(s), [x])
                    o = outs[x.id]
                    frame_of = o.step_frames()
                    n = len(o.frame_hidden)
                    low, high = np.full(n, 10**9), np.full(n, -2)
                    np.minimum.at(low, frame_of, steps)
                    np.maximum.at(high, frame_of, steps)
                    frames = np.where((low == high) & (low >= 0), low, -1)
                    times = np.arange(n) * o.config.hop / rate
                    votes = {
                        scale: labeling.run_votes(
                            np.asarray(o.frame_hidden), frames, len(classes), times_s=times, time_scale_s=scale
                        ).rows(frame_of)
                        for scale in (60.0, 10.0)
                    }
                    keep = (truth_c >= 0) & (steps < 0)

                    def figures(p: np.ndarray, keep=keep, steps=steps) -> str:
                        ans = p.argmax(1)
                        whole = np.where(steps >= 0, steps, ans)
                        return (
                            f"{100 * (ans[keep] == truth_c[keep]).mean():.1f} / "
                            f"{100 * (whole[truth_c >= 0] == truth_c[truth_c >= 0]).mean():.1f}"
                        )

                    def blends(p: np.ndarray, steps=steps, votes=votes, trust=trust) -> dict[str, str]:
                        out = {"model": figures(p), "vote alone": figures(votes[60.0].votes)}
                        for scale, v in votes.items():
                            out[f"vote, time {scale:.0f} s"] = figures(labeling.blend_votes(p, v, trust=trust))
                        for name, level in (("the card's", card), ("1", 1.0)):
                            out[f"vote, time 60 s, trust {name}"] = figures(
                                labeling.blend_votes(p, votes[60.0], trust=level)
                            )
                        q, near = bounded(votes[10.0].votes, votes[10.0].near, steps, sid, len(classes))
                        out["vote, bounded"] = figures(labeling.blend_votes(p, labeling.RunVotes(q, near), trust=trust))
                        return out

                    before = blends(p0)
                    cycle.train_classifier(s, warm_start=False)
                    p1 = cycle.compute_scores(s, votes=False).scores[x.id].probs
                    after = blends(p1)
                    for key in before:
                        rows.append(
                            f"| {n_picks} | {variant} | {(steps >= 0).sum() / rate:.0f} | {key} | {before[key]} | "
                            f"{after[key]} |"
                        )
                    print(rows[-1].split("|")[2], f"done at {time.monotonic() - t0:.0f} s", flush=True)
                shutil.rmtree(folder, ignore_errors=True)
        print(f"\nthe run's trust from the picks' first answers: {right_first} of {n_picks} right -> {trust:.2f}\n")
        print("Accuracy (%) on the run's unlabelled time / on the whole run (labels counted as known):\n")
        print("| picks | a pick is | labelled s | answer | no refit | stage 2 fitted again |")
        print("| --- | --- | --- | --- | --- | --- |")
        print("\n".join(rows))
    print(f"\n{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
