"""Coverage and width of `labeling.powered_accuracy` on simulated sessions: how often its 90 % interval holds the
accuracy of the time nobody labelled, and how wide it is beside the checks' own Wilson interval.

    python benchmarks/studies/powered_accuracy_sim.py [--draws 400] [--max-gain 4]

Each draw makes a session of 4,000 steps (whether the model is right at each, its confidence there), places 8, 24
or 48 uniform checks and asks for the interval. The cases: calibrated, over- and underconfident, a blind
confidence, a sharp one (it tells right from wrong), whole stretches wrong with the confidence hardly lower.
"""

from __future__ import annotations

import argparse

import numpy as np

from labeling import MAX_GAIN, Z90, powered_accuracy, wilson

CASES = (
    "calibrated-90",
    "overconfident-80",
    "underconfident-95",
    "blind-85",
    "sharp-99",
    "sharp-85",
    "low-60",
    "stretches-70",
)


def session(case: str, rng: np.random.Generator, n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """Whether the model is right at each step (drawn from its chance of being right) and its confidence."""
    if case == "calibrated-90":
        c = rng.beta(9, 1, n)
        f = c
    elif case == "overconfident-80":
        c = rng.beta(4, 1, n)
        f = np.clip(c + 0.15, 0, 1)
    elif case == "underconfident-95":
        c = rng.beta(19, 1, n)
        f = np.clip(c - 0.3, 0, 1)
    elif case == "blind-85":
        c = np.full(n, 0.85)
        f = rng.uniform(0.3, 1, n)
    elif case in ("sharp-99", "sharp-85"):
        c = np.where(rng.random(n) < (0.01 if case == "sharp-99" else 0.15), 0.03, 0.99)
        f = np.where(c > 0.5, rng.uniform(0.85, 1, n), rng.uniform(0.2, 0.5, n))
    elif case == "low-60":
        c = rng.beta(3, 2, n)
        f = c
    else:
        wrong = np.repeat(rng.random(n // 200) < 0.3, 200)
        c = np.where(wrong, 0.05, 0.98)
        f = np.clip(np.where(wrong, 0.7, 0.9) + rng.normal(0, 0.05, n), 0, 1)
    return (rng.random(n) < c).astype(float), f


def main() -> None:
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--draws", type=int, default=400)
    args.add_argument("--max-gain", type=float, default=MAX_GAIN)
    opts = args.parse_args()
    print(f"max gain {opts.max_gain:g}, {opts.draws} draws per cell; cover / width (the checks alone), points")
    for case in CASES:
        cells = []
        for n in (8, 24, 48):
            rng = np.random.default_rng(0)
            cover = width = alone = 0.0
            for _ in range(opts.draws):
                right, sure = session(case, rng)
                at = rng.choice(len(right), n, replace=False)
                got = powered_accuracy(right[at], sure[at], sure, max_gain=opts.max_gain)
                cover += got.low <= right.mean() <= got.high
                width += got.high - got.low
                low, high = wilson(int(right[at].sum()), n, z=Z90)
                alone += high - low
            d = opts.draws
            cells.append(f"{n} checks: {cover / d:.2f} / {100 * width / d:.1f} ({100 * alone / d:.1f})")
        print(f"{case:18s} " + " | ".join(cells))


if __name__ == "__main__":
    main()
