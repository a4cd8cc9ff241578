"""Active labelling: acquisition scores, suggestions, segment snapping, label-efficiency simulation.

NumPy in, NumPy out: no torch, no UI, no session. Built in issue #4; empty until then.
"""

__all__: list[str] = []
