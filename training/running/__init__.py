"""How fits run: on the CPUs that are free, side by side in forked processes or threads, across processes under
``torchrun``, resumable from checkpoints, reporting progress and polled for a cancel.

Modules: ``cpu_threads`` (threads for the free CPUs), ``fit_threads`` (a family's fits run two or more at a time,
bit-identical whatever the workers), ``fit_processes`` (those fits in forked children, clear of the GIL),
``distributed`` (the process group under ``torchrun``; a public submodule),
``checkpoint`` (a fit's state on disk, keyed by its settings), ``progress`` (what a fit reports, and its cancel),
``parent_death`` (a forked child ends with its parent). Names load on first use: ``progress``, ``cpu_threads`` and
``parent_death`` never load torch.
"""

from ..lazy_names import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "checkpoint": (
            "CHECKPOINT_SCHEMA",
            "Checkpoint",
            "fingerprint",
            "keyed_path",
            "load_checkpoint",
            "other_checkpoints",
            "save_checkpoint",
        ),
        "cpu_threads": ("free_cpus", "threads_for", "use_free_cpus", "usable_cpus"),
        "fit_processes": ("fork_safe", "forking", "hide_gpus", "run_forked"),
        "fit_threads": ("INIT_LOCK", "fit_workers", "run_fits"),
        "parent_death": ("end_with_parent",),
        "progress": ("CancelFn", "Cancelled", "Progress", "ProgressFn", "never"),
    },
    globals(),
    submodules=("distributed",),
)
