"""Kept: the yardstick of issue 65 (`workbench evaluate loop`). On the spliced run, `combined` 89.8 % against random's
79.8 %; on one new run per terrain, 87.1 against 87.2 % (benchmarks/results/raw/loop/notebook-new-runs-2026-11-28.md).

Issue 65's loop on BorealTC's runs: `workbench evaluate loop` on a session where some runs were labelled (10 % of
their time, in 5 s pieces) and others have no label at all, as a person's new runs do.

    python benchmarks/studies/loop_borealtc.py new-runs [--per-terrain 1] [--seed S] [--rounds 4] [--person piece]
    python benchmarks/studies/loop_borealtc.py spliced [--changes 26] ...
    python benchmarks/studies/loop_borealtc.py new-runs --far-per-terrain 2   # + runs kept out of the session

``new-runs``: ``--per-terrain`` runs of each terrain (drawn with ``--seed``) get no label; every other run is
labelled at 10 %. ``spliced``: one run of each terrain is cut into ``--changes`` + 1 pieces, shuffled into one new
run with that many terrain changes (the IMU and the motor channels cut at the same times, on one clock), which
replaces them; every other run is labelled at 10 %. The reference of the new runs is their folder name (spliced: the
pieces' own terrains). ``--far-per-terrain N``: N more runs of each terrain are kept out of the session entirely
and scored after every round by the bundle the session would export (issue 82's far runs); ``--labelled-per-terrain
N`` keeps only N labelled runs of each terrain in the session (often one run per terrain, as a robot's first day
is). Skips with a reason when
``../shared/data/borealtc`` is absent.
"""

from __future__ import annotations

import itertools
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from study_common import label_runs, loop_arguments, loop_settings

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "borealtc"


