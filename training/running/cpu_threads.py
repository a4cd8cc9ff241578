"""Torch's threads on a machine that may be busy: one thread per CPU that is actually free.

torch takes a thread per core whatever else runs, and libgomp's threads spin between parallel regions by default.
With one of two cores taken (a browser, a second ``train``, a test run), the thread on the taken core is descheduled
while its partner spins at the next barrier, waiting for it: measured, the frame predictor on a 14-minute session
took 8 s alone, 30 s beside one single-threaded busy loop (3.75x) and 216 s beside two CPU-heavy processes (27x).
Counting the free CPUs (``/proc/stat`` over a fifth of a second) and leaving the rest alone makes a fit slow in
proportion to the CPU it gets (``benchmarks/speed/bench_under_load.py``: 1.48x beside one busy loop, 4.16x with torch's
own count). OpenMP's passive wait was the other lever; it costs small steps a futex wake each (17x for an LSTM's
steps, ``workbench/ui/torch_lane.py``), and one thread per free CPU leaves no partner to wait for.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path


def _cpu_times() -> tuple[int, int] | None:
    """(idle, total) jiffies of all CPUs, or None where ``/proc/stat`` is not there."""
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]
    except OSError:
        return None
    values = [int(x) for x in fields]
    idle = values[3] + (values[4] if len(values) > 4 else 0)  # idle + iowait
    return idle, sum(values[:8])  # guest time is counted in user already


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity, as a container or ``taskset`` gives it)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def free_cpus(*, sample_s: float = 0.2) -> float:
    """CPUs idle over the last ``sample_s`` seconds (of those this process may use); all of them where the machine
    gives no count."""
    cpus = usable_cpus()
    first = _cpu_times()
    if first is None:
        return float(cpus)
    time.sleep(sample_s)
    second = _cpu_times()
    assert second is not None
    total = second[1] - first[1]
    if total <= 0:
        return float(cpus)
    machine = os.cpu_count() or cpus
    idle_share = (second[0] - first[0]) / total  # of the whole machine's CPUs
    return min(float(cpus), idle_share * machine)


def threads_for(free: float, cpus: int) -> int:
    """Threads for a machine with ``free`` idle CPUs of ``cpus``: the free ones, at least one (a core half free
    counts: 1.5 free of 2 gives 2, 1.2 gives 1)."""
    return max(1, min(cpus, math.floor(free + 0.5)))


def use_free_cpus(*, sample_s: float = 0.2) -> int:
    """Set torch's intra-op threads to the CPUs free now; returns the count. An explicit ``OMP_NUM_THREADS`` or
    ``WORKBENCH_THREADS`` wins."""
    import torch

    given = os.environ.get("WORKBENCH_THREADS") or os.environ.get("OMP_NUM_THREADS")
    if given and given.isdigit() and int(given) > 0:
        threads = int(given)
    else:
        threads = threads_for(free_cpus(sample_s=sample_s), usable_cpus())
    torch.set_num_threads(threads)
    return threads
