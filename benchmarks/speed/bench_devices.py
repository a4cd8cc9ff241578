"""A first model on 2 cores, on every core and on the GPU (issue 66): `workbench train SESSION` (both stages, the
default family) on ``--hours`` of 22-channel 100 Hz demo walks with 5 % of the time labelled, three ways in the same
run, each on its own copy of the session (the frames are computed anew by each) and in a fresh interpreter:

- limited to 2 CPUs (the process's affinity and ``OMP_NUM_THREADS=2``, as ``taskset -c 0,1`` gives): the reference;
- on every CPU of the machine;
- on every CPU with stage 2's fits in threads (``WORKBENCH_FIT_PROCESSES=0``), as before they ran in processes: what
  the processes are worth;
- with ``--device cuda`` on every CPU, where a CUDA device is present (else the row says "not run").

On the model the every-CPU arm trained, a Retrain's rescoring of every log (``cycle.score_and_store``, nothing kept
first) in a fresh interpreter three ways: on 2 CPUs (its two processes), on every CPU (a process per core where the
logs have the samples for it), and on every CPU in one process (``jobs=1``): what the processes are worth there.

Then the paper family's stage 1 (``--model paper --stage predictor``, ``--paper-epochs`` epochs, no early stop) on
every CPU and with ``--device cuda``: its throughput in timesteps per second (``--no-paper``: not run).

Usage::

    python benchmarks/speed/bench_devices.py [--hours 4] [--paper-epochs 2] [--no-paper] [--keep DIR] [--quick]
        [--out FILE.json]

Writing, ingesting and labelling the logs are set-up (``bench_first_model.py``'s), timed but not part of a figure.
On a 2-CPU machine the first two rows are the same machine twice: the ratio says so rather than hides it.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from speed_common import ROOT, Row, record

FIRST_MODEL = ROOT / "benchmarks" / "speed" / "bench_first_model.py"
LOG_MINUTES = 30.0


def _cuda() -> bool:
    code = "import torch; print(torch.cuda.is_available())"
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip() == "True"


def _setup(folder: Path, hours: float) -> dict:
    n_logs = max(1, round(hours * 60 / LOG_MINUTES))
    args = [str(folder), str(n_logs), str(hours * 60 / n_logs)]
    out = subprocess.run([sys.executable, str(FIRST_MODEL), "--child", "setup", *args], capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"set-up failed:\n{out.stdout[-2000:]}\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _pinned(cpus: int | None, env_extra: dict[str, str] | None) -> tuple[dict[str, str], Callable[[], None] | None]:
    """A child's environment and what pins it to the first ``cpus`` CPUs (``None``: all, nothing pinned)."""
    env = {**os.environ, **(env_extra or {})}
    if cpus is None:
        return env, None
    chosen = sorted(os.sched_getaffinity(0))[:cpus]
    env["OMP_NUM_THREADS"] = str(cpus)
    return env, lambda: os.sched_setaffinity(0, chosen)


def _train(session: Path, extra: list[str], *, cpus: int | None, env_extra: dict[str, str] | None = None) -> dict:
    """``workbench train SESSION *extra`` in a fresh interpreter on ``cpus`` CPUs (``None``: all); its seconds, the
    new classifier's out-of-fold accuracy and the stages' own "done in" lines."""
    env, pin = _pinned(cpus, env_extra)
    t = time.perf_counter()
    cmd = [sys.executable, "-m", "workbench.cli", "train", str(session), *extra]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, preexec_fn=pin, cwd=ROOT)
    seconds = time.perf_counter() - t
    if out.returncode != 0:
        return {"seconds": seconds, "error": (out.stderr or out.stdout).strip().splitlines()[-1:]}
    code = (
        "import json, sys; from sessions import Session\n"
        "with Session.open(sys.argv[1]) as s:\n"
        "    c, p = s.active_model('classifier'), s.active_model('predictor')\n"
        "    print(json.dumps({'accuracy': c.metrics.get('accuracy') if c else None, 'predictor': p.metrics}))"
    )
    info = subprocess.run([sys.executable, "-c", code, str(session)], capture_output=True, text=True, cwd=ROOT)
    stages = [line.strip() for line in (out.stdout + out.stderr).splitlines() if "done in" in line]
    return {"seconds": seconds, "stages": stages, **json.loads(info.stdout.strip().splitlines()[-1])}


