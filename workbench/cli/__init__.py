"""The ``workbench`` command line (tyro): one module per group of commands, the ingest dry-run report."""

from .main import main, serve

__all__ = ["main", "serve"]
