"""Where reference motions live: ``$JAXMOTION_DATA``, else a loaded run's recorded folder, else ``./data``.

A run folder records the absolute data folder it was trained with (``config.json``, under
``resolved``). Loading a run (eval, resume, play, ``init_from``, a meta run) calls
``use_recorded`` with it, so ``python -m jaxmotion.eval <run>`` finds the clips that
``make train`` found through the Makefile's ``JAXMOTION_DATA`` without the user exporting it.
``$JAXMOTION_DATA`` set by the user always wins.
"""

from __future__ import annotations

import os
from pathlib import Path

_recorded: Path | None = None
"""The data folder recorded by the run folder loaded last (``use_recorded``), or None."""


def use_recorded(path: str | os.PathLike | None) -> None:
    """Makes ``path`` (a loaded run's recorded data folder) the fallback of ``data_dir()`` when
    ``$JAXMOTION_DATA`` is not set; None forgets it. Process-wide: clips a run's evaluation loads
    later (other clip sets, references) come from the same folder."""
    global _recorded
    _recorded = None if path is None else Path(path).expanduser()


def recorded() -> Path | None:
    """The fallback ``use_recorded`` set, or None."""
    return _recorded


def data_dir() -> Path:
    """The data directory: ``$JAXMOTION_DATA`` (if set and not empty), else the folder recorded by
    a loaded run (``use_recorded``), else ``./data``; not checked for existence."""
    env = os.environ.get("JAXMOTION_DATA")
    if env:
        return Path(env).expanduser()
    if _recorded is not None:
        return _recorded
    return Path("data")


def resolve(path: str | os.PathLike) -> Path:
    """Resolves a motion path: absolute or existing paths as given, else relative to ``data_dir()``."""
    p = Path(path).expanduser()
    if p.is_absolute() or p.exists():
        return p
    return data_dir() / p
