"""Peak memory of ingesting and scoring one long log, at two lengths, to see whether it grows with the log.

Each step runs in a fresh process and reports its peak resident set (``ru_maxrss``): writing the log (a demo walk as
ROS 2 MCAP, 22 channels at 100 Hz; not counted), ingesting it into a session, and scoring it as the UI does
(``compute_scores``: stage 1 into the feature cache, the 5-member ensemble, tracks and suggestion embeddings) with
the paper's sizes (hidden 200; weights untrained, which does not change memory), then again with the default
family (its next-frame stage 1 and stage 2's networks fitted on eight 30 s labels, not counted; scoring reads the
spectral frames' cache, the predictor and the networks over them). The reference beside each figure is
the size of the log's own float32 array. The target is for a 10-hour log; ingest and scoring take about a minute
per hour of log here, so the benchmark measures 1 and 2 hours and reports how the peak grows per hour (a bounded
pass grows by what it must keep per sample: the stamps while aligning, the per-step scores and tracks).

Peak RSS counts the pages of memory-mapped files a process has touched, so the passes measured here read and write
the arrays by blocks (``sessions.FileRows``, ``sessions.NpyWriter``), not through maps.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from speed_common import Row, parse_args, record

HIDDEN, MEMBERS = 200, 5


def child(step: str, folder: Path, hours: float) -> dict:
    """Run one step in a fresh interpreter; its peak RSS and seconds."""
    out = subprocess.run(
        [sys.executable, __file__, "--child", step, str(folder), str(hours)], capture_output=True, text=True
    )
    if out.returncode != 0:
        raise RuntimeError(f"{step} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_child(step: str, folder: Path, hours: float) -> None:
    t = time.perf_counter()
    from sessions import Session

    session_dir = folder / "session"
    if step == "write":
        from workbench.demo import generate_walk, write_walk

        write_walk(generate_walk(0, hours * 3600.0), folder / "long.mcap")
        extra = {}
    elif step == "ingest":
        from workbench.demo import TERRAINS

        with Session.create(session_dir) as s:
            for name in TERRAINS:  # a new session has none
                s.add_terrain(name)
            (log,) = s.ingest([folder / "long.mcap"])
            extra = {"samples": log.n_samples, "channels": len(log.channel_names)}
    elif step == "train-default":  # not measured: the default family's stage 2 for the next step to score with
        from workbench import cycle

        with Session.open(session_dir) as s:
            (log,) = s.logs()
            n = log.n_samples
            length = min(3000, n // 20)
            for k in range(8):  # eight 30 s labels of four terrains spread over the log
                a = (2 * k + 1) * n // 16
                s.add_segment(log.id, a, a + length, ("grass", "gravel", "sand", "dirt")[k % 4], author="bench")
            cycle.train_frame_predictor(s)
            cycle.train_classifier(s, model="default", hidden=HIDDEN)
            extra = {}
    elif step == "score-default":
        from workbench.cycle import compute_scores

        with Session.open(session_dir) as s:
            (log,) = s.logs()
            scores = compute_scores(s)
            extra = {"scored_steps": len(scores.scores[log.id].surprise)}
    else:
        import torch

        from training import (
            Classifier,
            ClassifierConfig,
            ModelBundle,
            Normalizer,
            Predictor,
            PredictorConfig,
            save_bundle,
        )
        from workbench.cycle import compute_scores

        torch.manual_seed(0)
        with Session.open(session_dir) as s:
            (log,) = s.logs()
            array = s.array(log.id)
            norm = Normalizer.fit([array[:100_000]])
            p = Predictor(PredictorConfig(array.shape[1], HIDDEN)).eval()
            mode = "hidden+surprise"
            cs = [Classifier(ClassifierConfig(HIDDEN + array.shape[1], 4, HIDDEN)).eval() for _ in range(MEMBERS)]
            for stage, members in (("predictor", []), ("classifier", cs)):
                bundle = ModelBundle(p, norm, log.channel_names, log.rate_hz, members, ("a", "b", "c", "d"), mode)
                path = s.next_model_dir()
                save_bundle(bundle, path)
                config = {"predictor": 1} if stage == "classifier" else {}
                s.register_model(stage, path, config=config, metrics={})
            scores = compute_scores(s)
            extra = {"scored_steps": len(scores.scores[log.id].surprise)}
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # kB on Linux
    print(json.dumps({"peak": peak, "seconds": time.perf_counter() - t, **extra}))


def main() -> None:
    if "--child" in sys.argv:
        i = sys.argv.index("--child")
        run_child(sys.argv[i + 1], Path(sys.argv[i + 2]), float(sys.argv[i + 3]))
        return
    args = parse_args(__doc__)
    lengths = (0.1, 0.2) if args.quick else (1.0, 2.0)
    results = {}
    for hours in lengths:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            child("write", folder, hours)
            ingest = child("ingest", folder, hours)
            score = child("score", folder, hours)
            child("train-default", folder, hours)
            default = child("score-default", folder, hours)
            results[hours] = (ingest, score, default)
            print(f"{hours:g} h: ingest {ingest}, score {score}, score with the default family {default}", flush=True)
    rows = []
    (h1, (i1, s1, d1)), (h2, (i2, s2, d2)) = results.items()
    for name, a, b in (
        ("ingest", i1, i2),
        ("score, paper family (stage 1 → cache, 5 members, tracks)", s1, s2),
        ("score, default family (spectral frames → cache, next-frame stage 1 → cache, 5 networks, tracks)", d1, d2),
    ):
        per_hour = (b["peak"] - a["peak"]) / (h2 - h1)
        array1 = i1["samples"] * i1["channels"] * 4
        array2 = i2["samples"] * i2["channels"] * 4
        at10 = a["peak"] + per_hour * (10 - h1)
        rows.append(
            Row(
                f"peak memory: {name} one log of {h1:g} h / {h2:g} h (22 ch, 100 Hz)",
                f"{a['peak'] / 2**30:.2f} GB / {b['peak'] / 2**30:.2f} GB RSS ({a['seconds']:.0f} s / "
                f"{b['seconds']:.0f} s)",
                f"the log's float32 array: {array1 / 2**20:.0f} MB / {array2 / 2**20:.0f} MB",
                f"grows {per_hour / 2**20:.0f} MB per hour of log ({per_hour / (array2 - array1) * (h2 - h1):.1f}× "
                "the array's growth)",
                "≤ 2 GB RSS for 10 h, not growing with length",
                bool(per_hour < 0.05 * 2**30 and at10 <= 2 * 2**30),
                f"10 h at this slope: {at10 / 2**30:.1f} GB (a straight line through the two points, not measured)",
            )
        )
    record("memory", rows, device=args.device)


if __name__ == "__main__":
    main()
