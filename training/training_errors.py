"""Errors ``training`` raises for what a user did (a damaged or incomplete model bundle). Each message is for a
person, on one line; ``workbench`` reports them as it reports the session's errors (``workbench.user_errors``)."""

from __future__ import annotations


class TrainingError(Exception):
    """Base class of the errors a user can cause in ``training``."""


class BundleError(TrainingError):
    """A bundle folder is missing files, damaged, from a newer schema, or lacks the stage a use needs."""
