"""Reading motion files (CompositeMotion JSON, DeepMimic txt, poselib npy) into ``Clip``s.

Each file is read into one neutral form (root trajectory + local wxyz rotation of every body +
the skeleton offsets to check against), converted to hinge angles by Euler decomposition (in hinge chain order) of
each body's local rotation (1-DoF knees/elbows: the twist angle about their hinge axis; among
the equivalent Euler solutions the one that best respects the joint ranges, see ``convert``),
and then MuJoCo forward kinematics gives the body poses (``clip.build_clip``). ``fk_error_m``
compares those MuJoCo body positions with positions composed directly from the file's own
rotations and skeleton offsets (the character's offsets for JSON, ``local_translation`` for npy).

DeepMimic files give per-frame durations; when they are not all equal (``humanoid3d_roll`` has
one double-length frame) the clip is resampled onto a uniform grid at the median frame rate.

Any problem with the input raises ``MotionFileError`` naming the file and the problem: malformed
or wrongly typed values (a bool is not a number), NaN/inf, and finite values no body can have
(``plausibility``: fps outside 1-1000, a root jumping 100 m between frames or under the floor, ...).
poselib ``.npy`` files are unpickled by ``safe_pickle``, which refuses every global but numpy's
array reconstructors and plain containers, so a clip cannot run code.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from collections.abc import Iterable

import numpy as np

from jaxmotion.motion.data import resolve
from jaxmotion.motion.errors import MotionFileError
from jaxmotion.motion import plausibility as plaus
from jaxmotion.motion import rotations as rot
from jaxmotion.motion.clip import Clip, build_clip, select_frames
from jaxmotion.motion.convert import local_quats_to_dof, reference_body_pos
from jaxmotion.motion.retarget import retarget_file
from jaxmotion.motion.frame_ranges import Ranges, format_ranges, split_frame_ranges
from jaxmotion.motion.safe_pickle import NotPickledObject, RefusedPickle, load_pickled_npy
from jaxmotion.physics.character import Character
from jaxmotion.physics.character import character as _character

MOTION_SUFFIXES = (".json", ".txt", ".npy", ".bvh")

# DeepMimic humanoid3d frame: dt, root pos(3), root rot(4), then these (name, width) in order.
_DEEPMIMIC_LAYOUT = (
    ("torso", 4),
    ("head", 4),
    ("right_thigh", 4),
    ("right_shin", 1),
    ("right_foot", 4),
    ("right_upper_arm", 4),
    ("right_lower_arm", 1),
    ("left_thigh", 4),
    ("left_shin", 1),
    ("left_foot", 4),
    ("left_upper_arm", 4),
    ("left_lower_arm", 1),
)
_DEEPMIMIC_WIDTH = 8 + sum(w for _, w in _DEEPMIMIC_LAYOUT)  # 44
# y-up -> z-up: +90 degrees about x, p' = (x, -z, y).
_YUP_TO_ZUP = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])


@dataclasses.dataclass
class _Raw:
    """A parsed file before conversion: T frames, N bodies in the character's order."""

    format: str
    fps: float
    loop: bool
    sword_shield: bool
    root_pos: np.ndarray  # [T, 3]
    local_quat: np.ndarray  # [T, N, 4] wxyz; index 0 is the root's world rotation
    offsets: np.ndarray  # [N, 3] child offsets in the parent frame (the file's skeleton)


# ----------------------------------------------------------------------------- validation


def _first_bad_frame(a: np.ndarray) -> int:
    bad = ~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
    return int(np.argmax(bad)) if bad.any() else -1


def _check_finite(path, a: np.ndarray, field: str) -> None:
    t = _first_bad_frame(a)
    if t >= 0:
        raise MotionFileError(path, f"non-finite value (NaN/inf) in {field!r} at frame {t}")


def _check_fps(path, fps) -> float:
    """A file's frame rate as a float: a real number (not a bool or string) in ``plausibility.FPS_RANGE``."""
    problem = plaus.fps_problem(fps)
    if problem:
        raise MotionFileError(path, problem)
    return float(plaus.real_number(fps))


