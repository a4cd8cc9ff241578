"""A forked child that ends with its parent: no fit, rescoring or ``classify`` worker runs on after a kill.

Torch-free, so ``classify``'s pool (which runs without PyTorch) uses it too.
"""

from __future__ import annotations

import ctypes
import os
import signal

PR_SET_PDEATHSIG = 1  # prctl's option: a signal for this process when the thread that forked it ends


def end_with_parent(parent: int) -> None:
    """Have the kernel end this child when the thread that forked it ends (a killed ``train``, server or
    ``classify`` leaves no child running on), or end it now if that already happened.

    Args:
        parent: The parent's pid, taken before the fork.
    """
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):  # no prctl: the child ends when its send finds the pipe closed
        return
    if os.getppid() != parent:
        os._exit(1)
