"""Stand-in D (issue 98): a legged robot's IMU, one floor per run, where the session knows far more than its bundle.

`workbench evaluate loop` on DogSurf's Go1 runs (`../shared/data/dogsurf-go1/`, SOURCE.md: 14 runs of about 600 s
at 50 Hz on four floors, a headerless CSV each). Per floor, drawn with ``--seed``: one run labelled at 10 % of its
time in 5 s pieces, one new run nobody labelled, the rest far (kept out of the session, scored after every round
by the bundle the session would export, read with the session's mapping and ``--allow-gaps``). Ice has two runs:
one labelled, one far, and no new run, so every floor is in the far runs (what the robot gets is judged on each
floor) and the session's new runs are three floors. The session: 4 labelled runs and 3 new (about 70 minutes), 7
far runs.

    python benchmarks/studies/loop_dogsurf.py [--seed S] [--strategies combined combined-teacher-last random]
    python benchmarks/studies/loop_dogsurf.py --ceiling [--seed S]     # every step of the session labelled

``--ceiling``: every step of the session's 7 runs given its true floor, both stages fitted, the bundle scored on
the far runs: what knowing the session's runs perfectly buys the default family (`loop_ceiling.py`'s rule).
Skips with a reason when ``../shared/data/dogsurf-go1`` is absent; its files are read there, never copied.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from study_common import label_runs, loop_arguments, loop_settings

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "dogsurf-go1"
# columns 0-5: the accelerometer and the gyroscope (raw counts); 6-8 unused; 9: Unix time in milliseconds
MAPPING = """[csv]
header = false
time_column = 9
time_unit = "ms"
""" + "".join(
    f'\n[[channels]]\nsource = "{i}"\nname = "{name}"\nunit = "count"\n'
    for i, name in enumerate(("acc.x", "acc.y", "acc.z", "gyro.x", "gyro.y", "gyro.z"))
)


def runs() -> dict[str, list[Path]]:
    """DogSurf's runs: floor -> its files, in run order."""
    return {d.name: sorted(d.glob("*.csv")) for d in sorted(DATA.iterdir()) if d.is_dir()}


def read_options(folder: Path):
    """The ``IngestOptions`` the session's runs and the far runs are read with (the mapping written in ``folder``)."""
    from sessions import IngestOptions, load_mapping

    path = folder / "dogsurf.toml"
    path.write_text(MAPPING)
    return IngestOptions(mapping=load_mapping(path), allow_gaps=True, camera_fps=0)


def build(folder: Path, *, seed: int) -> tuple[Path, Path, list[Path], object]:
    """The session at ``folder``, the reference file (the new runs' truth and the far runs'), the far runs' files
    and the read options; labels on one run per floor."""
    from sessions import Session

    rng = np.random.default_rng(seed)
    by_floor = {t: [fs[i] for i in rng.permutation(len(fs))] for t, fs in runs().items()}
    labelled = {t: fs[0] for t, fs in by_floor.items()}
    new = {t: fs[1] for t, fs in by_floor.items() if len(fs) > 2}  # ice's second run goes far
    far = sorted(f for t, fs in by_floor.items() for f in fs[1 + (t in new) :])
    options = read_options(folder.parent)
    floor_of = {f.stem: t for t, fs in by_floor.items() for f in fs}
    with Session.create(folder) as s:
        for t in sorted(by_floor):
            s.add_terrain(t)
        logs = s.ingest([*labelled.values(), *new.values()], options=options)
        truth = folder.parent / "session-truth.csv"
        pd.DataFrame(
            [(x.name, 0.0, x.n_samples / x.rate_hz, floor_of[x.name]) for x in logs],
            columns=["log", "start_s", "end_s", "terrain"],
        ).to_csv(truth, index=False)
        s.import_reference(truth)
        label_runs(s, [x for x in logs if Path(x.source_path).stem in {f.stem for f in labelled.values()}], seed=seed)
        print(
            f"{len(logs)} runs; labelled at 10 % in 5 s pieces: {', '.join(f.stem for f in labelled.values())} "
            f"({len(s.segments())} segments); new: {', '.join(f.stem for f in new.values())}",
            flush=True,
        )
        new_names = {f.stem for f in new.values()}
        rows = [(x.name, 0.0, x.n_samples / x.rate_hz, floor_of[x.name]) for x in logs if x.name in new_names]
    rows += [(f.stem, 0.0, 1e5, floor_of[f.stem]) for f in far]
    reference = folder.parent / "far-reference.csv"
    pd.DataFrame(rows, columns=["log", "start_s", "end_s", "terrain"]).to_csv(reference, index=False)
    print(f"far: {', '.join(f.stem for f in far)} (never in the session)", flush=True)
    return folder, reference, far, options


def main() -> int:
    args = loop_arguments(__doc__)
    args.add_argument("--ceiling", action="store_true", help="every step of the session's runs labelled with its truth")
    args.add_argument("--model", default=None, help="--ceiling: stage 2's family (default: the session's)")
    opts = args.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (DogSurf is not shipped with the project)")
        return 0
    sys.path.insert(0, str(ROOT))
    from sessions import Session
    from workbench.evaluation import evaluate_loop

    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        folder, reference, far, options = build(Path(tmp) / "s", seed=opts.seed)
        with Session.open(folder) as s:
            if opts.ceiling:
                from loop_ceiling import labelled_by_truth, report

                got, n = labelled_by_truth(s, far, reference, model=opts.model, options=options)
                report(got, n, opts.model, opts.seed, t0)
                return 0
            print(
                evaluate_loop(
                    s,
                    reference=reference,
                    settings=loop_settings(opts),
                    workdir=Path(tmp),
                    far=far,
                    far_options=options,
                    out=opts.out,
                )
            )
    print(f"{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
