"""``workbench label-studio``: the session as a Label Studio ML backend."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import tyro

from sessions import Session, WorkbenchError

from .terminal import shown


def label_studio(
    session: Annotated[Path, tyro.conf.Positional],
    host: str = "127.0.0.1",
    port: int = 9090,
    user: str | None = None,
    password: str | None = None,
    create_terrains: bool = False,
) -> None:
    """Serve the session as a Label Studio ML backend: its model's stretches as pre-annotations, tasks scored so that
    "sort by prediction score" (ascending) follows the workbench's suggestions, annotations as the session's labels
    and "Start training" as a Retrain.

    In Label Studio: the project's Settings > Model > Connect Model, URL ``http://HOST:PORT`` (with the user and
    password under "Use basic authentication" when served beyond loopback); tasks name their log by ``data.log`` or
    a data file named after it, as `labels export --format label-studio` writes them.

    Args:
        session: The session folder.
        host: Address to bind. The default serves this machine only; another needs --user and --password.
        port: Port to listen on (Label Studio's examples use 9090); 0 picks any free one.
        user: Basic auth's user Label Studio must send (default: $BASIC_AUTH_USER).
        password: Basic auth's password, at least 16 characters (default: $BASIC_AUTH_PASS).
        create_terrains: Add a terrain an annotation names that the session lacks (else that region is refused).
    """
    from training import hide_gpus

    from ..label_studio import serve_label_studio
    from ..ui.gate import MIN_TOKEN_CHARS, is_loopback

    user = user if user is not None else os.environ.get("BASIC_AUTH_USER")
    password = password if password is not None else os.environ.get("BASIC_AUTH_PASS")  # "" is given, and too short
    if (not user) != (password is None):
        raise WorkbenchError("basic auth needs both a user and a password (--user, --password)")
    if password is not None and (len(password) < MIN_TOKEN_CHARS or not password.isprintable()):
        raise WorkbenchError(
            f"a basic-auth password of {len(password)} character(s): at least {MIN_TOKEN_CHARS} printable characters,"
            " as the page's token"
        )
    if not user and not is_loopback(host):
        raise WorkbenchError(
            f"serving {host} beyond loopback needs basic auth: --user and --password (Label Studio's BASIC_AUTH_USER"
            " and BASIC_AUTH_PASS), or an SSH tunnel to a loopback backend"
        )
    hide_gpus()  # as serve: the backend trains and scores on the CPU
    with Session.open(session) as s:
        print(f"serving {shown(s.path)} to Label Studio", flush=True)
        auth = None if not user else (user, password or "")
        serve_label_studio(s, host=host, port=port, auth=auth, create_terrains=create_terrains)
