"""The two-stage model (stage-1 predictor, stage-2 classifier), its training, scoring and export.

Takes arrays, never sessions: ``workbench`` wires it to the session store. Built in issue #3; empty until then.
"""

__all__: list[str] = []
