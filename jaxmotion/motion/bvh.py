"""Reading BVH motion capture (numpy): the skeleton, the channel values, and joint positions.

A small parser of our own (``bvhio`` 1.5.4 installs cleanly beside the pins, but loops forever on
a truncated file and silently skips channels it does not know, shifting every later value), so
every problem is a ``BvhError`` with one line naming the line or frame and what is wrong.

Conventions handled here:

* **Rotation order, per joint**: the order of a joint's rotation channels is the order of its
  intrinsic Euler rotations, ``Zrotation Xrotation Yrotation`` = R_z R_x R_y (degrees).
* **Translations**: a joint's position channels replace the matching components of its OFFSET
  (usually only the root has them).
* **Axes**: ``up="y"`` (the BVH default, LAFAN1, CMU) turns the file by +90 degrees about x into our
  z-up frame, ``(x, y, z) -> (x, -z, y)``; ``up="z"`` takes it as is.
* **Units**: ``units`` is metres per file unit, or ``"m"``, ``"cm"``, ``"mm"``, ``"inch"``, or
  ``"auto"``: the rest pose's height (extent along the up axis of the joints and end sites) of
  20 or more units is taken as centimetres, else metres (a person is 1-2 m tall).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

CHANNELS = tuple(f"{a}{k}" for k in ("position", "rotation") for a in "XYZ")
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254}
AUTO_CM_HEIGHT = 20.0
"""A rest pose this many file units tall or taller is read as centimetres under ``units="auto"``."""


class BvhError(ValueError):
    """A BVH file could not be parsed; the message is one line (the caller adds the file)."""


@dataclasses.dataclass(frozen=True, eq=False)
class Bvh:
    """A parsed BVH file, in its own units and axes.

    Attributes:
        names: [J] joint names, in file order (a parent before its children).
        parents: [J] parent index, -1 for the root.
        offsets: [J, 3] each joint's OFFSET from its parent.
        end_sites: [J, 3] a joint's End Site offset, NaN where it has none.
        channels: [J] each joint's channel names, in file order.
        frame_time: seconds per frame.
        values: [T, C] the channel values, C = the total number of channels.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    end_sites: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    frame_time: float
    values: np.ndarray

    @property
    def num_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def fps(self) -> float:
        """1 / frame_time, snapped to the nearest integer when within 0.01% of it: files write
        ``Frame Time: 0.0333333``, which is 30 fps, not 30.0000003."""
        fps = 1.0 / self.frame_time
        return float(round(fps)) if abs(fps - round(fps)) < 1e-4 * fps else fps

    def rotation_order(self, j: int) -> str:
        """The joint's rotation channels' axes in order, e.g. ``"ZXY"`` ("" without rotation)."""
        return "".join(c[0] for c in self.channels[j] if c.endswith("rotation"))


class _Tokens:
    """Whitespace tokens of the HIERARCHY part, each with its line number."""

    def __init__(self, lines: list[str]):
        self.items = [(tok, i + 1) for i, line in enumerate(lines) for tok in line.split()]
        self.pos = 0

    def next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise BvhError(f"truncated hierarchy: expected {what} at the end of the file")
        self.pos += 1
        return self.items[self.pos - 1]

    def expect(self, word: str) -> int:
        tok, line = self.next(repr(word))
        if tok != word:
            raise BvhError(f"line {line}: expected {word!r}, found {tok!r}")
        return line

    def numbers(self, n: int, what: str) -> np.ndarray:
        out = []
        for _ in range(n):
            tok, line = self.next(what)
            try:
                out.append(float(tok))
            except ValueError:
                raise BvhError(f"line {line}: {what} holds {tok!r}, not a number") from None
        a = np.array(out)
        if not np.isfinite(a).all():
            raise BvhError(f"line {line}: non-finite {what} {tok!r}")
        return a


