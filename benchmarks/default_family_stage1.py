"""Does the default family's classifier gain from reading stage 1? On demo logs: a logistic regression on the spectral
summaries, on stage 1's features (``hidden+surprise``, their mean over the same 1.6 s window), and on both; random
1 s labels in 8 pool logs, accuracy on 4 held-out logs, 3 draws per budget.

    python benchmarks/default_family_stage1.py demo-logs-12

where ``demo-logs-12`` holds ``workbench.demo.generate_demo_logs(FOLDER, n_logs=12, minutes=5.0, seed=0)``.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import LogisticRegression

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from training import SpectralConfig, TrainConfig, fit_predictor, log_summaries, run_predictor
from workbench.evaluation import load_recordings, truth_arrays

INPUTS = ("spectra", "stage1", "both")


def main(folder: str) -> None:
    warnings.simplefilter("ignore", ConvergenceWarning)
    recs, _ = load_recordings(Path(folder))
    classes = sorted({t for r in recs for _, _, t in r.truth})
    truth, logs = truth_arrays(recs, classes), [r.data for r in recs]
    fit = fit_predictor(logs, config=TrainConfig(max_epochs=20, patience=5, seed=0), hidden=64)
    outs = run_predictor(fit.model, fit.normalizer, logs)
    config = SpectralConfig.for_log(np.concatenate(logs[:5]), 100.0)
    order = np.random.default_rng(0).permutation(len(logs))
    test, pool = np.sort(order[:4]), np.sort(order[4:])
    per_log = []
    for i, log in enumerate(logs):
        spectra = log_summaries(log, config, transform=fit.normalizer)  # (N, 2F), one row per frame
        ends = np.arange(config.frame - 1, len(log), config.hop)[: len(spectra)]
        stage1 = outs[i].features("hidden+surprise")  # (T, H + C)
        sums = np.concatenate([np.zeros((1, stage1.shape[1])), np.cumsum(stage1, axis=0)])
        lo = np.maximum(ends + 1 - config.span, 0)
        means = ((sums[ends + 1] - sums[lo]) / (ends + 1 - lo)[:, None]).astype(np.float32)  # window means
        inputs = {"spectra": spectra, "stage1": means, "both": np.hstack([spectra, means])}
        per_log.append((inputs, truth[i][ends], ends))
    for budget_s in (100, 250):
        for name in INPUTS:
            accs = []
            for draw in range(3):
                rng = np.random.default_rng(draw)
                xs, ys = [], []
                for _ in range(budget_s):  # one random 1 s piece of a pool log per labelled second
                    i = int(rng.choice(pool))
                    a = int(rng.integers(0, len(logs[i]) - 100))
                    inputs, y, ends = per_log[i]
                    pick = (ends >= a) & (ends < a + 100) & (y >= 0)
                    xs.append(inputs[name][pick])
                    ys.append(y[pick])
                x, y = np.concatenate(xs), np.concatenate(ys)
                mean, std = x.mean(0), x.std(0) + 1e-6
                model = LogisticRegression(C=0.1, max_iter=1000).fit((x - mean) / std, y)
                x_test = np.concatenate([per_log[i][0][name] for i in test])
                y_test = np.concatenate([per_log[i][1] for i in test])
                known = y_test >= 0
                accs.append(float((model.predict((x_test[known] - mean) / std) == y_test[known]).mean()))
            cells = ", ".join(f"{100 * a:.1f}" for a in accs)
            print(f"{budget_s} s labelled, {name}: {100 * np.mean(accs):.1f} % ({cells})", flush=True)


if __name__ == "__main__":
    main(sys.argv[1])
