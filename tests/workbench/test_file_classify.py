"""``workbench classify`` with a default-family bundle: scored in NumPy, never loading PyTorch, and writing what the
session's PyTorch path scores for the same file."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from sessions import IngestOptions
from tests.conftest import children_of_a_killed_parent, ended_within
from training import load_bundle, load_scoring_bundle
from workbench.export import read_logs, score_arrays

from ..training.test_scoring_bundle import RATE, _log, bundle_dir  # noqa: F401 (a fixture)


def test_classify_scores_a_file_in_numpy_as_the_pytorch_path_does(bundle_dir: Path, tmp_path: Path) -> None:  # noqa: F811
    x = _log(3000, 5)
    log = tmp_path / "run.csv"
    table = pd.DataFrame(x, columns=["fast", "noise", "held"])
    table.insert(0, "time", np.arange(len(x)) / RATE)
    table.to_csv(log, index=False)
    out = tmp_path / "p.csv"
    code = (
        "import sys\n"
        "from workbench.cli import main\n"
        f"code = main(['classify', {str(bundle_dir)!r}, {str(log)!r}, '--out', {str(out)!r}])\n"
        "print(code, 'torch' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split()[-2:] == ["0", "False"], done.stdout + done.stderr
    written = pd.read_csv(out)
    read = read_logs(load_bundle(bundle_dir), [log], IngestOptions(camera_fps=0))
    (expected,) = score_arrays(load_bundle(bundle_dir), read.arrays)  # the session's scoring path, in PyTorch
    probs = written[[f"p_{c}" for c in ("a", "b", "c", "d")]].to_numpy()
    assert len(written) == len(x) == len(expected.probs)
    np.testing.assert_allclose(probs, expected.probs, atol=1e-5)
    np.testing.assert_array_equal(written["terrain"], np.asarray(["a", "b", "c", "d"])[expected.probs.argmax(1)])
    np.testing.assert_allclose(written["drift"], expected.drift, rtol=1e-5, atol=1e-5)
    (ours,) = score_arrays(load_scoring_bundle(bundle_dir), read.arrays)
    np.testing.assert_allclose(ours.agreement, expected.agreement, atol=1e-5)
    np.testing.assert_allclose(ours.disagreement, expected.disagreement, atol=1e-5)


def test_several_files_are_read_and_scored_in_processes_as_one_process_does(
    bundle_dir: Path,  # noqa: F811
    tmp_path: Path,
) -> None:
    """Each file in a forked process: the same table, the same lines (a refused file named in its place among them)
    as the files one after another; a `--jobs` under 1 is refused in one line."""
    from workbench.cli import main

    files = []
    for i in range(3):
        table = pd.DataFrame(_log(1500 + 500 * i, 10 + i), columns=["fast", "noise", "held"])
        table.insert(0, "time", np.arange(len(table)) / RATE)
        files.append(tmp_path / f"run{i}.csv")
        table.to_csv(files[-1], index=False)
    broken = tmp_path / "broken.csv"
    broken.write_text("time,fast\n0,1\n")
    files.insert(1, broken)
    outs = []
    for jobs in (1, 3):
        out = tmp_path / f"p{jobs}.csv"
        assert main(["classify", str(bundle_dir), *map(str, files), "--out", str(out), "--jobs", str(jobs)]) == 2
        outs.append(pd.read_csv(out))
    pd.testing.assert_frame_equal(outs[0], outs[1])
    assert sorted(set(outs[0]["log"])) == ["run0", "run1", "run2"]
    assert main(["classify", str(bundle_dir), str(files[0]), "--out", str(tmp_path / "x.csv"), "--jobs", "0"]) == 2


def _sleeper(pids: Path, _item: int) -> None:
    with pids.open("a") as f:
        f.write(f"{os.getpid()}\n")
    time.sleep(60)


def test_a_killed_classify_leaves_no_worker_running(tmp_path: Path) -> None:
    """Issue 99, item 4: `classify --jobs 2 | cat` killed with SIGKILL left both pool workers alive for 20-60 s,
    holding the pipe; they now end with the process that forked them."""
    from functools import partial

    from workbench.export.file_classify import in_processes

    pids = tmp_path / "pids"
    # a process standing for `classify`
    workers = children_of_a_killed_parent(lambda: in_processes(partial(_sleeper, pids), [0, 1], jobs=2), pids, 2)
    assert ended_within(workers, 10)


def test_classify_to_mcap_adds_the_files_path_coloured_by_the_models_answers(
    bundle_dir: Path,  # noqa: F811
    tmp_path: Path,
) -> None:
    from tests.sessions.test_path_mcap import _messages
    from workbench.cli import main

    x = _log(3000, 5)
    table = pd.DataFrame(x, columns=["fast", "noise", "held"])
    t = np.arange(len(x)) / RATE
    table.insert(0, "time", t)
    table["lat"], table["lon"] = 45.38 + t * 9e-6, -71.92 + 0 * t  # north at 1 m/s
    table.to_csv(tmp_path / "drive.csv", index=False)
    assert main(["classify", str(bundle_dir), str(tmp_path / "drive.csv"), "--out", str(tmp_path / "d.mcap")]) == 0
    msgs = _messages(tmp_path / "d.mcap")  # every message valid against Foxglove's published schema
    assert {"/terrain", "/terrain/path", "/terrain/geojson", "/terrain/fix"} <= set(msgs)
    (update,) = msgs["/terrain/path"]
    lines = update["entities"][0]["lines"]
    assert sum(len(x["points"]) for x in lines) >= 3000 // 6  # every pose drawn once (stretches share their ends)
    features = json.loads(msgs["/terrain/geojson"][0]["geojson"])["features"]
    assert {f["properties"]["name"] for f in features} <= {"a", "b", "c", "d", "unsure"}