def _parse_joint(tk: _Tokens, name: str, parent: int, out: dict) -> None:
    j = len(out["names"])
    if name in out["names"]:
        raise BvhError(f"joint name {name!r} appears twice")
    out["names"].append(name)
    out["parents"].append(parent)
    out["end_sites"].append(np.full(3, np.nan))
    tk.expect("{")
    tk.expect("OFFSET")
    out["offsets"].append(tk.numbers(3, f"OFFSET of {name!r}"))
    line = tk.expect("CHANNELS")
    n = tk.numbers(1, f"channel count of {name!r}")[0]
    if n != int(n) or not 0 <= n <= 6:
        raise BvhError(f"line {line}: joint {name!r} has a channel count of {n:g} (0 to 6 allowed)")
    chans = []
    for _ in range(int(n)):
        tok, line = tk.next(f"a channel name of {name!r}")
        if tok not in CHANNELS:
            raise BvhError(f"line {line}: unknown channel {tok!r} of joint {name!r} (known: {', '.join(CHANNELS)})")
        chans.append(tok)
    if len(set(chans)) != len(chans):
        raise BvhError(f"line {line}: joint {name!r} repeats a channel ({' '.join(chans)})")
    out["channels"].append(tuple(chans))
    while True:
        tok, line = tk.next(f"JOINT, End Site or '}}' in {name!r}")
        if tok == "}":
            return
        if tok == "JOINT":
            child, _ = tk.next("a joint name")
            _parse_joint(tk, child, j, out)
        elif tok == "End":
            tk.expect("Site")
            tk.expect("{")
            tk.expect("OFFSET")
            out["end_sites"][j] = tk.numbers(3, f"End Site OFFSET of {name!r}")
            tk.expect("}")
        else:
            raise BvhError(f"line {line}: expected JOINT, End Site or '}}' in joint {name!r}, found {tok!r}")


def _header_value(line: str, key: str, lineno: int) -> float:
    if not line.startswith(key):
        raise BvhError(f"line {lineno}: expected {key!r}, found {line[:40]!r}")
    text = line[len(key) :].strip()
    try:
        return float(text)
    except ValueError:
        raise BvhError(f"line {lineno}: {key} {text[:40]!r} is not a number") from None


