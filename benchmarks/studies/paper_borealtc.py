"""The studies, as ``make paper`` runs them: both model families on BorealTC's protocols, the label-efficiency
simulation, the studies behind the default family's kept choices, the model's and its figures' studies, and the
loop's. Each study is one script of this room whose first line says what it decided and the figure that did.

    python benchmarks/studies/paper_borealtc.py [protocol|simulate|decisions|model|loop|all]
    python benchmarks/studies/paper_borealtc.py model PART...   # some of its parts: labels, card-runs, ...

``decisions``: the default family's kept choices, each its study (the spectral front end under a plain learner, the
network over the frames against the linear model, self-training left out, ``classify --smooth``), and MiniRocket's
heads at 4,096 windows; each output goes to ``benchmarks/results/raw/protocols/NAME-DATE.txt``. Their durations on
2 cores were not measured as one command.

``protocol``: the default family (about 2 minutes on 2 CPU cores) and the paper family (about an hour per split) on
the authors' partition folds and on folds holding out whole runs, 10 % of the training partitions labelled.
``simulate``: random against the suggested labels, 5 seeds (seed s runs outer fold s + 1), 8 rounds of 10 whole
partitions, for the default family (about 15 minutes) and the paper family (hours).

``model``: the runs split at 5, 10, 25 and 100 % of labels for the default family, MiniRocket with a ridge head and
their mean (an ensemble member), the default family at a 3.4 s span (an ablation of the span), the default family's
minority row (each terrain kept at a tenth of its time; again without the logit adjustment, its ablation), the
expected accuracy per held-out run against what it scored (on BorealTC's runs and on demo walks whose terrain
changes), the card against ``workbench evaluate session`` on BorealTC sessions, and the label efficiency on folds by
run (``workbench evaluate borealtc --simulate --split runs``, 3 seeds); 82 minutes as one command on 2 cores (at
76f3e90), each output written to ``benchmarks/results/raw/protocols/`` (the expected accuracy's and the card's to
``raw/estimates/``) as ``NAME-DATE.txt``, which ends with its seconds.

``loop``: `workbench evaluate loop` (4 rounds of 12 suggestions, a piece person) on BorealTC with one run per
terrain left unlabelled, on BorealTC with a run spliced from five (26 terrain changes), and on demo walks whose
terrain changes, each with ``combined``, its ablations (``combined-no-unchecked``: new runs not first;
``combined-no-wrong-first``: runs the checks found wrong not asked again; ``combined-no-main-answer``: a run's main
answer never asked; ``combined-no-votes``: a run's labels not voting over its frames) and ``random``, on seed 1
(some rules were chosen on it; benchmarks/results/raw/loop/notebook-new-runs-2026-11-28.md has seed 2 beside it);
and the run votes' screen on demo walks never used for the choice. About an hour a loop part on 2 cores (six arms).

Writes its raw outputs (and the simulation plot) under ``benchmarks/results/raw/<question>/``; the pages above them
(``protocols.md``, ``estimates.md``, ``loop.md``) are written by hand from them. Skips with a reason when
``../shared/data/borealtc`` is absent (a user's clone).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "borealtc"
RAW = ROOT / "benchmarks" / "results" / "raw"
DAY = time.strftime("%Y-%m-%d")
BENCH = str(ROOT / "benchmarks" / "studies")
SIMULATE_RUNS = (
    "--simulate",
    "--split",
    "runs",
    "--model",
    "default",
    "--seeds",
    "3",
    "--rounds",
    "8",
    "--per-round",
    "10",
)
MODEL = (  # (name, arguments to python): each prints its own table
    ("labels", [f"{BENCH}/minirocket_borealtc.py"]),  # the runs split at 5/10/25/100 %: default, MiniRocket, mean
    ("labels-span", [f"{BENCH}/minirocket_borealtc.py", "--span", "3.4", "--no-member", "--labelled", "0.1", "1"]),
    ("minority", [f"{BENCH}/minority_borealtc.py"]),
    ("minority-none", [f"{BENCH}/minority_borealtc.py", "--balance", "none"]),  # the logit adjustment's ablation
    ("expected", [f"{BENCH}/expected_borealtc.py", "--screen-stretch", "0"]),  # 0: the ablation of the 10 s merge
    ("expected-walks", [f"{BENCH}/expected_walks.py"]),  # the same figure where terrain changes within a file
    ("card-pieces", [f"{BENCH}/card_vs_session_borealtc.py", "pieces"]),
    ("card-runs", [f"{BENCH}/card_vs_session_borealtc.py", "runs"]),
    ("efficiency-runs", ["-m", "workbench.cli", "evaluate", "borealtc", str(DATA), *SIMULATE_RUNS]),
)
LOOP_ARMS = (
    "--strategies",
    "combined",
    "combined-no-unchecked",
    "combined-no-wrong-first",
    "combined-no-main-answer",
    "combined-no-votes",
    "random",
)
LOOP = (
    ("loop-walks", [f"{BENCH}/loop_walks.py", "--seed", "1", *LOOP_ARMS]),
    ("loop-new-runs", [f"{BENCH}/loop_borealtc.py", "new-runs", "--seed", "1", *LOOP_ARMS]),
    ("loop-spliced", [f"{BENCH}/loop_borealtc.py", "spliced", "--seed", "1", *LOOP_ARMS]),
    ("propagate-demo-s2", [f"{BENCH}/propagate_screen.py", "demo", "--seed", "2"]),
)
DECISIONS = (
    ("front-end", [f"{BENCH}/spectral_baseline.py", str(DATA), "--labelled", "0.05", "0.1", "1.0"]),
    ("network", [f"{BENCH}/default_family_cnn.py", "--outer", "3", "--variants", "lr", "cnn_st"]),
    ("self-training", [f"{BENCH}/default_family_ablation.py", "--labelled", "0.1"]),
    ("smooth", [f"{BENCH}/smooth_demo.py"]),
    ("rocket-rows", [f"{BENCH}/rocket_rows_borealtc.py"]),  # MiniRocket's 4,096 windows where they bite (25 %)
)
PARTS = {"decisions": DECISIONS, "model": MODEL, "loop": LOOP}
# the question each part's raw output answers (benchmarks/results/raw/<question>/): the page it feeds
QUESTION = {"decisions": "protocols", "model": "protocols", "loop": "loop"}
ESTIMATES = {"expected", "expected-walks", "card-pieces", "card-runs"}  # model's parts that feed estimates.md


def main(which: str = "all", *, parts: list[str] | None = None) -> int:
    if parts and which not in PARTS:
        print(f"paper_borealtc.py: parts are for {' and '.join(PARTS)} only, not {which}", file=sys.stderr)
        return 2
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return 0
    sys.path.insert(0, str(ROOT))
    from workbench.evaluation import protocols as ev

    protocols = RAW / "protocols"
    protocols.mkdir(parents=True, exist_ok=True)
    if which in ("protocol", "all"):
        t = time.monotonic()
        (protocols / f"borealtc-protocol-{DAY}.json").unlink(missing_ok=True)  # the workbench writes new files only
        report = ev.evaluate_borealtc(
            DATA,
            model="both",
            labelled=0.1,
            split="both",
            variant="shared",
            out=protocols / f"borealtc-protocol-{DAY}.json",
        )
        (protocols / f"borealtc-protocol-{DAY}.md").write_text(report + f"\n\n{time.monotonic() - t:.0f} s\n")
        print(report)
    if which in ("simulate", "all"):
        t = time.monotonic()
        for model in ("default", "paper"):
            (protocols / model / "simulate-borealtc.png").unlink(missing_ok=True)
        report = "\n\n".join(
            f"## {model} family\n\n"
            + ev.simulate(
                "borealtc",
                DATA,
                strategies=("random", "combined"),
                seeds=5,
                rounds=8,
                batch=10,
                out=protocols / model,
                model=model,
            )
            for model in ("default", "paper")
        )
        (protocols / f"borealtc-simulate-{DAY}.md").write_text(report + f"\n\n{time.monotonic() - t:.0f} s\n")
        print(report)
    code = 0
    for part, table in PARTS.items():
        if which in (part, "all"):
            code = max(code, run_parts(part, table, parts or [name for name, _ in table]))
    return code


def run_parts(part: str, table: tuple, parts: list[str]) -> int:
    """Run the named parts of a ``table`` in its order; each output goes to ``raw/<question>/NAME-DATE.txt`` headed by
    the commit it ran at and ending with its seconds, so parts run at different times say which code gave them."""
    known = [name for name, _ in table]
    unknown = sorted(set(parts) - set(known))
    if unknown:
        print(f"paper_borealtc.py: no part named {', '.join(unknown)} (the parts: {', '.join(known)})", file=sys.stderr)
        return 2
    commit = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True, cwd=ROOT)
    failed = []
    for name, args in table:
        if name not in parts:
            continue
        print(f"## {name} (started {time.strftime('%H:%M:%S')})", flush=True)
        t = time.monotonic()
        out = subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=ROOT)
        took = f"{time.monotonic() - t:.0f} s" + (f", exit {out.returncode}" if out.returncode else "")
        command = " ".join(a.replace(f"{ROOT}/", "") for a in args)
        text = f"commit {commit.stdout.strip() or 'unknown'}: python {command}\n\n{out.stdout}{out.stderr}\n{took}\n"
        folder = RAW / ("estimates" if name in ESTIMATES else QUESTION[part])
        folder.mkdir(parents=True, exist_ok=True)
        (folder / f"{name}-{DAY}.txt").write_text(text)
        print(f"\n{text}", flush=True)
        if out.returncode:
            failed.append(name)
    if failed:
        where = f"benchmarks/results/raw/{QUESTION[part]}/"
        print(f"paper_borealtc.py: {', '.join(failed)} failed; see {where}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:2], parts=sys.argv[2:]))
