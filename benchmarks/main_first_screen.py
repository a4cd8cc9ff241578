"""Screen of issue 65 (not kept): the first pick in each log nobody labelled checks the model's main answer there (the
centre of its longest predicted run, smoothed over a suggestion's length) instead of its most unsure piece, only
where that run holds at least SHARE (0.5, fixed before measuring) of the log; every other pick as ``combined`` makes
it. It wraps ``labeling.suggest`` and runs a loop benchmark unchanged.

Run from the repository root:
    python benchmarks/main_first_screen.py benchmarks/loop_borealtc.py new-runs --seed 1 --strategies combined
    python benchmarks/main_first_screen.py benchmarks/loop_walks.py --seed 1 --strategies combined
"""

import runpy
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))
import labeling  # noqa: E402

orig = labeling.suggest
SHARE = 0.5  # fixed before measuring: "most of the run"


def longest_run_centre(probs: np.ndarray, smooth: int) -> tuple[int, int]:
    k = np.ones(max(1, smooth)) / max(1, smooth)
    sm = np.stack([np.convolve(probs[:, j], k, mode="same") for j in range(probs.shape[1])], 1)
    lab = sm.argmax(1)
    edges = np.flatnonzero(np.diff(lab)) + 1
    starts = np.r_[0, edges]
    stops = np.r_[edges, len(lab)]
    i = int(np.argmax(stops - starts))
    return int(starts[i]), int(stops[i])


def patched(scores, *, labelled=(), n=12, max_len=100, strategy="combined", **kw):
    out = orig(scores, labelled=labelled, n=n, max_len=max_len, strategy=strategy, **kw)
    if strategy != "combined" or not kw.get("unchecked_first", True):
        return out
    checked = {g for g, a, b in labelled if b > a}
    for g, s in enumerate(scores):
        if g in checked or s.probs is None or len(s.probs) < max_len:
            continue
        a, b = longest_run_centre(np.asarray(s.probs), max_len)
        share = (b - a) / len(s.probs)
        print(
            f"  [screen] log {g}: longest stretch {share:.2f} of the run",
            "(main answer)" if share >= SHARE else "(as combined)",
            flush=True,
        )
        if share < SHARE:
            continue
        c = (a + b) // 2
        start = max(0, min(c - max_len // 2, len(s.probs) - max_len))
        piece = (start, start + max_len)
        guess = int(np.asarray(s.probs[piece[0] : piece[1]]).mean(0).argmax())
        for i, x in enumerate(out):
            if x.log == g and x.kind == "suggestion":
                out[i] = replace(
                    x, start=piece[0], stop=piece[1], reason="the model's main answer in this run", guess=guess
                )
                break
    return out


labeling.suggest = patched
script, *args = sys.argv[1:]
sys.argv = [script, *args]
runpy.run_path(script, run_name="__main__")
