"""Where a rescoring of every log spends its time, per part, beside what the arithmetic needs.

A Retrain's rescoring and the UI's first start are the same work: every log scored by the active models, written to
the kept scores, the tracks ranked over the session (``cycle.score_and_store``). This profiles it (cProfile, one
process: ``jobs=1``, where a rescoring of hours forks a process per core; nothing else running) on a session
that ``bench_fleet.py`` built and trained:

    python benchmarks/speed/bench_fleet.py --hours 10 --keep /tmp/f10 --until train
    python benchmarks/speed/profile_rescoring.py /tmp/f10/session [--top 25]

Each part is the cumulative time of the functions that do it (a part's time includes what it calls, so parts that
nest are said so). The arithmetic's limit of the networks is the ensemble's multiply-adds over the frames (each
frame through the 1x1 mixing once, its 7-frame window through the 3-frame convolution, the head), of the drift's
search each frame's distances to every member's reference rows in both views, both at the rate this machine
multiplies matrices (measured in the same run, a float32 matrix product of the network's shape).
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
    "the default family's scores (the parts below, and each frame's answer repeated over its steps)": (
        ("scores.py", "_frame_scores"),
    ),
    "  the members over the frames (frame_chunks: networks, softmax, drift)": (("frame_scores.py", "frame_chunks"),),
    "    of it: the members' networks": (
        ("window_classifier.py", "mixed"),
        ("window_classifier.py", "windowed"),
        ("window_classifier.py", "pool"),
        ("window_classifier.py", "standardise"),
    ),
    "    of it: the drift's nearest labelled frames": (("drift_reference.py", "scaled_drift"),),
    "  mean, BALD, agreement (per frame)": (("frame_reduce.py", "reduce"),),
    "the step pass (another family's members)": (("passes.py", "ensemble_pass"),),
    "writing the kept scores": (("score_files.py", "write_array"),),
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
        frames = steps // bundle.spectral.hop if bundle.spectral is not None else steps
        cfg = bundle.classifiers[0].config
        w, f, h, k = cfg.window, cfg.frame_width, cfg.hidden, cfg.n_classes
        per_frame = len(bundle.classifiers) * (f * h + w * 3 * h * h + 2 * h * k)  # multiply-adds, mixing once a frame
        refs = () if bundle.drift is None else (*bundle.drift.references, *bundle.drift.inputs)
        searched = sum(r.size for r in refs)  # each frame's multiply-adds against every reference row, both views
        for folder in s.path.glob("cache/scores-*"):  # the rescoring a Retrain starts: nothing kept for it yet
            (folder / "meta.json").unlink(missing_ok=True)
        profile = cProfile.Profile()
        t = time.perf_counter()
        profile.enable()
        cycle.score_and_store(s, score=cycle.compute_scores, jobs=1)  # in this process: where cProfile sees it
        profile.disable()
        total = time.perf_counter() - t
    stats = pstats.Stats(profile)
    rate = matmul_rate()
    print(f"{len(logs)} logs, {steps / 100 / 3600:.1f} h at 100 Hz, {frames:,} frames; rescoring {total:.1f} s")
    members = len(bundle.classifiers)
    print(f"ensemble: {members} members, {per_frame:,} multiply-adds a frame; drift: {searched:,} a frame")
    print(f"this machine: {rate / 1e9:.1f} G mult-adds/s")
    limits = {"networks": per_frame * frames / rate, "nearest": searched * frames / rate}
    print("\n| part | seconds | share of the rescoring | the arithmetic's limit |\n| --- | --- | --- | --- |")
    for part, keys in PARTS.items():
        cum = sum(
            v[3] for (file, _, name), v in stats.stats.items() if any(file.endswith(f) and name == n for f, n in keys)
        )
        said = next((f"{v:.1f} s" for key, v in limits.items() if key in part), "–")
        print(f"| {part} | {cum:.1f} | {cum / total:.0%} | {said} |")
    print(f"\nthe {args.top} functions with the most time of their own:\n")
    stats.sort_stats("tottime").print_stats(args.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
