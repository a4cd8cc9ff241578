"""Where a rescoring of every log spends its time, per part, beside what the arithmetic needs.

A Retrain's rescoring and the UI's first start are the same work: every log scored by the active models, written to
the kept scores, the tracks ranked over the session (``cycle.score_and_store``). This profiles it (cProfile, one
process, nothing else running) on a session that ``bench_fleet.py`` built and trained:

    python benchmarks/speed/bench_fleet.py --hours 10 --keep /tmp/f10 --until train
    python benchmarks/speed/profile_rescoring.py /tmp/f10/session [--top 25]

Each part is the cumulative time of the functions that do it (a part's time includes what it calls, so parts that
nest are said so). The arithmetic's limit of the members' part is the ensemble's multiply-adds over the distinct
frames, at the rate this machine multiplies matrices (measured in the same run, a float32 matrix product of the
network's shape).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

# part -> (module path fragment, function name) pairs whose cumulative time is the part's
PARTS: dict[str, tuple[tuple[str, str], ...]] = {
    "stage-1 outputs (read from the cache)": (("frame_outputs.py", "__init__"), ("scores.py", "stage1_embedding")),
    "frames for the classifier (SpectralSteps.at)": (("spectra.py", "at"),),
    "the ensemble pass (members, softmax, reduce)": (("passes.py", "ensemble_pass"),),
    "  of it: the members' forward": (("window_classifier.py", "forward"), ("passes.py", "per_distinct_row")),
    "  of it: mean, BALD, agreement": (("scores.py", "reduce"),),
    "drift": (("window_drift.py", "drift_of_log"),),
    "writing the kept scores": (("score_store.py", "_write_array"),),
    "tracks ranked over the session": (("tracks.py", "normalised_tracks"),),
}


def matmul_rate(n: int = 4096, k: int = 256, m: int = 64, repeats: int = 50) -> float:
    """Multiply-adds per second of a float32 ``(n, k) @ (k, m)`` product on this machine (the network's shape)."""
    import torch

    a, b = torch.randn(n, k), torch.randn(k, m)
    a @ b
    t = time.perf_counter()
    for _ in range(repeats):
        a @ b
    return n * k * m * repeats / (time.perf_counter() - t)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("session", type=Path)
    p.add_argument("--top", type=int, default=25, help="functions listed by their own time")
    args = p.parse_args()
    from sessions import Session
    from training import load_bundle
    from workbench import cycle

    with Session.open(args.session) as s:
        logs = s.logs()
        steps = sum(x.n_samples for x in logs)
        version = s.active_model("classifier")
        bundle = load_bundle(s.path / version.path)
        weights = sum(int(w.numel()) for m in bundle.classifiers for w in m.parameters())
        frames = steps // bundle.spectral.hop if bundle.spectral is not None else steps
        for folder in s.path.glob("cache/scores-*"):  # the rescoring a Retrain starts: nothing kept for it yet
            (folder / "meta.json").unlink(missing_ok=True)
        profile = cProfile.Profile()
        t = time.perf_counter()
        profile.enable()
        cycle.score_and_store(s, score=cycle.compute_scores)
        profile.disable()
        total = time.perf_counter() - t
    stats = pstats.Stats(profile)
    rate = matmul_rate()
    print(f"{len(logs)} logs, {steps / 100 / 3600:.1f} h at 100 Hz, {frames:,} frames; rescoring {total:.1f} s")
    members = len(bundle.classifiers)
    print(f"ensemble: {members} members, {weights:,} weights; this machine: {rate / 1e9:.1f} G mult-adds/s")
    limit = weights * frames / rate
    print("\n| part | seconds | share of the rescoring | the arithmetic's limit |\n| --- | --- | --- | --- |")
    for part, keys in PARTS.items():
        cum = sum(
            v[3] for (file, _, name), v in stats.stats.items() if any(file.endswith(f) and name == n for f, n in keys)
        )
        said = f"{limit:.1f} s (every weight once per frame)" if "forward" in part else "–"
        print(f"| {part} | {cum:.1f} | {cum / total:.0%} | {said} |")
    print(f"\nthe {args.top} functions with the most time of their own:\n")
    stats.sort_stats("tottime").print_stats(args.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