def _splice(
    runs: list[tuple[Path, ...]],
    terrains: list[str],
    out: Path,
    *,
    changes: int,
    seed: int,
    piece_s: tuple[float, float] | None = None,
) -> list:
    """One BorealTC-shaped run (``out/MIXED/imu_90.csv``, ``pro_90.csv``: the files each run has) from pieces of
    ``runs``, shuffled so that neighbours differ: ``changes`` terrain changes. Each run is cut in equal pieces, or
    with ``piece_s`` in pieces of lengths drawn between those seconds. Returns its reference rows ``(start_s, end_s,
    terrain)``."""
    rng = np.random.default_rng(seed)
    per_run = (changes + 1) // len(runs) + 1
    pieces = []
    for files, terrain in zip(runs, terrains, strict=True):
        frames = [pd.read_csv(f) for f in files]
        end = min(f["time"].iloc[-1] for f in frames)
        if piece_s is None:
            cuts = np.linspace(0.0, end, per_run + 1)
        else:  # lengths between piece_s, as many as the run holds
            lengths = rng.uniform(*piece_s, size=int(end // piece_s[0]) + 1)
            cuts = np.concatenate([[0.0], np.cumsum(lengths)])
            cuts = cuts[cuts <= end]
        pieces += [(terrain, frames, lo, hi) for lo, hi in itertools.pairwise(cuts)]
    order: list[int] = []
    left = list(rng.permutation(len(pieces)))
    while left and len(order) < changes + 1:  # neighbours of different terrains: every joint is a change
        pick = next((i for i in left if not order or pieces[i][0] != pieces[order[-1]][0]), None)
        if pick is None:
            break
        order.append(pick)
        left.remove(pick)
    names = [f.name.split("_")[0] for f in runs[0]]  # imu, pro
    parts: list[list[pd.DataFrame]] = [[] for _ in names]
    rows, t = [], 0.0
    for i in order:
        terrain, frames, lo, hi = pieces[i]
        for frame, into in zip(frames, parts, strict=True):
            part = frame[(frame["time"] >= lo) & (frame["time"] < hi)].copy()
            part["time"] = part["time"] - lo + t
            into.append(part)
        rows.append((t, t + hi - lo, terrain))
        t += hi - lo
    folder = out / "MIXED"
    folder.mkdir(parents=True)
    for name, got in zip(names, parts, strict=True):
        pd.concat(got).to_csv(folder / f"{name}_90.csv", index=False)
    return rows


def _runs() -> dict[str, dict[str, list[Path]]]:
    """BorealTC's runs: terrain folder -> run number -> its files."""
    out: dict[str, dict[str, list[Path]]] = {}
    for f in sorted(DATA.glob("*/*_*.csv")):
        out.setdefault(f.parent.name, {}).setdefault(f.stem.split("_")[1], []).append(f)
    return out


def build(
    folder: Path,
    layout: str,
    *,
    per_terrain: int,
    changes: int,
    seed: int,
    far_per_terrain: int = 0,
    labelled_per_terrain: int = 0,
    motor_only: bool = False,
    piece_s: tuple[float, float] | None = None,
) -> tuple[Path, Path | None, list[Path]]:
    """The session, the reference file (the spliced run's, and the far runs' truth) and the far runs' files
    (``motor_only``: the ``pro_*.csv`` files alone, at their own 6.5 Hz; ``piece_s``: the spliced run's pieces of
    lengths drawn between those seconds)."""
    from sessions import Session

    rng = np.random.default_rng(seed)
    runs = _runs()
    if motor_only:  # copies of the motor files alone (a BorealTC file given alone brings its partner beside it)
        for t, by_run in runs.items():
            for r, fs in by_run.items():
                (folder.parent / "motor" / t).mkdir(parents=True, exist_ok=True)
                for f in fs:
                    if f.name.startswith("pro_"):
                        shutil.copy(f, folder.parent / "motor" / t / f.name)
                by_run[r] = [folder.parent / "motor" / t / f.name for f in fs if f.name.startswith("pro_")] + [
                    f for f in fs if not f.name.startswith("pro_")
                ]

    def kept_files(fs) -> list[Path]:
        return [f for f in fs if not motor_only or f.name.startswith("pro_")]

    taken = {  # per terrain, the runs that will not be labelled (spliced: cut into the new run instead), then far
        t: [r for r in rng.permutation(sorted(by_run)) if len(by_run[r]) == 2] for t, by_run in runs.items()
    }
    first = per_terrain
    chosen = {t: rs[:first] for t, rs in taken.items()}
    far_runs = {t: rs[first : first + far_per_terrain] for t, rs in taken.items()}
    far_files = sorted(f for t, rs in far_runs.items() for r in rs for f in kept_files(runs[t][r]))
    files = [f for t, by_run in runs.items() for r, fs in by_run.items() for f in kept_files(fs) if f not in far_files]
    if labelled_per_terrain:  # a small session: that many labelled runs of each terrain, the rest left out entirely
        end = first + far_per_terrain
        kept = {(t, r) for t, rs in taken.items() for r in rs[: end + labelled_per_terrain]}
        files = [f for f in files if (f.parent.name, f.stem.split("_")[1]) in kept or f.parent.name == "MIXED"]
    reference = None
    if layout == "spliced":
        pairs = [tuple(sorted(kept_files(runs[t][r]))) for t in sorted(chosen) for r in chosen[t]]  # (imu, pro)
        terrains = [t.lower() for t in sorted(chosen) for _ in chosen[t]]
        rows = _splice(pairs, terrains, folder.parent / "spliced", changes=changes, seed=seed, piece_s=piece_s)
        skip = {f for pair in pairs for f in pair}
        files = [f for f in files if f not in skip] + sorted((folder.parent / "spliced" / "MIXED").iterdir())
    with Session.create(folder) as s:
        logs = s.ingest(files)
        for name in sorted({t for x in logs for _, _, t in s.reference(x.id)} - {"mixed"}):
            s.add_terrain(name)
        if layout == "spliced":
            (spliced,) = [x for x in logs if x.name.startswith("MIXED")]
            reference = folder.parent / "spliced-reference.csv"
            end = spliced.n_samples / spliced.rate_hz  # the aligned run ends at its last sample
            kept = [(spliced.name, a, min(b, end), t) for a, b, t in rows if a < end]
            pd.DataFrame(kept, columns=["log", "start_s", "end_s", "terrain"]).to_csv(reference, index=False)
            new = [spliced]
        else:
            names = {f"{t}_{r}" for t in chosen for r in chosen[t]}
            new = [x for x in logs if x.name in names]
        labelled = [x for x in logs if x.id not in {n.id for n in new}]
        label_runs(s, labelled, seed=seed)
        print(
            f"{len(logs)} runs; {len(labelled)} labelled at 10 % in 5 s pieces ({len(s.segments())} segments); "
            f"new: {', '.join(x.name for x in new)}",
            flush=True,
        )
        if far_files:  # the far runs' truth (their folder), beside the session's new runs' reference rows
            if reference is not None:  # the spliced run's truth is in its file, not in the session
                rows = list(pd.read_csv(reference).itertuples(index=False, name=None))
            else:
                rows = [(x.name, a / x.rate_hz, b / x.rate_hz, t) for x in new for a, b, t in s.reference(x.id)]
            rows += [(f"{t}_{r}", 0.0, 1e5, t.lower()) for t, rs in far_runs.items() for r in rs]
            reference = folder.parent / "far-reference.csv"
            pd.DataFrame(rows, columns=["log", "start_s", "end_s", "terrain"]).to_csv(reference, index=False)
            print(f"far: {', '.join(f'{t}_{r}' for t, rs in far_runs.items() for r in rs)} (never in the session)")
    return folder, reference, far_files


def main() -> int:
    args = loop_arguments(__doc__)
    args.add_argument("layout", nargs="?", default="new-runs", choices=["new-runs", "spliced"])
    args.add_argument("--per-terrain", type=int, default=1)
    args.add_argument("--changes", type=int, default=26)
    args.add_argument("--far-per-terrain", type=int, default=0, help="runs of each terrain kept out of the session")
    args.add_argument(
        "--labelled-per-terrain", type=int, default=0, help="labelled runs of each terrain in the session (0: all)"
    )
    args.add_argument("--motor-only", action="store_true", help="the motor files alone (pro_*.csv, 6.5 Hz)")
    args.add_argument("--piece-s", type=float, nargs=2, default=None, help="the spliced run's pieces: LO HI seconds")
    opts = args.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return 0
    sys.path.insert(0, str(ROOT))
    from sessions import Session
    from workbench.evaluation import evaluate_loop

    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        folder, reference, far = build(
            Path(tmp) / "s",
            opts.layout,
            per_terrain=opts.per_terrain,
            changes=opts.changes,
            seed=opts.seed,
            far_per_terrain=opts.far_per_terrain,
            labelled_per_terrain=opts.labelled_per_terrain,
            motor_only=opts.motor_only,
            piece_s=None if opts.piece_s is None else tuple(opts.piece_s),
        )
        with Session.open(folder) as s:
            print(
                evaluate_loop(
                    s, reference=reference, settings=loop_settings(opts), workdir=Path(tmp), far=far, out=opts.out
                )
            )
    print(f"{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
