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


def cli_errors(main):
    """Wraps a CLI ``main``: a motion file that is missing or malformed ends the command with one
    clear line (and how to point ``JAXMOTION_DATA`` at the clips) and exit status 2, not a
    traceback; so does a meta run (incremental learning) that is missing or does not fit."""
    import functools
    import sys

    @functools.wraps(main)
    def wrapped(*args, **kwargs):
        from jaxmotion.meta import MetaError
        from jaxmotion.motion.loaders import MotionFileError
        try:
            return main(*args, **kwargs)
        except MetaError as e:  # incremental learning: the meta run is missing or does not fit
            print(f"error: {e}", file=sys.stderr)
            return 2
        except MotionFileError as e:
            print(f"error: {e}", file=sys.stderr)
            print(f"Motion clips are read from $JAXMOTION_DATA (now {str(data_dir().resolve())!r}); "
                  f"point it at the folder of clips, e.g. `export JAXMOTION_DATA=/path/to/shared/motions`.",
                  file=sys.stderr)
            return 2
    return wrapped