RESCORE = """
import json, sys, time
from sessions import Session
from workbench import cycle
jobs = None if sys.argv[2] == "auto" else int(sys.argv[2])
with Session.open(sys.argv[1]) as s:
    for folder in s.path.glob("cache/scores-*"):
        (folder / "meta.json").unlink(missing_ok=True)
    t = time.perf_counter()
    cycle.score_and_store(s, score=cycle.compute_scores, jobs=jobs)
    print(json.dumps({"seconds": time.perf_counter() - t}))
"""


def _rescore(session: Path, *, cpus: int | None, jobs: str) -> dict:
    """A rescoring of every log of ``session`` in a fresh interpreter on ``cpus`` CPUs (``None``: all), ``jobs``
    processes (``auto``: the session's choice)."""
    env, pin = _pinned(cpus, None)
    cmd = [sys.executable, "-c", RESCORE, str(session), jobs]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, preexec_fn=pin, cwd=ROOT)
    if out.returncode != 0:
        return {"error": (out.stderr or out.stdout).strip().splitlines()[-1:]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--hours", type=float, default=4.0)
    p.add_argument("--paper-epochs", type=int, default=2)
    p.add_argument("--no-paper", action="store_true", help="leave out the paper family's stage-1 arms")
    p.add_argument("--no-cuda-arm", action="store_true", help="leave out the default family's `--device cuda` arm")
    p.add_argument("--keep", type=Path, default=None, help="copy the set-up session here (no model yet) for more runs")
    p.add_argument("--quick", action="store_true", help="half an hour, one paper epoch: checks the script runs")
    p.add_argument("--out", type=Path, default=None, help="also write every measurement here (JSON)")
    p.add_argument("--device", default=None, help="make bench's device: on cpu with 2 CPUs or fewer, not run")
    args = p.parse_args()
    if args.device == "cpu" and len(os.sched_getaffinity(0)) <= 2:
        # its rows compare this machine's 2 CPUs with all of them and a GPU: on 2 CPUs and no GPU every arm is the
        # same machine, hours of it (run it by hand, or `make bench DEVICE=cuda` where there is a GPU)
        print("bench_devices.py: not run on cpu with 2 CPUs (it compares 2 CPUs, every CPU and the GPU)")
        return
    hours, epochs = (0.5, 1) if args.quick else (args.hours, args.paper_epochs)
    cpus = len(os.sched_getaffinity(0))
    cuda = _cuda()
    runs: dict = {"cpus": cpus, "cuda": cuda, "no_paper": args.no_paper}
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        runs["setup"] = _setup(base, hours)
        session = base / "session"
        print(f"set-up: {runs['setup']}", flush=True)
        if args.keep:
            _copy(session, args.keep)
        threads = {"WORKBENCH_FIT_PROCESSES": "0"}
        # the default family named, as each arm's line says: every arm fits the same family, whatever a session's
        # first classifier defaults to
        default = ["--model", "default"]
        arms = {
            "2 cpus": (default, 2, None),
            f"{cpus} cpus": (default, None, None),
            f"{cpus} cpus, threads": (default, None, threads),
        }
        if cuda and not args.no_cuda_arm:
            arms[f"{cpus} cpus + cuda"] = ([*default, "--device", "cuda"], None, None)
        for name, (extra, n, env) in arms.items():
            folder = base / name.replace(" ", "-").replace(",", "")
            runs[name] = _train(_copy(session, folder), extra, cpus=n, env_extra=env)
            print(f"default family, {name}: {runs[name]}", flush=True)
            if name == f"{cpus} cpus" and "error" not in runs[name]:
                for arm, (n_cpus, jobs) in {"2 cpus": (2, "auto"), f"{cpus} cpus": (None, "auto")}.items():
                    runs[f"rescore {arm}"] = _rescore(folder, cpus=n_cpus, jobs=jobs)
                runs[f"rescore {cpus} cpus, one process"] = _rescore(folder, cpus=None, jobs="1")
                print({k: v for k, v in runs.items() if k.startswith("rescore")}, flush=True)
            shutil.rmtree(folder)
        paper = ["--model", "paper", "--stage", "predictor", "--max-epochs", str(epochs), "--patience", str(epochs + 1)]
        paper_arms = {} if args.no_paper else {f"paper {cpus} cpus": (paper, None)}
        if cuda and not args.no_paper:
            paper_arms[f"paper {cpus} cpus + cuda"] = ([*paper, "--device", "cuda"], None)
        for name, (extra, n) in paper_arms.items():
            runs[name] = _train(_copy(session, base / name.replace(" ", "-")), extra, cpus=n)
            print(f"{name}: {runs[name]}", flush=True)
    if args.out:
        args.out.write_text(json.dumps(runs, indent=1, default=str))
    record("devices", _rows(runs, epochs), device="cuda" if cuda else "cpu")


def _rows(runs: dict, epochs: int) -> list[Row]:
    cpus, setup = runs["cpus"], runs["setup"]
    shape = f"{setup['hours']:.1f} h of {setup['channels']}-channel 100 Hz logs, {setup['labelled']:.1%} labelled"

    def fig(name: str) -> str:
        r = runs.get(name)
        if r is None:
            return "not run (no CUDA device)"
        if "error" in r:
            return f"failed: {r['error']}"
        acc = f", out-of-fold accuracy {r['accuracy']:.1%}" if r.get("accuracy") is not None else ""
        return f"{r['seconds']:.0f} s{acc}"

    def secs(name: str) -> str:
        r = runs.get(name)
        return "not run" if r is None else f"failed: {r['error']}" if "error" in r else f"{r['seconds']:.1f} s"

    def ratio(a: str, b: str) -> tuple[str, float | None]:
        ra, rb = runs.get(a), runs.get(b)
        if not ra or not rb or "error" in ra or "error" in rb:
            return "–", None
        x = rb["seconds"] / ra["seconds"]
        return f"{x:.2f}× faster", x

    many, gpu = f"{cpus} cpus", f"{cpus} cpus + cuda"
    r_cores, x_cores = ratio(many, "2 cpus") if cpus > 2 else ("– (this machine has 2 CPUs: one arm)", None)
    r_gpu, x_gpu = ratio(gpu, many)
    r_forked, _ = ratio(many, f"{many}, threads")
    r_paper, _ = ratio(f"paper {gpu}", f"paper {many}")
    steps = setup["hours"] * 3600 * 100 * epochs
    paper = {
        k: f"{steps / runs[k]['seconds'] / 1e3:.0f} k timesteps/s ({runs[k]['seconds']:.0f} s)"
        for k in (f"paper {many}", f"paper {gpu}")
        if k in runs and "error" not in runs[k]
    }
    return [
        Row(
            f"first model (`workbench train`, default family), {shape}: every CPU",
            f"{fig(many)}",
            f"2 CPUs: {fig('2 cpus')}",
            r_cores,
            "≥ 4× with 16 CPUs",
            None if x_cores is None or cpus < 16 else x_cores >= 4,
        ),
        Row(
            f"first model, {shape}, every CPU ({cpus}): stage 2's fits in forked processes",
            fig(many),
            f"the fits in threads (`WORKBENCH_FIT_PROCESSES=0`): {fig(f'{many}, threads')}",
            r_forked,
            "–",
            None,
        ),
        Row(
            f"first model, {shape}: `--device cuda`",
            fig(gpu),
            f"every CPU ({cpus}): {fig(many)}",
            r_gpu,
            "≥ 2× (H100 against 16 CPUs)",
            None if x_gpu is None else x_gpu >= 2,
        ),
        Row(
            f"a Retrain's rescoring of every log, {shape}: every CPU ({cpus}), a process per core",
            secs(f"rescore {many}"),
            f"2 CPUs: {secs('rescore 2 cpus')}; every CPU in one process: {secs(f'rescore {many}, one process')}",
            ratio(f"rescore {many}", "rescore 2 cpus")[0],
            "–",
            None,
        ),
        Row(
            f"paper family's stage 1, {epochs} epoch(s) over {shape}: `--device cuda`",
            paper.get(f"paper {gpu}", "not run" if runs.get("no_paper") else "not run (no CUDA device)"),
            f"every CPU ({cpus}): {paper.get(f'paper {many}', '–')}",
            r_paper,
            "–",
            None,
        ),
    ]


if __name__ == "__main__":
    main()
