"""The errors a user can cause, and the wrapper that turns them into one line on the command line.

Every error a user can cause by what they pass in (a setting, a clip, a run folder) derives from
``JaxmotionError``; a command wrapped in ``cli_errors`` prints it as ``error: <message>`` (and
the error's ``hint``, if it has one) and exits with status 2 instead of showing a traceback.
"""

from __future__ import annotations

import functools
import sys


class JaxmotionError(Exception):
    """Bad input from the user: the message says what is wrong and where."""

    hint: str = ""
    """What the user can do about it (printed on a line of its own), or empty."""


class ConfigError(JaxmotionError, ValueError):
    """A config key, value or experiment name that does not fit the config's declared shape."""


def cli_errors(main):
    """Wraps a CLI ``main``: a ``JaxmotionError`` (a missing or malformed clip, a bad setting, a
    meta run that is missing or does not fit) ends the command with one clear line and exit
    status 2, not a traceback."""

    @functools.wraps(main)
    def wrapped(*args, **kwargs):
        try:
            return main(*args, **kwargs)
        except JaxmotionError as e:
            print(f"error: {e}", file=sys.stderr)
            if e.hint:
                print(e.hint, file=sys.stderr)
            return 2

    return wrapped