def _check_frames(path, n: int) -> None:
    if n < 2:
        raise MotionFileError(path, f"too few frames ({n}; need at least 2)")


def _unit_quats(path, q: np.ndarray, field: str) -> np.ndarray:
    """Validates [T, ..., 4] quaternions (finite, length near 1) and normalises them."""
    _check_finite(path, q, field)
    problem = plaus.quat_norm_problem(q, field)
    if problem:
        raise MotionFileError(path, problem)
    return q / np.linalg.norm(q, axis=-1)[..., None]


def _xyzw_to_wxyz(q: np.ndarray) -> np.ndarray:
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


# ----------------------------------------------------------------------------- readers


def _non_number(value) -> object:
    """The first leaf of nested lists/arrays that is not a real number (a bool, string, None, dict
    or non-numeric array), a container met twice (a pickle can share or nest a list in itself),
    or ``_NUMBERS_OK``. Iterative: a file's nesting can be any depth."""
    stack, seen = [value], set()
    while stack:
        v = stack.pop()
        if isinstance(v, (list, tuple)):
            if id(v) in seen:
                return v
            seen.add(id(v))
            stack.extend(v)
        elif isinstance(v, np.ndarray):
            if v.dtype.kind not in "iuf":
                return v
        elif isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
            return v
    return _NUMBERS_OK


_NUMBERS_OK = object()


def _as_array(path, value, shape_tail: tuple[int, ...], field: str) -> np.ndarray:
    """``value`` as a float64 array [T, *shape_tail]: only real numbers (no bools, strings or
    nulls, which numpy would silently convert), finite, in that shape."""
    shape = f"[{', '.join(['T', *map(str, shape_tail)])}]"
    bad = _non_number(value)
    if bad is not _NUMBERS_OK:
        if isinstance(bad, np.ndarray):
            what = f"an array of {bad.dtype}"
        elif isinstance(bad, (list, tuple)):
            what = "a list nested in itself (or one list twice)"
        else:
            what = plaus._short(bad, 40)
        raise MotionFileError(path, f"{field!r} holds {what}, not a number")
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise MotionFileError(path, f"{field!r} is not a numeric array of shape {shape}") from None
    if a.ndim != 1 + len(shape_tail) or a.shape[1:] != shape_tail:
        raise MotionFileError(path, f"{field!r} has shape {a.shape}, expected {shape}")
    return a


def _read_compositemotion(path, d: dict) -> _Raw:
    """CompositeMotion JSON, both layouts (``pelvis: [pos, quat]`` or ``base_position``)."""
    ch = _character(False)
    frames = d.get("frames")
    if not isinstance(frames, list):
        raise MotionFileError(path, "'frames' must be a list of per-frame objects")
    _check_frames(path, len(frames))
    fps = _check_fps(path, d.get("fps"))
    for t, f in enumerate(frames):
        if not isinstance(f, dict):
            raise MotionFileError(path, f"frame {t} is not an object of body -> rotation")
    old = "base_position" in frames[0]
    expected = set(ch.body_names) | ({"base_position"} if old else set())
    for t, f in enumerate(frames):
        missing = [b for b in ch.body_names if b not in f]
        if old and "base_position" not in f:
            missing.insert(0, "base_position")
        if missing:
            raise MotionFileError(
                path, f"missing body {missing[0]!r} in frame {t} (the character's bodies are {list(ch.body_names)})"
            )
        extra = sorted(set(f) - expected)
        if extra:
            raise MotionFileError(
                path,
                f"unknown body {extra[0]!r} in frame {t}: wrong skeleton "
                f"(the character's bodies are {list(ch.body_names)})",
            )
    if old:
        root_pos = _as_array(path, [f["base_position"] for f in frames], (3,), "base_position")
        root_q = _as_array(path, [f["pelvis"] for f in frames], (4,), "pelvis")
    else:
        try:
            pos_q = [(f["pelvis"][0], f["pelvis"][1]) for f in frames]
        except (TypeError, IndexError, KeyError):
            raise MotionFileError(path, "'pelvis' must be [[x, y, z], [qx, qy, qz, qw]]") from None
        root_pos = _as_array(path, [p for p, _ in pos_q], (3,), "pelvis position")
        root_q = _as_array(path, [q for _, q in pos_q], (4,), "pelvis")
    _check_finite(path, root_pos, "pelvis position" if not old else "base_position")
    quats = [root_q] + [_as_array(path, [f[b] for f in frames], (4,), b) for b in ch.body_names[1:]]
    local = np.stack([_unit_quats(path, q, b) for q, b in zip(quats, ch.body_names)], axis=1)
    return _Raw("compositemotion_json", fps, False, False, root_pos, _xyzw_to_wxyz(local), ch.body_offsets.copy())


