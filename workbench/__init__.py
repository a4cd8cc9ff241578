"""The human-in-the-loop workbench: CLI, viser app, demo logs. Composes ``sessions``, ``training``, ``labeling``."""

__all__: list[str] = []
