"""Frame ranges after a clip's path, ``squat.json[0:33,58:]``: Python slices of frame indices.

Each range is ``start:stop`` with either end optional and either end negative (counted from the
end, as in Python): ``[-5:]`` the last five frames, ``[:10]`` the first ten, ``[10:-3]`` all but
the first ten and the last three. Steps (``[::2]``) are not supported: they would change the
frame rate. ``select_frames`` (``clip``) resolves the ranges against a clip's frame count.
"""

from __future__ import annotations

import os
import re

_INT = r"\s*-?\d*\s*"
_RANGE = _INT + ":" + _INT
_FRAMES = re.compile(rf"^(?P<path>.+)\[(?P<ranges>{_RANGE}(?:,{_RANGE})*)\]$")
_BRACKETS = re.compile(r"^(?P<path>.+\.[A-Za-z0-9]+)\[(?P<inside>[^\[\]]*)\]$")

Ranges = tuple[tuple[int, int | None], ...]


def split_frame_ranges(spec: str | os.PathLike) -> tuple[str | os.PathLike, Ranges | None]:
    """``"squat.json[0:33,58:]"`` -> ``("squat.json", ((0, 33), (58, None)))``; ``"a.json[-5:]"``
    -> ``("a.json", ((-5, None),))``; no brackets -> ``(spec, None)``.

    Raises:
        ValueError: brackets after a file name that are not ranges (``a.json[5]``, ``a.json[::2]``).
    """
    m = _FRAMES.match(str(spec))
    if m is None:
        bad = _BRACKETS.match(str(spec))
        if bad is not None:
            raise ValueError(
                f"bad frame range [{bad['inside']}] (Python slices of frame indices, e.g. "
                f"[10:-3], [-5:] or [0:33,58:]; no steps)"
            )
        return spec, None
    ranges = []
    for part in m["ranges"].split(","):
        a, b = (x.strip() for x in part.split(":"))
        ranges.append((int(a) if a else 0, int(b) if b else None))
    return m["path"], tuple(ranges)


def format_ranges(ranges: Ranges) -> str:
    """``((0, 33), (58, None))`` -> ``"0:33,58:"`` (what a clip name and an error show)."""
    return ",".join(f"{a}:{'' if b is None else b}" for a, b in ranges)


def resolve_range(start: int, stop: int | None, n: int) -> tuple[int, int]:
    """One range as frame indices ``[start, stop)`` of a clip of ``n`` frames (negative ends
    count from the end, None = to the end).

    Raises:
        ValueError: an end outside the clip (Python would clip it; a typo here should not pass).
    """
    lo = start + n if start < 0 else start
    hi = n if stop is None else (stop + n if stop < 0 else stop)
    if not (0 <= lo <= n and 0 <= hi <= n):
        raise ValueError(f"frames [{format_ranges(((start, stop),))}] are not within the clip's {n} frames")
    return lo, hi
