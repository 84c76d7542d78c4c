"""Is a parsed clip a motion a body can make? Checks that turn finite-but-absurd clips into errors.

A clip with fps 1e300, a root at 1e30 m, a 100 m jump between frames or a root metres under the
floor loads without a NaN but trains to one (velocities of 1e30, a character spawned in the
ground). Each check here is a small pure function that returns the problem as one line naming the
frame and the quantity (the loader adds the file), or None; ``motion_problem`` runs them all on
the neutral form every format is read into (root positions + local rotations), so every format is
held to the same limits.

The limits are generous. Measured over the 97 shared clips (``/work/shared/motions``): 16 to
120 fps; root speed at most 7.9 m/s between frames (``amp_humanoid_run``); root height 0.000 to
1.461 m; the root at most 11.8 m from the origin in x or y; a body turning at most 94.2 rad/s
between frames (``iccgan/roll.json``: a half turn in one frame at 30 fps); quaternion lengths
off 1 by up to 0.42 (DeepMimic); hinge angles up to 2.76 rad; skeleton offsets up to 1.0 m;
DeepMimic frames at most 1.96 times the median frame. Between two frames a rotation changes by
at most pi, so the turning limit only bites above 150 / pi = 48 fps.
"""

from __future__ import annotations

import numbers

import numpy as np

FPS_RANGE = (1.0, 1000.0)
"""Frames per second a clip may have."""
MAX_ROOT_SPEED = 20.0
"""m/s between two frames; sprinters peak near 12 m/s."""
ROOT_HEIGHT_RANGE = (-0.25, 3.0)
"""Root (pelvis) height in metres; the floor is z = 0, a lying body's pelvis is near 0.1 m."""
MAX_ROOT_HORIZONTAL = 1000.0
"""Metres from the origin in x or y (float32 keeps 0.1 mm there)."""
MAX_ANGULAR_SPEED = 150.0
"""rad/s a body turns between frames (about a pitcher's shoulder, the fastest human joint)."""
QUAT_NORM_RANGE = (0.1, 10.0)
"""Length of a stored rotation quaternion before normalising (DeepMimic's are off by up to 0.42)."""
MAX_OFFSET = 10.0
"""Metres of a skeleton offset (a child body from its parent)."""
MAX_HINGE_ANGLE = 2 * np.pi
"""Radians of a 1-DoF hinge angle as a file stores it."""
MAX_DT_RATIO = 4.0
"""How many times longer or shorter than the median a DeepMimic frame may last."""


def real_number(value) -> float | None:
    """``value`` as a float if it is one real number (int, float, numpy scalar or 0-d array; not a
    bool, string or container), else None."""
    if isinstance(value, np.ndarray):
        if value.shape != () or value.dtype.kind not in "iuf":
            return None
        value = value.item()
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        return None
    try:
        return float(value)
    except (OverflowError, ValueError):
        return None


def fps_problem(value) -> str | None:
    """A problem with a frame rate as stored in a file (a real number in ``FPS_RANGE``), or None."""
    f = real_number(value)
    if f is None:
        return f"bad fps {_short(value)} (need a number of frames per second)"
    if not (FPS_RANGE[0] <= f <= FPS_RANGE[1]):  # also NaN
        return f"bad fps {f:g} (need {FPS_RANGE[0]:g} to {FPS_RANGE[1]:g} frames per second)"
    return None


def frame_time_problem(dts: np.ndarray) -> str | None:
    """A problem with DeepMimic per-frame durations ``dts`` [T-1] (each a frame rate in
    ``FPS_RANGE``, none more than ``MAX_DT_RATIO`` off the median), or None."""
    lo, hi = 1.0 / FPS_RANGE[1], 1.0 / FPS_RANGE[0]
    bad = np.argwhere(~((dts >= lo) & (dts <= hi)))
    if bad.size:
        t = int(bad[0][0])
        return f"bad fps: frame {t} lasts {float(dts[t]):g} s (frames last {lo:g} to {hi:g} s)"
    med = float(np.median(dts))
    ratio = np.maximum(dts / med, med / dts)
    if ratio.max() > MAX_DT_RATIO:
        t = int(np.argmax(ratio))
        return (
            f"bad fps: frame {t} lasts {float(dts[t]):g} s but the median frame {med:g} s "
            f"(frames may differ by at most {MAX_DT_RATIO:g}x)"
        )
    return None


