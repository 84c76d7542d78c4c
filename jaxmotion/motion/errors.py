"""``MotionFileError``: a motion file that cannot be read, one line naming the file and the problem.

Its own module so that every reader (``loaders``, ``retarget``) can raise it without importing the others.
"""

from __future__ import annotations

import os

from jaxmotion.config.errors import JaxmotionError
from jaxmotion.motion.data import data_dir

_MAX_PROBLEM = 400


class MotionFileError(JaxmotionError, ValueError):
    """A motion file could not be read; the message names the file and the problem, on one line
    (a file's values can be anything: a problem is cut to ``_MAX_PROBLEM`` characters)."""

    @property
    def hint(self) -> str:
        if not any(s in self.problem for s in ("no such file", "no motion files")):
            return ""  # a bad file's problem is in the file, not in where clips are looked for
        return (
            f"Motion clips are read from $JAXMOTION_DATA (now {str(data_dir().resolve())!r}); point it at "
            f"the folder of clips, e.g. `export JAXMOTION_DATA=/path/to/shared/motions`."
        )

    def __init__(self, path: str | os.PathLike, problem: str):
        self.path = str(path)
        problem = " ".join(str(problem).split())
        self.problem = problem if len(problem) <= _MAX_PROBLEM else problem[: _MAX_PROBLEM - 3] + "..."
        super().__init__(f"{self.path}: {problem}")