def _yup_to_zup_quat(q: np.ndarray) -> np.ndarray:
    r = np.broadcast_to(_YUP_TO_ZUP, q.shape)
    return rot.quat_mul(rot.quat_mul(r, q), rot.quat_conj(r))


def _read_deepmimic(path, d: dict) -> _Raw:
    """DeepMimic humanoid3d motion (y-up, wxyz, scalar knees/elbows about local z)."""
    ch = _character(False)
    frames = d.get("Frames")
    if not isinstance(frames, list):
        raise MotionFileError(path, "'Frames' must be a list of frames")
    _check_frames(path, len(frames))
    widths = {len(f) if isinstance(f, list) else -1 for f in frames}
    if widths != {_DEEPMIMIC_WIDTH}:
        raise MotionFileError(
            path,
            f"each frame must be a list of {_DEEPMIMIC_WIDTH} numbers "
            f"(humanoid3d), got lengths {sorted(widths)}: wrong skeleton",
        )
    a = _as_array(path, frames, (_DEEPMIMIC_WIDTH,), "Frames")
    dts = a[:-1, 0]
    problem = plaus.frame_time_problem(dts)  # also NaN; a frame of 1e6 s would resample to millions
    if problem:
        raise MotionFileError(path, problem)
    _check_finite(path, a[:, 1:4], "root position")
    p = a[:, 1:4]
    root_pos = np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=-1)
    T = a.shape[0]
    local = np.zeros((T, ch.num_bodies, 4))
    local[..., 0] = 1.0
    local[:, 0] = _yup_to_zup_quat(_unit_quats(path, a[:, 4:8], "root rotation"))
    col = 8
    for name, w in _DEEPMIMIC_LAYOUT:
        b = ch.body_index(name)
        v = a[:, col : col + w]
        if w == 4:
            local[:, b] = _yup_to_zup_quat(_unit_quats(path, v, name))
        else:  # A revolute angle about local z (y-up) is -theta about the z-up y axis.
            _check_finite(path, v, name)
            problem = plaus.magnitude_problem(v, plaus.MAX_HINGE_ANGLE, f"{name!r} angle", "rad")
            if problem:
                raise MotionFileError(path, problem)
            theta = -v[:, 0]
            local[:, b] = np.stack([np.cos(theta / 2), 0 * theta, np.sin(theta / 2), 0 * theta], -1)
        col += w
    if np.ptp(dts) <= 1e-6 * np.mean(dts):
        fps = _check_fps(path, 1.0 / float(np.mean(dts)))
    else:  # Per-frame durations differ (humanoid3d_roll has one double-length frame): resample.
        fps = _check_fps(path, 1.0 / float(np.median(dts)))
        root_pos, local = resample_uniform(np.concatenate([[0.0], np.cumsum(dts)]), root_pos, local, fps)
    loop = d.get("Loop", "none")
    return _Raw("deepmimic_txt", fps, loop == "wrap", False, root_pos, local, ch.body_offsets.copy())


def resample_uniform(
    times: np.ndarray, root_pos: np.ndarray, local_quat: np.ndarray, fps: float
) -> tuple[np.ndarray, np.ndarray]:
    """Resamples frames at arbitrary increasing times onto the grid k / fps (lerp / slerp).

    Args:
        times: [T] increasing frame times, times[0] = 0.
        root_pos: [T, 3].
        local_quat: [T, nb, 4] wxyz.
        fps: output rate.

    Returns:
        (root_pos [T', 3], local_quat [T', nb, 4]) with T' = round(times[-1] * fps) + 1.
    """
    tn = np.minimum(np.arange(int(round(times[-1] * fps)) + 1) / fps, times[-1])
    i0 = np.clip(np.searchsorted(times, tn, side="right") - 1, 0, len(times) - 2)
    a = (tn - times[i0]) / (times[i0 + 1] - times[i0])
    pos = root_pos[i0] + a[:, None] * (root_pos[i0 + 1] - root_pos[i0])
    t_q = np.broadcast_to(a[:, None], (len(a), local_quat.shape[1]))
    return pos, rot.slerp(local_quat[i0], local_quat[i0 + 1], t_q)


