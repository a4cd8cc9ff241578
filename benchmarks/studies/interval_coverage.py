"""How often the workbench's 90 % intervals cover the truth after the loop: `evaluate loop` with 24 verification
checks on the stand-ins (BorealTC with one run per terrain new, a spliced run of 26 terrain changes, the demo walks),
over seeds; per session and per new run, the share covered and the mean width. Decided: nothing is tuned here (the
interval is `labeling.powered_accuracy`'s, its cap fixed on simulations); this is the check of it.

Runs each loop as its own process (`loop_borealtc.py`, `loop_walks.py` with `--strategies combined --verify 24
--out`), keeps their output under `benchmarks/results/raw/estimates/`, and prints the table. About 25 minutes on 2
cores.
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RAW = ROOT / "benchmarks" / "results" / "raw" / "estimates"
sys.path.insert(0, str(ROOT))
TOL = 1e-9  # a bound of 1.0 computed as 0.99999999 still holds a truth of 1.0
PLAN = {
    "walks": ("loop_walks.py", [], "demo walks (C)"),
    "borealtc-new-runs": ("loop_borealtc.py", ["new-runs"], "BorealTC, one run per terrain new (A)"),
    "borealtc-spliced": ("loop_borealtc.py", ["spliced"], "BorealTC, one spliced run of 26 terrain changes"),
}


def run_one(name: str, seed: int, verify: int, tmp: Path) -> list[dict] | None:
    """One loop; every round's verification figures (``None`` when it made none)."""
    script, extra, _ = PLAN[name]
    out = tmp / f"{name}-{seed}.json"
    cmd = [sys.executable, str(ROOT / "benchmarks" / "studies" / script), *extra, "--seed", str(seed)]
    cmd += ["--strategies", "combined", "--verify", str(verify), "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    raw = RAW / f"coverage-{name}-s{seed}-{datetime.date.today()}.txt"
    raw.write_text(done.stdout + (f"\n{done.stderr}" if done.returncode else ""))
    print(f"{name} seed {seed}: exit {done.returncode}, output in {raw.relative_to(ROOT)}", flush=True)
    if done.returncode or not out.exists():
        return None
    raw.with_suffix(".json").write_text(out.read_text())  # every round's figures, for tables made later
    return [r["verified"] for r in json.loads(out.read_text())["arms"]["combined"] if r["verified"]]


def _pct(x: float) -> str:
    return f"{100 * x:.1f}"


def _interval(estimate: float, checks: int) -> tuple[float, float]:
    """The workbench's interval at an estimate: Wilson's with the checks' count (``labeling.MAX_GAIN`` 1). Loops run
    before that cap stored intervals the confidence had narrowed; every figure is put on today's rule from its
    estimate, which the cap does not change."""
    import labeling

    return labeling.wilson_bounds(estimate, checks * labeling.MAX_GAIN)


def _session_figures(verified: list[dict]) -> list[dict]:
    return [{**v, **dict(zip(("low", "high"), _interval(v["accuracy"], v["checks"]), strict=True))} for v in verified]


def _runs(verified: list[dict]) -> list[list]:
    """The checked runs' figures ``[estimate, low, high, checks, truth]`` of some rounds."""
    got = [r for v in verified for r in v["per_run"].values() if r[0] is not None]
    return [[r[0], *_interval(r[0], r[3]), r[3], r[4]] for r in got]


def _miss(r: list) -> float:
    return max(0.0, r[1] - r[4], r[4] - r[2])


def table(results: dict[str, list[list[dict]]]) -> list[str]:
    """Markdown: per stand-in, the session's figures covered (every round's), the runs' (after the last round, and
    every round's), mean widths, the largest miss."""
    lines = [
        "| stand-in | loops | session figures covered (every round) | mean width (points) | run figures covered "
        "(last round) | mean width (points) | run figures covered (every round) | mean width (points) | largest "
        "miss (points) | runs not checked (last round) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    rows = []
    every_loop = [loop for loops in results.values() for loop in loops]
    for name, got in [*results.items(), ("all", every_loop)]:
        every_round = _session_figures([v for loop in got for v in loop])
        sessions = [(v["low"] - TOL <= v["truth"] <= v["high"] + TOL, v["high"] - v["low"]) for v in every_round]
        last = _runs([loop[-1] for loop in got])
        every = _runs(every_round)
        unchecked = sum(r[0] is None for loop in got for r in loop[-1]["per_run"].values())
        rows.append(
            f"| {PLAN[name][2] if name in PLAN else name} | {len(got)} | {sum(c for c, _ in sessions)} of "
            f"{len(sessions)} | {_pct(sum(w for _, w in sessions) / max(len(sessions), 1))} | "
            f"{sum(_miss(r) <= TOL for r in last)} of {len(last)} | "
            f"{_pct(sum(r[2] - r[1] for r in last) / max(len(last), 1))} | "
            f"{sum(_miss(r) <= TOL for r in every)} of {len(every)} | "
            f"{_pct(sum(r[2] - r[1] for r in every) / max(len(every), 1))} | "
            f"{_pct(max((_miss(r) for r in every), default=0.0))} | {unchecked} |"
        )
    return lines + rows


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("--only", nargs="+", choices=list(PLAN), default=list(PLAN))
    args.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    args.add_argument("--verify", type=int, default=24)
    args.add_argument("--from-raw", action="store_true", help="the table of the loops kept under raw/, none run")
    opts = args.parse_args()
    RAW.mkdir(parents=True, exist_ok=True)
    results: dict[str, list[list[dict]]] = {}
    if opts.from_raw:
        for name in opts.only:
            for path in sorted(RAW.glob(f"coverage-{name}-s*.json")):
                arm = json.loads(path.read_text())["arms"]["combined"]
                results.setdefault(name, []).append([r["verified"] for r in arm if r["verified"]])
        print("\n".join(table(results)))
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        for name in opts.only:
            for seed in opts.seeds:
                got = run_one(name, seed, opts.verify, Path(tmp))
                if got is not None:
                    results.setdefault(name, []).append(got)
                    print("\n".join(table(results)), flush=True)  # so far: a stopped study still says something
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
