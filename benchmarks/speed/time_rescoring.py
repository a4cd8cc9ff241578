"""A Retrain's rescoring of every log, in one process per core against one process, on a session ``bench_fleet.py``
built and trained (nothing else running; the two alternate, ``--repeats`` times each):

    python benchmarks/speed/bench_fleet.py --hours 10 --keep /tmp/f10 --until train
    python benchmarks/speed/time_rescoring.py /tmp/f10/session [--repeats 2]

What is timed is ``cycle.score_and_store`` with the kept scores removed first, as after a Retrain: every log scored,
written, the tracks ranked over the session. The reference is the same call with ``jobs=1`` (every log in this
process, torch on every core). The outputs are compared: the largest difference of the probabilities between the
two, and the share of steps with the same most probable terrain. Target (issue 85): at 10 h of logs, ≤ 30 s.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT.parents[1]))

from speed_common import Row, record  # noqa: E402

TARGET_S = 30.0  # at 10 h


def rescore(session_path: Path, jobs: int | None) -> tuple[float, dict, int]:
    """Seconds of one rescoring, its probabilities per log (copied out of the kept files) and its processes."""
    from sessions import Session
    from training import load_bundle
    from workbench import cycle

    with Session.open(session_path) as s:
        for folder in s.path.glob("cache/scores-*"):  # nothing kept for the models: what a Retrain leaves
            (folder / "meta.json").unlink(missing_ok=True)
        t = time.perf_counter()
        got = cycle.score_and_store(s, score=cycle.compute_scores, jobs=jobs)
        seconds = time.perf_counter() - t
        p = s.active_model("predictor")
        logs = cycle.model_logs(s, load_bundle(s.path / p.path).channels)
        processes = cycle.scoring_processes(logs) if jobs is None else jobs
        assert got is not None
        probs = {i: np.array(v.probs) for i, v in got.scores.items() if v.probs is not None}
    return seconds, probs, processes


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("session", type=Path)
    p.add_argument("--repeats", type=int, default=2)
    args = p.parse_args()
    from sessions import Session

    with Session.open(args.session) as s:
        hours = sum(x.n_samples / x.rate_hz for x in s.logs()) / 3600
        n_logs = len(s.logs())
    ours, one = [], []
    for _ in range(args.repeats):
        t, probs, processes = rescore(args.session, None)
        ours.append(t)
        t, ref, _ = rescore(args.session, 1)
        one.append(t)
        print(f"{processes} processes: {ours[-1]:.1f} s; one process: {one[-1]:.1f} s", flush=True)
    diff = max(float(np.abs(probs[i] - ref[i]).max()) for i in ref)
    same = sum(int((probs[i].argmax(1) == ref[i].argmax(1)).sum()) for i in ref) / sum(len(v) for v in ref.values())
    best, best_ref = min(ours), min(one)
    scale = f"{hours:.1f} h"
    row = Row(
        f"a Retrain's rescoring of every log ({scale}, {n_logs} logs), {processes} processes of one torch thread",
        f"{best:.1f} s (runs: {', '.join(f'{x:.1f}' for x in ours)})",
        f"one process, torch on every core: {best_ref:.1f} s (runs: {', '.join(f'{x:.1f}' for x in one)})",
        f"{best_ref / best:.2f}× faster",
        f"≤ {TARGET_S:.0f} s at 10 h",
        max(ours) <= TARGET_S if 9.5 <= hours <= 10.5 else None,  # met when every run is
        f"probabilities within {diff:.1e} of one process's; argmax equal on {same:.2%} of steps",
    )
    record("time_rescoring", [row], device="cpu")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
