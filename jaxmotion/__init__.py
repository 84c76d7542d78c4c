"""jaxmotion: physically simulated characters trained from motion capture, end to end in JAX."""

import contextlib as _contextlib
import io as _io

__version__ = "0.1.0"

# MJX prints "Failed to import warp" on stdout when the optional MuJoCo Warp backend is absent
# (always, on CPU); import it once here, quietly, so CLI output stays clean. The ImportError is
# suppressed only for safety: mujoco is a hard dependency.
with _contextlib.redirect_stdout(_io.StringIO()), _contextlib.suppress(ImportError):
    from mujoco import mjx as _mjx  # noqa: F401
