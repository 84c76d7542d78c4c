"""Where reference motions live: ``$JAXMOTION_DATA``, else ``./data``."""

from __future__ import annotations

import os
from pathlib import Path


def data_dir() -> Path:
    """The data directory (``$JAXMOTION_DATA`` or ``./data``); not checked for existence."""
    return Path(os.environ.get("JAXMOTION_DATA", "data")).expanduser()


def resolve(path: str | os.PathLike) -> Path:
    """Resolves a motion path: absolute or existing paths as given, else relative to ``data_dir()``."""
    p = Path(path).expanduser()
    if p.is_absolute() or p.exists():
        return p
    return data_dir() / p