def _npy_field(path, d: dict, key: str):
    if key not in d:
        raise MotionFileError(path, f"missing field {key!r} (not a poselib SkeletonMotion)")
    v = d[key]
    return v["arr"] if isinstance(v, dict) and "arr" in v else v


def _read_npy_dict(path) -> dict:
    """The pickled dict of a poselib ``.npy``, through ``safe_pickle`` (no code runs)."""
    try:
        d = load_pickled_npy(path)
    except RefusedPickle as e:
        raise MotionFileError(path, str(e)) from None
    except NotPickledObject as e:
        raise MotionFileError(path, f"not a poselib SkeletonMotion (expected a pickled dict; found {e})") from None
    except Exception as e:  # noqa: BLE001 - any reader failure (truncated, garbage) is a bad file
        raise MotionFileError(path, f"unreadable .npy file ({type(e).__name__}: {e})") from None
    if not isinstance(d, dict):
        found = type(d).__name__
        raise MotionFileError(path, f"not a poselib SkeletonMotion (expected a pickled dict; found a {found})")
    return d


def _node_names(path, tree: dict) -> list[str]:
    names = _npy_field(path, tree, "node_names")
    if not (isinstance(names, (list, tuple)) and all(isinstance(n, str) for n in names)):
        raise MotionFileError(path, f"'node_names' must be a list of body names, not {plaus._short(names)}")
    return list(names)


def _read_poselib(path, character_hint: Character | None) -> _Raw:
    """poselib ``SkeletonMotion`` saved with ``np.save`` (a pickled dict of numpy arrays), read
    by the restricted unpickler of ``safe_pickle``: a file that names any other callable is refused."""
    d = _read_npy_dict(path)
    if d.get("is_local", True) is not True:
        found = plaus._short(d.get("is_local"), 40)
        raise MotionFileError(path, f"is_local is {found}: only local rotations (is_local=True) are supported")
    tree = _npy_field(path, d, "skeleton_tree")
    if not isinstance(tree, dict):
        raise MotionFileError(path, "'skeleton_tree' is not a dict")
    names = _node_names(path, tree)
    parents = _as_array(path, _npy_field(path, tree, "parent_indices"), (), "parent_indices")
    _check_finite(path, parents, "parent_indices")
    parents = parents.astype(np.int64).tolist()
    offsets = _as_array(path, _npy_field(path, tree, "local_translation"), (3,), "local_translation")
    ss = len(names) == 17 if character_hint is None else character_hint.sword_shield
    ch = _character(ss)
    if tuple(names) != ch.body_names or tuple(parents) != ch.parents:
        raise MotionFileError(
            path,
            f"wrong skeleton: the file has {len(names)} nodes {plaus._short(names, 200)} with parents "
            f"{plaus._short(parents, 100)}, but the {'sword-shield ' if ss else ''}character has "
            f"{ch.num_bodies} bodies {list(ch.body_names)} with parents {list(ch.parents)}",
        )
    N = len(names)
    rotation = _as_array(path, _npy_field(path, d, "rotation"), (N, 4), "rotation")
    root_pos = _as_array(path, _npy_field(path, d, "root_translation"), (3,), "root_translation")
    _check_frames(path, rotation.shape[0])
    if root_pos.shape[0] != rotation.shape[0]:
        raise MotionFileError(
            path, f"'root_translation' has {root_pos.shape[0]} frames but 'rotation' has {rotation.shape[0]}"
        )
    fps = _check_fps(path, d.get("fps"))
    _check_finite(path, root_pos, "root_translation")
    _check_finite(path, offsets, "local_translation")
    problem = plaus.magnitude_problem(offsets[None], plaus.MAX_OFFSET, "skeleton offset", "m")
    if problem:
        raise MotionFileError(path, problem.removeprefix("frame 0: "))
    local = np.stack([_unit_quats(path, rotation[:, b], f"rotation[{n}]") for b, n in enumerate(names)], axis=1)
    return _Raw("poselib_npy", fps, False, ss, root_pos, _xyzw_to_wxyz(local), offsets)


