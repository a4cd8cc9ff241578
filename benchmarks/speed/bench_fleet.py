"""A fleet's hours in one session (issue 66): `workbench ingest`, `workbench train` (both stages, the default family),
the first screen after a restart (scores and the suggestion queue), a Retrain's quick phase and `workbench export
--predictions`, on ``--hours`` (100; ``--quick``: 2) of 22-channel 100 Hz logs: demo walks of 30 minutes as ROS 2
MCAP, 5 % of the time labelled.

    python benchmarks/speed/bench_fleet.py [--hours 100] [--quick]

Each step runs in a fresh interpreter, as a person runs the command (the first screen and the Retrain as
`workbench serve` hosts them), and reports its wall time and peak resident set (``ru_maxrss``: mapped file pages
count in it once read), and beside it the peak of what is not file pages (``RssAnon`` sampled every 50 ms: the
memory the process itself holds; mapped pages of the session's files are the kernel's to take back). While a step
has child processes (stage 2's forked fits), it also reports the peak of its and their summed ``Pss``
(``tree``, ``tree_anon``: a page they share counts once), which its own ``ru_maxrss`` would leave out. Writing the
logs and labelling them are set-up, timed but not part of any figure.

References, measured in the same run on the same session:

- for memory: the logs' own float32 samples (the data itself);
- for `workbench train`: reading the logs and computing the default family's spectral frames from them, in a fresh
  interpreter (no stage 1 over the frames can take less);
- for the first screen after a restart: opening the session and reading the scores its first start kept (no
  first screen can take less); the first start itself, which scores every log, is printed beside it;
- for the Retrain's quick phase: `workbench train` on the same session (a first model from scratch);
- for the export: reading the logs and computing their frames, as for `workbench train`.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

LABELLED = 0.05
LOG_MINUTES = 30.0
NEW_LABELS = 6  # one-second labels a person adds before pressing Retrain


def child(step: str, *args: str) -> dict:
    """Run one step of this file in a fresh interpreter; what it printed last (JSON: its peak RSS and seconds)."""
    out = subprocess.run([sys.executable, __file__, "--child", step, *args], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{step} failed:\n{out.stdout[-2000:]}\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _write(folder: Path, hours: float) -> dict:
    from workbench.demo import generate_demo_logs

    n_logs = max(1, round(hours * 60 / LOG_MINUTES))
    files = generate_demo_logs(folder / "logs", n_logs=n_logs, minutes=hours * 60 / n_logs, seed=0)
    return {"files": len(files), "bytes": sum(f.stat().st_size for f in files)}


def _ingest(folder: Path) -> dict:
    from workbench.cli import main as workbench

    if workbench(["new", str(folder / "session")]) != 0:
        raise SystemExit("workbench new failed")
    if workbench(["ingest", str(folder / "session"), str(folder / "logs")]) != 0:
        raise SystemExit("workbench ingest failed")
    return {}


def _label(folder: Path) -> dict:
    from sessions import Session
    from workbench.demo import seed_labels

    with Session.open(folder / "session") as s:
        logs = s.logs()
        for name in {t for x in logs for _, _, t in s.reference(x.id)} - {t.name for t in s.terrains()}:
            s.add_terrain(name)
        added = seed_labels(s, LABELLED, seed=0)
        steps = sum(x.n_samples for x in logs)
        return {
            "logs": len(logs),
            "hours": steps / logs[0].rate_hz / 3600,
            "channels": len(logs[0].channel_names),
            "labelled": sum(g.stop - g.start for g in added) / steps,
            "data": steps * len(logs[0].channel_names) * 4,
        }


def _frames(folder: Path) -> dict:
    from sessions import Session
    from training import Normalizer, log_frames
    from workbench.cycle import choose_front_end

    with Session.open(folder / "session") as s:
        logs = s.logs()
        normalizer = Normalizer.fit([s.rows(x.id) for x in logs])
        front = choose_front_end(s, logs)
        return {"frames": sum(len(log_frames(s.rows(x.id), front, transform=normalizer)) for x in logs)}


def _train(folder: Path) -> dict:
    from workbench.cli import main as workbench

    if workbench(["train", str(folder / "session")]) != 0:
        raise SystemExit("workbench train failed")
    return {}


def _stored_scores(folder: Path) -> dict:
    """The first screen's floor after a restart: open the session and read the scores its last start stored."""
    from sessions import Session
    from workbench import cycle

    with Session.open(folder / "session") as s:
        stored = cycle.stored_scores(s)
        if stored is None:
            raise SystemExit("no stored scores: the first start did not keep them")
        return {}