def parse_bvh(text: str) -> Bvh:
    """Parses BVH text.

    Raises:
        BvhError: malformed hierarchy, unknown channel, truncated motion (fewer frames or values
            than the header says), a value that is not a number or not finite, a bad frame time.
    """
    lines = text.splitlines()
    try:
        m = next(i for i, line in enumerate(lines) if line.strip() == "MOTION")
    except StopIteration:
        raise BvhError("no MOTION section (not a BVH file, or truncated in its hierarchy)") from None
    tk = _Tokens(lines[:m])
    tk.expect("HIERARCHY")
    tk.expect("ROOT")
    root, _ = tk.next("the root joint's name")
    out: dict = {"names": [], "parents": [], "offsets": [], "end_sites": [], "channels": []}
    _parse_joint(tk, root, -1, out)
    if tk.pos != len(tk.items):
        tok, line = tk.items[tk.pos]
        raise BvhError(f"line {line}: unexpected {tok!r} after the root joint (one ROOT per file)")
    body = [(i + 1, s.strip()) for i, s in enumerate(lines[m + 1 :], start=m + 1) if s.strip()]
    if len(body) < 2:
        raise BvhError("truncated: the MOTION section has no 'Frames:' and 'Frame Time:' lines")
    n = _header_value(body[0][1], "Frames:", body[0][0])
    dt = _header_value(body[1][1], "Frame Time:", body[1][0])
    if n != int(n) or n < 0:
        raise BvhError(f"line {body[0][0]}: 'Frames: {n:g}' is not a frame count")
    if not (np.isfinite(dt) and dt > 0):
        raise BvhError(f"line {body[1][0]}: Frame Time {dt!r} must be a positive number of seconds")
    rows = body[2:]
    if len(rows) < int(n):
        raise BvhError(f"truncated: the header says {int(n)} frames, the file has {len(rows)}")
    channels = out["channels"]
    width = sum(len(c) for c in channels)
    labels = [f"{name}.{c}" for name, cs in zip(out["names"], channels) for c in cs]
    values = np.empty((int(n), width))
    for t, (lineno, row) in enumerate(rows[: int(n)]):
        parts = row.split()
        if len(parts) != width:
            raise BvhError(f"line {lineno}: frame {t} has {len(parts)} values, the hierarchy's channels are {width}")
        try:
            values[t] = [float(v) for v in parts]
        except ValueError:
            bad = next(v for v in parts if not _is_float(v))
            raise BvhError(f"line {lineno}: frame {t} holds {bad[:20]!r}, not a number") from None
        if not np.isfinite(values[t]).all():
            c = int(np.argmax(~np.isfinite(values[t])))
            raise BvhError(f"line {lineno}: non-finite value {parts[c]!r} at frame {t}, channel {labels[c]}")
    return Bvh(
        names=tuple(out["names"]),
        parents=tuple(out["parents"]),
        offsets=np.array(out["offsets"]),
        end_sites=np.array(out["end_sites"]),
        channels=tuple(channels),
        frame_time=float(dt),
        values=values,
    )


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def read_bvh(path) -> Bvh:
    """``parse_bvh`` of a file (``OSError``/``UnicodeDecodeError`` become ``BvhError``)."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise BvhError(f"unreadable file: {e}") from None
    return parse_bvh(text)


def _to_zup(p: np.ndarray, up: str) -> np.ndarray:
    if up == "z":
        return p
    if up == "y":
        return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)
    raise BvhError(f"up axis {up!r} is not 'y' or 'z'")


def rest_height(bvh: Bvh, up: str) -> float:
    """Extent of the rest pose (OFFSETs only, no motion) along the up axis, in file units."""
    pos = np.zeros((len(bvh.names), 3))
    ends = []
    for j, p in enumerate(bvh.parents):
        pos[j] = bvh.offsets[j] + (pos[p] if p >= 0 else 0.0)
        if np.isfinite(bvh.end_sites[j]).all():
            ends.append(pos[j] + bvh.end_sites[j])
    z = _to_zup(np.concatenate([pos, np.reshape(ends, (-1, 3))]), up)[:, 2]
    return float(np.ptp(z))


def metres_per_unit(bvh: Bvh, units: str | float, up: str) -> float:
    """The scale of ``units`` (see the module docstring); ``"auto"`` judges by ``rest_height``."""
    if isinstance(units, (int, float)) and not isinstance(units, bool):
        if not (np.isfinite(units) and units > 0):
            raise BvhError(f"units {units!r} must be a positive number of metres per file unit")
        return float(units)
    if units == "auto":
        return UNITS["cm"] if rest_height(bvh, up) >= AUTO_CM_HEIGHT else UNITS["m"]
    if units not in UNITS:
        raise BvhError(f"units {units!r}: expected auto, {', '.join(UNITS)} or metres per unit")
    return UNITS[units]


def joint_positions(bvh: Bvh, scale: float, up: str) -> np.ndarray:
    """[T, J, 3] world joint positions in metres, z-up (forward kinematics of the channels)."""
    T, J = bvh.num_frames, len(bvh.names)
    col = 0
    rots: list[Rotation] = []
    pos = np.empty((T, J, 3))
    for j, chans in enumerate(bvh.channels):
        local_t = np.broadcast_to(bvh.offsets[j], (T, 3)).copy()
        angles, order = [], ""
        for c in chans:
            v = bvh.values[:, col]
            col += 1
            if c.endswith("position"):
                local_t[:, "XYZ".index(c[0])] = v
            else:
                angles.append(v)
                order += c[0]
        local_r = Rotation.from_euler(order, np.stack(angles, -1), degrees=True) if order else Rotation.identity(T)
        p = bvh.parents[j]
        if p < 0:
            rots.append(local_r)
            pos[:, j] = local_t
        else:
            rots.append(rots[p] * local_r)
            pos[:, j] = pos[:, p] + rots[p].apply(local_t)
    return _to_zup(pos * scale, up)
