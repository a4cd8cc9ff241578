"""What issue 65's loop benchmarks share: labelling runs as a person did before the loop, and the loop's options."""

from __future__ import annotations

import argparse

import numpy as np

PIECE_S, FRACTION = 5.0, 0.10


def label_runs(session, logs, *, seed: int) -> None:
    """10 % of each run's time in 5 s pieces inside its reference, drawn with ``seed``."""
    rng = np.random.default_rng(seed)
    for x in logs:
        n = round(PIECE_S * x.rate_hz)
        ref = session.reference(x.id)
        starts = [a for a0, b, _ in ref for a in range(a0, b - n + 1, n)]
        want = max(1, round(FRACTION * x.n_samples / n))
        for a in rng.permutation(starts)[:want]:
            terrain = next(t for r0, r1, t in ref if r0 <= a < r1)
            session.add_segment(x.id, int(a), int(a) + n, terrain, author="benchmark", source="seed")


def loop_arguments(description: str) -> argparse.ArgumentParser:
    """The options every loop benchmark takes: ``--seed``, ``--rounds``, ``--per-round``, ``--person``,
    ``--strategies``."""
    args = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("--seed", type=int, default=0)
    args.add_argument("--rounds", type=int, default=4)
    args.add_argument("--per-round", type=int, default=12)
    args.add_argument("--person", default="piece", choices=["piece", "stretch"])
    args.add_argument("--strategies", nargs="+", default=["combined", "random"])
    return args


def loop_settings(opts: argparse.Namespace):
    """The ``workbench.evaluation.LoopSettings`` of the parsed options."""
    from workbench.evaluation import LoopSettings

    return LoopSettings(
        rounds=opts.rounds,
        per_round=opts.per_round,
        person=opts.person,
        strategies=tuple(opts.strategies),
        seed=opts.seed,
    )