def _first_screen(folder: Path) -> dict:
    """As `workbench serve` starts on the session: its shared state until the logs are scored and the suggestion
    queue is ranked (what the first screen shows)."""
    from speed_common import hosted_like_the_server

    from sessions import Session
    from workbench.ui import SharedState

    with Session.open(folder / "session") as s:

        def run() -> dict:
            state = SharedState(s)
            try:
                while not (state.scored and state.queue) and not state.problem:
                    time.sleep(0.02)
                if state.problem:
                    raise SystemExit(f"first screen: {state.problem}")
                return {"queued": len(state.queue)}
            finally:
                state.stop()

        return hosted_like_the_server(run)


def _retrain(folder: Path, every_log: float = 1.0) -> dict:
    """A person adds a few labels and presses Retrain: seconds to the quick phase's model on the log in view, and to
    every log showing it (``every_log`` 0: the log in view only, ``"all"`` then ``None``); the refining phase (stage 2
    from scratch) is cancelled there, as new labels would."""
    from speed_common import hosted_like_the_server, label_stretches

    from sessions import Session
    from workbench.ui import SharedState, TrainJob

    with Session.open(folder / "session") as s:
        label_stretches(s, np.random.default_rng(1), NEW_LABELS)

        def run() -> dict:
            state = SharedState(s)
            while not state.scored or state.busy:
                time.sleep(0.05)
            before = s.active_model("classifier").id
            shown = s.logs()[-1].id
            state.set_viewed("bench", shown)
            n_logs = len(s.logs())
            seen: dict[str, float] = {}
            done = threading.Event()

            def heard(event: str) -> None:
                if event != "scores" or state.scores.classifier in (None, before):
                    return
                if shown in state.scores.scores and "view" not in seen:
                    seen["view"] = time.perf_counter()
                    if not every_log:
                        done.set()
                if len(state.scores.scores) == n_logs:
                    seen["all"] = time.perf_counter()
                    done.set()

            state.subscribe(heard)
            job = TrainJob(state)
            t0 = time.perf_counter()
            job.start()
            done.wait(3600)
            if not every_log:  # the rescoring of every log it started would hold the process 20 minutes at 100 h
                _CHILD["exit"] = True
                _finish({"view": seen["view"] - t0, "all": None})
            job.cancel()
            while job.running:
                time.sleep(0.05)
            state.stop()
            return {"view": seen["view"] - t0, "all": seen["all"] - t0 if "all" in seen else None}

        return hosted_like_the_server(run)


def _export(folder: Path) -> dict:
    from workbench.cli import main as workbench

    if workbench(["export", str(folder / "session"), "--out", str(folder / "export"), "--predictions"]) != 0:
        raise SystemExit("workbench export failed")
    return {}


STEPS = {
    "write": _write,
    "ingest": _ingest,
    "label": _label,
    "frames": _frames,
    "train": _train,
    "first-start": _first_screen,  # scores every log and keeps them in the session
    "stored": _stored_scores,
    "screen": _first_screen,  # the restart
    "retrain": _retrain,
    "export": _export,
}


def _children(pid: str) -> list[str]:
    """The processes ``pid`` started and that still run (every thread's), and theirs."""
    out = []
    for children in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            out += children.read_text().split()
        except OSError:  # the thread ended
            continue
    return out + [g for c in out for g in _children(c)]


def _proportional(pids: list[str]) -> tuple[int, int]:
    """The summed ``Pss`` and ``Pss_Anon`` of ``pids``, in bytes: a page shared by n of them counts 1/n in each,
    so the sum is what they hold together (a forked fit's inherited pages are not counted twice)."""
    pss = anon = 0
    for pid in pids:
        try:
            text = Path(f"/proc/{pid}/smaps_rollup").read_text()
        except OSError:  # it ended
            continue
        for line in text.splitlines():
            if line.startswith("Pss:"):
                pss += int(line.split()[1]) * 1024
            elif line.startswith("Pss_Anon:"):
                anon += int(line.split()[1]) * 1024
    return pss, anon


def _anonymous_peak(stop: threading.Event, out: dict) -> None:
    """The highest ``RssAnon`` (memory the process itself holds, not mapped file pages, which the kernel takes back
    when it needs them) seen every 50 ms until ``stop``; while the process has children (stage 2's forked fits),
    also the highest summed ``Pss`` and ``Pss_Anon`` of it and them (``tree``, ``tree_anon``), which
    ``ru_maxrss`` of this process alone would leave out."""
    me = str(os.getpid())
    while True:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("RssAnon:"):
                    out["anon"] = max(out.get("anon", 0), int(line.split()[1]) * 1024)
        if children := _children(me):
            pss, anon = _proportional([me, *children])
            out["tree"], out["tree_anon"] = max(out.get("tree", 0), pss), max(out.get("tree_anon", 0), anon)
        if stop.wait(0.05):
            return


_CHILD: dict = {}  # the running step's start, sampler and what it sampled


