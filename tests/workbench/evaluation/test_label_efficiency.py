"""``evaluate --simulate`` end to end at tiny sizes: stage 1, retrains per round, report and plot."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from labeling import CurvePoint
from workbench.evaluation.label_efficiency import SimSettings, report, simulate_logs, simulate_partitions

TINY = SimSettings(
    strategies=("random", "combined"),
    model="paper",
    seeds=1,
    rounds=2,
    batch=2,
    hidden=8,
    stage1_epochs=1,
    stage1_steps=100,  # the default family's next-frame predictor: the report, not its fit, is under test
    stage2_epochs=2,
    folds=2,
)


@pytest.mark.parametrize(("model", "stage1"), [("default", "own"), ("default", "lstm"), ("paper", "own")])
def test_simulate_logs_reports_both_strategies(tmp_path: Path, model: str, stage1: str) -> None:
    rng = np.random.default_rng(0)
    logs, truth = [], []
    for _ in range(3):
        y = np.repeat(rng.permutation(3), 100)
        logs.append((rng.normal(size=(300, 2)) * (1 + y[:, None])).astype(np.float32))
        truth.append(y)
    lines: list[str] = []
    settings = replace(TINY, model=model, stage1=stage1)
    text = simulate_logs(logs, truth, ["a", "b", "c"], rate_hz=20.0, settings=settings, out=tmp_path, log=lines.append)
    assert ("stage 2 on the default family" in lines[0]) == (model == "default")
    # the default family's own stage 1 unless the LSTM is asked for; the paper family's is always the LSTM
    assert ("the next-frame predictor" in lines[0]) == (model == "default" and stage1 == "own"), lines[0]
    assert ("of the LSTM" in lines[0]) == (model == "paper" or stage1 == "lstm"), lines[0]
    assert "| round | random: labelled s (%)" in text
    assert re.search(r"`combined` (reaches|does not reach) random's final accuracy", text)
    assert sum("round 2" in s for s in lines) == 2  # both strategies ran both rounds
    assert any("held out: 1 logs, 0.2 min, 3 terrain patches" in s for s in lines), lines[:2]
    assert TINY.consistency == 0 and not any("pairs of unlabelled" in s for s in lines)  # labels only by default
    # suggestions as long as the UI's (1 s = 20 samples here, pieces of half to all of it): 2 per round
    done = [int(m.group(1)) for s in lines if (m := re.search(r"round 2: (\d+) samples", s))]
    assert done and all(4 * 10 <= n <= 4 * 20 for n in done), done
    assert (tmp_path / "simulate-demo.png").read_bytes()[:4] == b"\x89PNG"


def _runs() -> list[np.ndarray]:
    rng = np.random.default_rng(1)
    return [(rng.normal(size=(400, 2)) * (0.5 + r % 2)).astype(np.float32) for r in range(6)]


@pytest.mark.parametrize("model", ["default", "paper"])
def test_simulate_partitions_labels_whole_partitions(tmp_path: Path, model: str) -> None:
    lines: list[str] = []
    settings = replace(TINY, model=model)
    text = simulate_partitions(
        _runs(), [r % 2 for r in range(6)], ["a", "b"], rate_hz=20.0, settings=settings, out=tmp_path, log=lines.append
    )
    assert "BorealTC" in text
    assert ("the next-frame predictor" in lines[0]) == (model == "default"), lines[0]
    # two partitions of 5 s (100 samples at 20 Hz) per round
    assert any("random seed 0 round 2: 400 samples labelled" in s for s in lines)
    assert (tmp_path / "simulate-borealtc.png").exists()


def test_simulate_partitions_pairs_windows_of_neighbouring_partitions_of_one_run(monkeypatch) -> None:
    from sklearn.model_selection import StratifiedKFold

    import workbench.evaluation.label_efficiency as ws

    seen = []
    real = ws.fit_classifier

    def spy(features, segments, *args, **kwargs):
        seen.append((len(features), segments, kwargs["pairs"]))
        return real(features, segments, *args, **kwargs)

    monkeypatch.setattr(ws, "fit_classifier", spy)
    labels = [r % 2 for r in range(6)]
    simulate_partitions(
        _runs(),
        labels,
        ["a", "b"],
        rate_hz=20.0,
        settings=replace(TINY, strategies=("random",), consistency=3.0),
        out=None,
        log=lambda s: None,
    )
    # 6 runs of 4 partitions (100 samples); seed 0 uses fold 0's training partitions as the pool
    y = np.repeat(labels, 4)
    pool = set(next(StratifiedKFold(5, shuffle=True, random_state=0).split(np.zeros(len(y)), y))[0].tolist())
    neighbours = sum(p + 1 in pool and p // 4 == (p + 1) // 4 for p in pool)  # the next partition, same run
    per_partition = (100 - 34) // 10 + 1  # 1.7 s windows every 0.5 s
    for n_features, segments, pairs in seen:
        assert len(pairs) == neighbours * per_partition**2
        labelled = len(segments)  # one window per segment, first in the features
        assert n_features == labelled + len(pool) * per_partition
        assert all(a.seq >= labelled and b.seq >= labelled and a.length == b.length == 34 for a, b in pairs)


def test_simulate_partitions_can_label_thirds_of_partitions(tmp_path: Path) -> None:
    lines: list[str] = []
    simulate_partitions(
        _runs(),
        [r % 2 for r in range(6)],
        ["a", "b"],
        rate_hz=20.0,
        settings=replace(TINY, segment_s=5 / 3),
        out=tmp_path,
        log=lines.append,
    )
    assert any("3 suggestion(s) of 1.70 s in each" in s for s in lines), lines
    # two thirds of a partition (pieces of 33 or 34 samples) per round
    done = [int(m.group(1)) for s in lines if (m := re.search(r"seed 0 round 2: (\d+) samples", s))]
    assert len(done) == 2 and all(4 * 33 <= n <= 4 * 34 for n in done), done


def test_report_gives_the_ratio_per_round_and_its_spread_over_seeds() -> None:
    random = [[CurvePoint(200, 0.5, 0.0), CurvePoint(400, 0.7, 0.0)]] * 3
    fast = [[CurvePoint(100, 0.5, 0.0), CurvePoint(200, 0.7, 0.0)]] * 3
    text = report({"random": random, "combined": fast}, total=1000, rate_hz=100.0, title="Demo", out=None)
    assert "`combined` reaches random's final accuracy (70.00 % at 4 s labelled) with 2 s: 0.50×" in text
    assert "against each of random's rounds: 0.50×, 0.50×" in text
    assert "median 0.50×, 5–95 % 0.50× to 0.50×; at most 0.5× in 100% of draws" in text


def test_device_reaches_every_fit_and_pass(monkeypatch, tmp_path: Path) -> None:
    """``--device cuda`` must move all of the simulation: a pass left on the CPU would be silently slow."""
    import workbench.evaluation.label_efficiency as ws

    seen: list[tuple[str, str]] = []

    def spy(name, fn, *, config: bool):
        def wrapped(*args, **kwargs):
            if config:
                seen.append((name, kwargs["config"].device))
                kwargs["config"] = replace(kwargs["config"], device="cpu")
            else:
                seen.append((name, kwargs.get("device", "cpu")))
                kwargs["device"] = "cpu"
            return fn(*args, **kwargs)

        monkeypatch.setattr(ws, name, wrapped)

    for name, config in [
        ("fit_predictor", True),
        ("fit_classifier", True),
        ("run_predictor", False),
        ("run_classifiers", False),
        ("score_logs", False),
    ]:
        spy(name, getattr(ws, name), config=config)
    gpu = replace(TINY, device="cuda")
    simulate_partitions(
        _runs(), [r % 2 for r in range(6)], ["a", "b"], rate_hz=20.0, settings=gpu, out=None, log=lambda s: None
    )
    rng = np.random.default_rng(0)
    logs = [rng.normal(size=(300, 2)).astype(np.float32) for _ in range(3)]
    truth = [np.repeat(rng.permutation(3), 100) for _ in range(3)]
    simulate_logs(logs, truth, ["a", "b", "c"], rate_hz=20.0, settings=gpu, out=None, log=lambda s: None)
    passes = {"fit_predictor", "fit_classifier", "run_predictor", "run_classifiers", "score_logs"}
    assert {name for name, _ in seen} == passes
    assert [s for s in seen if s[1] != "cuda"] == []


def test_simulate_partitions_by_runs_takes_the_protocols_folds_over_runs(monkeypatch) -> None:
    """The folds are the protocol's (``outer_folds``, whose runs split holds whole runs out: test_evaluate_windows)."""
    import workbench.evaluation.label_efficiency as ws

    asked = []

    class Stop(Exception):
        pass

    def spy(y, run_of, *, split, folds, seed):
        asked.append((split, len(set(run_of.tolist()))))
        raise Stop

    monkeypatch.setattr(ws, "outer_folds", spy)
    for split in ("runs", "partitions"):
        with pytest.raises(Stop):
            settings = replace(TINY, strategies=("random",), split=split)
            simulate_partitions(
                _runs(), [r % 2 for r in range(6)], ["a", "b"], rate_hz=20.0, settings=settings, out=None, log=print
            )
    assert asked == [("runs", 6), ("partitions", 6)]