def _read_json(path) -> dict:
    try:
        with open(path) as f:
            d = json.load(f)
    except (OSError, UnicodeDecodeError) as e:
        raise MotionFileError(path, f"unreadable file: {e}") from None
    except json.JSONDecodeError as e:
        raise MotionFileError(path, f"malformed JSON: {e}") from None
    except (ValueError, RecursionError) as e:  # an int of 5000 digits, [[[[...]]]] nested 100000 deep
        raise MotionFileError(path, f"malformed JSON: {type(e).__name__}: {e}") from None
    if not isinstance(d, dict):
        raise MotionFileError(path, "expected a JSON object with 'frames' or 'Frames'")
    return d


# ----------------------------------------------------------------------------- conversion


def _to_clip(path: Path, raw: _Raw, ch: Character) -> Clip:
    dof = local_quats_to_dof(ch, raw.local_quat)
    clip = build_clip(
        name=path.stem,
        path=str(path),
        format=raw.format,
        fps=raw.fps,
        loop=raw.loop,
        sword_shield=ch.sword_shield,
        root_pos=raw.root_pos,
        root_quat=raw.local_quat[:, 0],
        dof_pos=dof,
    )
    ref = reference_body_pos(ch.parents, raw.offsets, raw.root_pos, raw.local_quat)
    err = float(np.linalg.norm(ref - clip.body_pos, axis=-1).max())
    return dataclasses.replace(clip, fk_error_m=err)


def load_clip(path: str | os.PathLike, character: Character | None = None) -> Clip:
    """Loads one motion file.

    The format comes from the extension and content: ``.npy`` poselib SkeletonMotion; ``.json`` /
    ``.txt`` with ``"frames"`` (CompositeMotion, both layouts) or ``"Frames"`` (DeepMimic); ``.bvh``
    motion capture, retargeted onto the humanoid with the first packaged skeleton mapping that
    covers its joints (``retarget.retarget_file``; docs/bvh.md).

    Args:
        path: file path, absolute or relative to ``$JAXMOTION_DATA`` (see ``jaxmotion.motion.data``).
        character: the character to load onto; None = auto (poselib with 17 nodes -> sword-shield,
            everything else -> the 15-body humanoid). A file whose skeleton does not match -> error.

    Returns:
        The clip.

    Raises:
        MotionFileError: unreadable or malformed file, missing/unknown body, NaN/inf values, bad
            fps, wrong skeleton, fewer than 2 frames.
    """
    p = resolve(path)
    if not p.is_file():
        raise MotionFileError(p, "no such file")
    if p.suffix.lower() == ".bvh":
        if character is not None and character.sword_shield:
            raise MotionFileError(
                p, "a BVH is retargeted onto the 15-body humanoid only, not the sword-shield character"
            )
        return retarget_file(p)[0]
    try:
        raw = _read_raw(p, character)
        return _to_clip(p, raw, character or _character(raw.sword_shield))
    except MotionFileError:
        raise
    except Exception as e:  # noqa: BLE001 - never let a deep numpy error escape for bad input
        raise MotionFileError(p, f"could not read motion ({type(e).__name__}: {e})") from None