def _finish(out: dict) -> None:
    """Print the step's figures (its peak RSS, peak anonymous memory, seconds and ``out``) as one line of JSON."""
    _CHILD["stop"].set()
    _CHILD["sampler"].join()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # kB on Linux
    seconds = time.perf_counter() - _CHILD["t"]
    sampled = _CHILD["anon"]
    tree = {k: sampled[k] for k in ("tree", "tree_anon") if k in sampled}  # only where fits were forked
    print(json.dumps({"peak": peak, "anon": sampled.get("anon", 0), **tree, "seconds": seconds, **out}), flush=True)
    if _CHILD.get("exit"):
        os._exit(0)  # work the step started and has no use for (a rescoring) is not waited for


def run_child(step: str, folder: Path, extra: list[str]) -> None:
    stop, anon = threading.Event(), {}
    sampler = threading.Thread(target=_anonymous_peak, args=(stop, anon), daemon=True)
    _CHILD.update(t=time.perf_counter(), stop=stop, anon=anon, sampler=sampler)
    sampler.start()
    out = STEPS[step](folder, *(float(a) for a in extra))
    _finish(out)


def main() -> None:
    if "--child" in sys.argv:
        i = sys.argv.index("--child")
        sys.path.insert(0, str(Path(__file__).parent))
        run_child(sys.argv[i + 1], Path(sys.argv[i + 2]), sys.argv[i + 3 :])
        return
    from speed_common import Row, record

    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--device", default="cpu", choices=("cpu", "cuda"))
    p.add_argument("--quick", action="store_true", help="2 hours: checks the script runs, figures mean little")
    p.add_argument("--hours", type=float, default=100.0)
    p.add_argument("--keep", type=Path, default=None, help="build the session here and keep it (default: a temp dir)")
    p.add_argument("--until", choices=tuple(STEPS), default=None, help="stop after this step and print what ran")
    args = p.parse_args()
    hours = 2.0 if args.quick else args.hours
    r: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for step in STEPS:
            r[step] = child(step, str(folder), *([str(hours)] if step == "write" else []))
            print(f"{step} {r[step]}", flush=True)
            if step == args.until:
                return
    gib = 2**30
    data = r["label"]["data"] / gib
    where = (
        f"{r['label']['hours']:.1f} h of {r['label']['channels']}-channel 100 Hz logs ({r['label']['logs']} logs), "
        f"{r['label']['labelled']:.1%} labelled"
    )

    def peak(step: str) -> str:
        tree = r[step].get("tree")
        forked = "" if tree is None else f"; with its forked fits, summed Pss {tree / gib:.2f} GiB"
        return f"peak {r[step]['peak'] / gib:.2f} GiB RSS ({r[step]['anon'] / gib:.2f} GiB not file pages{forked})"

    rows = [
        Row(
            f"`workbench ingest`, {where}",
            f"{r['ingest']['seconds']:.0f} s, {peak('ingest')}",
            f"the logs' float32 samples: {data:.2f} GiB",
            f"{r['ingest']['peak'] / gib / data:.2f}× the data",
            "peak not growing with the hours",
            None,
        ),
        Row(
            f"first model: `workbench train` (both stages, default family), {where}",
            f"{r['train']['seconds']:.0f} s, {peak('train')}",
            f"reading the logs + computing the frames: {r['frames']['seconds']:.0f} s, {peak('frames')}",
            f"{r['train']['seconds'] / r['frames']['seconds']:.1f}× the reference",
            "≤ 15 min, peak ≤ 3 GiB",
            bool(r["train"]["seconds"] <= 900 and r["train"]["peak"] <= 3 * gib),
        ),
        Row(
            f"first screen after a restart (scores and the suggestion queue), {where}",
            f"{r['screen']['seconds']:.1f} s, {peak('screen')}",
            f"opening the session, reading the scores kept: {r['stored']['seconds']:.1f} s "
            f"(the first start, scoring every log: {r['first-start']['seconds']:.0f} s)",
            f"{r['screen']['seconds'] / r['stored']['seconds']:.1f}× the reference",
            "≤ 10 s",
            bool(r["screen"]["seconds"] <= 10),
            f"{r['screen']['queued']} suggestions queued",
        ),
        Row(
            f"Retrain, quick phase: pressed → log in view / every log refreshed, {where}",
            f"{r['retrain']['view']:.0f} s / {r['retrain']['all']:.0f} s, {peak('retrain')}",
            f"`workbench train` on the same session: {r['train']['seconds']:.0f} s",
            f"{r['train']['seconds'] / r['retrain']['view']:.1f}× faster",
            "≤ 60 s",
            bool(r["retrain"]["view"] <= 60),
        ),
        Row(
            f"`workbench export --predictions`, {where}",
            f"{r['export']['seconds']:.0f} s, {peak('export')}",
            f"reading the logs + computing the frames: {r['frames']['seconds']:.0f} s",
            f"{r['export']['seconds'] / r['frames']['seconds']:.1f}× the reference",
            "peak not growing with the hours",
            None,
        ),
    ]
    record("fleet", rows, device=args.device)


if __name__ == "__main__":
    main()