def quat_norm_problem(q: np.ndarray, field: str) -> str | None:
    """A quaternion [T, ..., 4] whose length is far from 1 (or zero), or None."""
    m = np.abs(q).max(axis=-1)
    with np.errstate(over="ignore", invalid="ignore"):  # scaled by the largest entry: 1e300 stays finite
        n = m * np.sqrt(np.sum(np.square(q / np.where(m > 0, m, 1.0)[..., None]), axis=-1))
    bad = ~((n >= QUAT_NORM_RANGE[0]) & (n <= QUAT_NORM_RANGE[1]))
    if not bad.any():
        return None
    idx = tuple(int(i) for i in np.argwhere(bad)[0])
    t, length = idx[0], float(n[idx])
    if length < 1e-6:
        return f"zero-length quaternion in {field!r} at frame {t}"
    return f"frame {t}: quaternion in {field!r} has length {length:.3g} (need a unit quaternion)"


def magnitude_problem(a: np.ndarray, limit: float, field: str, unit: str) -> str | None:
    """The first frame of ``a`` [T, ...] with a value beyond ``limit`` in size, or None."""
    bad = np.abs(a).reshape(a.shape[0], -1) > limit
    if not bad.any():
        return None
    t = int(np.argmax(bad.any(axis=1)))
    v = float(a.reshape(a.shape[0], -1)[t][bad[t]][0])
    return f"frame {t}: {field} {v:.4g} {unit} (at most {limit:.4g} {unit} in size)"


def root_position_problem(root_pos: np.ndarray) -> str | None:
    """Root positions [T, 3] far from the origin or from the floor, or None."""
    xy = np.abs(root_pos[:, :2]).max(axis=1)
    if (xy > MAX_ROOT_HORIZONTAL).any():
        t = int(np.argmax(xy > MAX_ROOT_HORIZONTAL))
        return f"frame {t}: root is {xy[t]:.4g} m from the origin (at most {MAX_ROOT_HORIZONTAL:g} m in x and y)"
    z = root_pos[:, 2]
    lo, hi = ROOT_HEIGHT_RANGE
    if (z < lo).any():
        t = int(np.argmax(z < lo))
        return f"frame {t}: root height {z[t]:.4g} m is under the floor (at least {lo:g} m; the floor is z = 0)"
    if (z > hi).any():
        t = int(np.argmax(z > hi))
        return f"frame {t}: root height {z[t]:.4g} m is too high (at most {hi:g} m above the floor)"
    return None


def root_speed_problem(root_pos: np.ndarray, fps: float) -> str | None:
    """A root [T, 3] that moves faster than a body can between two frames, or None."""
    step = np.linalg.norm(np.diff(root_pos, axis=0), axis=-1)
    speed = step * fps
    if not (speed > MAX_ROOT_SPEED).any():
        return None
    t = int(np.argmax(speed > MAX_ROOT_SPEED)) + 1
    return (
        f"frame {t}: root moves {step[t - 1]:.4g} m in one frame ({speed[t - 1]:.4g} m/s; "
        f"a body moves at most {MAX_ROOT_SPEED:g} m/s)"
    )


def angular_speed_problem(local_quat: np.ndarray, fps: float, body_names) -> str | None:
    """A body whose rotation [T, N, 4] (unit wxyz, parent frame; the root's world rotation)
    changes faster than ``MAX_ANGULAR_SPEED`` between two frames, or None."""
    q0, q1 = local_quat[:-1], local_quat[1:]
    dot = np.abs(np.sum(q0 * q1, axis=-1)).clip(0.0, 1.0)
    angle = 2.0 * np.arccos(dot)  # the rotation from one frame to the next, in [0, pi]
    speed = angle * fps
    if not (speed > MAX_ANGULAR_SPEED).any():
        return None
    t, b = (int(i) for i in np.argwhere(speed > MAX_ANGULAR_SPEED)[0])
    return (
        f"frame {t + 1}: {body_names[b]!r} turns {angle[t, b]:.3g} rad in one frame ({speed[t, b]:.4g} rad/s; "
        f"a body turns at most {MAX_ANGULAR_SPEED:g} rad/s)"
    )


def motion_problem(fps: float, root_pos: np.ndarray, local_quat: np.ndarray, body_names) -> str | None:
    """The first implausibility of a parsed clip (fps, root position and speed, body turning
    speed), or None. ``root_pos`` [T, 3] finite, ``local_quat`` [T, N, 4] finite unit wxyz."""
    return (
        fps_problem(fps)
        or root_position_problem(root_pos)
        or root_speed_problem(root_pos, fps)
        or angular_speed_problem(local_quat, fps, body_names)
    )


def _short(value, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (a file's values can be any size)."""
    try:
        r = repr(value)
    except Exception:  # noqa: BLE001 - an int too long to print, a list nested 100000 deep
        r = f"<a {type(value).__name__} too large to show>"
    return r if len(r) <= limit else r[: limit - 3] + "..."