def _read_raw(p: Path, character: Character | None) -> _Raw:
    """Parses a file by suffix and layout, then checks it fits ``character`` and is a motion a
    body can make (``plausibility.motion_problem``)."""
    suffix = p.suffix.lower()
    if suffix == ".npy":
        raw = _read_poselib(p, character)
    elif suffix in (".json", ".txt"):
        d = _read_json(p)
        if "frames" in d:
            raw = _read_compositemotion(p, d)
        elif "Frames" in d:
            raw = _read_deepmimic(p, d)
        else:
            raise MotionFileError(p, "unknown JSON motion layout (no 'frames' or 'Frames' key)")
    else:
        raise MotionFileError(p, f"unsupported file type {suffix!r} (expected one of {', '.join(MOTION_SUFFIXES)})")
    if character is not None and character.sword_shield != raw.sword_shield:
        n = 17 if raw.sword_shield else 15
        raise MotionFileError(
            p,
            f"wrong skeleton: the file has the {n}-body skeleton, but a "
            f"{character.num_bodies}-body character was requested",
        )
    names = _character(raw.sword_shield).body_names
    problem = plaus.motion_problem(raw.fps, raw.root_pos, raw.local_quat, names)
    if problem:
        raise MotionFileError(p, problem)
    return raw


def _is_motion_file(p: Path) -> bool:
    """For folder scans: motion suffix, and a .txt must look like JSON (skips LICENSE/README.txt)."""
    if p.suffix.lower() not in MOTION_SUFFIXES or p.name.startswith("."):
        return False
    if p.suffix.lower() == ".txt":
        try:
            with open(p, "rb") as f:
                head = f.read(256).lstrip()
        except OSError:
            return True
        return head.startswith(b"{")
    return True


def find_motion_files(paths: str | os.PathLike | Iterable[str | os.PathLike]) -> list[Path]:
    """Expands files and folders (recursively, sorted) into motion file paths.

    Args:
        paths: a path or a list of paths (files are kept as given, even with other suffixes, so
            that loading reports them; folders are scanned for .json, .npy and JSON-like .txt).

    Returns:
        The file paths, in the given order with each folder's files sorted.

    Raises:
        MotionFileError: a path that does not exist, or a folder without motion files.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    out: list[Path] = []
    for item in paths:
        p = resolve(item)
        if p.is_dir():
            found = sorted(f for f in p.rglob("*") if f.is_file() and _is_motion_file(f))
            if not found:
                raise MotionFileError(p, f"no motion files ({', '.join(MOTION_SUFFIXES)}) in folder")
            out += found
        elif p.exists():
            out.append(p)
        else:
            raise MotionFileError(p, "no such file or folder")
    return out


def find_clip_specs(item: str | os.PathLike) -> list[tuple[Path, Ranges | None]]:
    """One command-line or config entry -> its clip files, each with its frame ranges (a file
    named ``path[start:stop,...]``, see ``frame_ranges``) or None (a plain file or a folder).

    Raises:
        MotionFileError: a path that does not exist, a folder without clips, bad range syntax.
    """
    if resolve(item).exists():  # a file whose own name ends in brackets
        return [(p, None) for p in find_motion_files([item])]
    try:
        path, ranges = split_frame_ranges(item)
    except ValueError as e:
        raise MotionFileError(item, str(e)) from None
    if ranges is None:
        return [(p, None) for p in find_motion_files([item])]
    if resolve(path).is_dir():
        raise MotionFileError(resolve(path), f"frame ranges [{format_ranges(ranges)}] need one file, not a folder")
    return [(resolve(path), ranges)]


def load_clip_frames(path: str | os.PathLike, ranges: Ranges | None, character: Character | None = None) -> Clip:
    """``load_clip``, then only the frames of ``ranges`` (None = all) joined (``clip.select_frames``)."""
    clip = load_clip(path, character)
    if ranges is None:
        return clip
    try:
        return select_frames(clip, ranges)
    except ValueError as e:
        raise MotionFileError(resolve(path), str(e)) from None


def load_clips(
    paths: str | os.PathLike | Iterable[str | os.PathLike], character: Character | None = None
) -> list[Clip]:
    """Loads files and folders (recursively, sorted) of motion files; see ``load_clip``.

    A file may name frame ranges, ``path[start:stop,...]`` (frame indices, Python slices, ends may
    be negative: ``[-5:]``, ``[10:-3]``): only those frames, joined into one clip
    (``clip.select_frames``), e.g. a squat without its bounce. Fewer than 2 frames is an error.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    return [load_clip_frames(p, ranges, character) for item in paths for p, ranges in find_clip_specs(item)]
