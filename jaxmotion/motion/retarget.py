"""Retargeting BVH motion capture onto the character: mapping files, inverse kinematics, the floor.

A BVH skeleton is not our character, so a BVH clip becomes a ``Clip`` in four steps:

1. **Mapping** (``skeletons/<name>.json``): BVH joint name -> character body, optionally a point
   in the body's frame (``offset``, metres, e.g. the toes on the foot) and a ``weight``; with the
   file's usual ``up`` axis and ``units`` (see ``bvh``).
2. **Height scale**: the BVH joint positions (metres, z-up) are scaled about the origin by the
   ratio of the character's leg length (hip-knee plus knee-ankle) to the BVH's, measured on the
   mapped thigh, shin and foot joints (median over frames, both legs).
3. **Inverse kinematics**, frame by frame: damped least squares on the mapped points' positions
   (MuJoCo ``mj_jac``), warm-started from the previous frame's solution; hinge angles are kept in
   their joint ranges (a joint at a limit whose step would leave the range is frozen for that step
   and the others re-solved). A joint is reported *clamped* in a frame where it ends at a limit.
4. **Floor**: the clip is lowered or raised so that the lowest foot point (``level.sole_points``)
   is at z = 0 at its 5th percentile over frames (the frames the feet stand on), then every frame
   whose feet would still be inside the floor is raised out of it.

The report gives the position error per frame (mean and max over the mapped points, mm), against
the scaled BVH positions moved by the same vertical shift as the whole clip in step 4 (so a
frame raised out of the floor counts its lift as error).
"""

from __future__ import annotations

import dataclasses
import json
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from jaxmotion.motion import bvh as bvh_mod
from jaxmotion.motion import plausibility as plaus
from jaxmotion.motion import rotations as rot
from jaxmotion.motion.clip import Clip, _model, build_clip
from jaxmotion.motion.errors import MotionFileError
from jaxmotion.motion.frame_ranges import format_ranges
from jaxmotion.motion.level import sole_points
from jaxmotion.physics.character import character

FLOOR_PERCENTILE = 5.0
"""Percentile over frames of the lowest foot point that is put at z = 0."""
LEGS = (("left_thigh", "left_shin", "left_foot"), ("right_thigh", "right_shin", "right_foot"))


@dataclasses.dataclass(frozen=True)
class Target:
    """One mapped point: BVH joint -> a point (``offset`` in the body frame, m) on a character body."""

    joint: str
    body: str
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    weight: float = 1.0


@dataclasses.dataclass(frozen=True)
class Mapping:
    name: str
    targets: tuple[Target, ...]
    up: str = "y"
    units: str | float = "auto"

    @property
    def joints(self) -> tuple[str, ...]:
        return tuple(t.joint for t in self.targets)


def skeleton_names() -> list[str]:
    """The packaged mappings (``jaxmotion/motion/skeletons/*.json``)."""
    folder = resources.files("jaxmotion.motion") / "skeletons"
    return sorted(p.name.removesuffix(".json") for p in folder.iterdir() if p.name.endswith(".json"))


def _target(joint: str, v) -> Target:
    bodies = character(False).body_names
    if isinstance(v, str):
        v = {"body": v}
    if not isinstance(v, dict) or v.get("body") not in bodies:
        raise ValueError(f"joint {joint!r} maps to {v!r}: need a body name of {list(bodies)} or {{'body': ...}}")
    off = tuple(float(x) for x in v.get("offset", (0.0, 0.0, 0.0)))
    w = float(v.get("weight", 1.0))
    if len(off) != 3 or not np.isfinite(off).all() or not (np.isfinite(w) and w > 0):
        raise ValueError(f"joint {joint!r}: offset must be 3 finite numbers and weight a positive number")
    return Target(joint, v["body"], off, w)


def load_mapping(name_or_path: str) -> Mapping:
    """A packaged mapping by name (``lafan1``, ``cmu``, ``humanoid``) or a JSON file of the same form.

    Raises:
        MotionFileError: no such mapping, or a malformed one.
    """
    if name_or_path in skeleton_names():
        path = resources.files("jaxmotion.motion") / "skeletons" / f"{name_or_path}.json"
        name = name_or_path
    else:
        path, name = Path(name_or_path), Path(name_or_path).stem
        if not path.is_file():
            raise MotionFileError(path, f"no such skeleton mapping (packaged: {', '.join(skeleton_names())})")
    try:
        d = json.loads(path.read_text())
        joints = d["joints"]
        targets = tuple(_target(j, v) for j, v in joints.items())
        at_origin = {t.body for t in targets if t.offset == (0.0, 0.0, 0.0)}
        if not {b for leg in LEGS for b in leg} <= at_origin:
            legs = [b for leg in LEGS for b in leg]
            raise ValueError(f"the mapping must map a joint to each of the legs' bodies {legs}")
        return Mapping(name, targets, d.get("up", "y"), d.get("units", "auto"))
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise MotionFileError(path, f"bad skeleton mapping: {type(e).__name__}: {e}") from None


def guess_mapping(bvh: bvh_mod.Bvh) -> Mapping | None:
    """The first packaged mapping whose joints the BVH has (None if no mapping covers it)."""
    for name in skeleton_names():
        m = load_mapping(name)
        if set(m.joints) <= set(bvh.names):
            return m
    return None


@dataclasses.dataclass(frozen=True, eq=False)
class RetargetReport:
    """What retargeting did. ``error_mm``: [T] per frame, the mean over mapped points of the
    distance from each point to its (scaled) BVH target; ``max_error_mm``: [T] the worst point.
    ``clamped``: joint name -> the frames (ranges) where it ends at a joint limit."""

    skeleton: str
    bvh_joints: int
    frames: int
    fps: float
    metres_per_unit: float
    height_scale: float
    error_mm: np.ndarray
    max_error_mm: np.ndarray
    clamped: dict[str, tuple[tuple[int, int], ...]]
    clamped_frames: int

    def summary(self) -> str:
        clamped = ", ".join(f"{j} [{format_ranges(r)}]" for j, r in self.clamped.items())
        return (
            f"skeleton {self.skeleton} ({self.bvh_joints} joints, {self.metres_per_unit:g} m/unit, height scale "
            f"{self.height_scale:.3f}), {self.frames} frames at {self.fps:g} fps; position error mean "
            f"{self.error_mm.mean():.1f} mm, max {self.max_error_mm.max():.1f} mm; "
            f"{self.clamped_frames} frames with a joint at its limit" + (f": {clamped}" if clamped else "")
        )


def _leg_length(p: np.ndarray, idx: dict[str, int]) -> float:
    """Median over frames and both legs of hip-knee + knee-ankle; p [T, K, 3]."""
    out = []
    for hip, knee, ankle in LEGS:
        a, b, c = p[:, idx[hip]], p[:, idx[knee]], p[:, idx[ankle]]
        out.append(np.linalg.norm(b - a, axis=-1) + np.linalg.norm(c - b, axis=-1))
    return float(np.median(np.concatenate(out)))


def _character_leg_length() -> float:
    ch = character(False)
    hip, knee, ankle = LEGS[0]
    return float(
        np.linalg.norm(ch.body_offsets[ch.body_index(knee)]) + np.linalg.norm(ch.body_offsets[ch.body_index(ankle)])
    )


def _initial_root(targets: np.ndarray, idx: dict[str, int]) -> tuple[np.ndarray, np.ndarray]:
    """Root position and orientation that face the first frame: y from the right to the left hip,
    z up (from the pelvis to the torso when mapped), x = y cross z."""
    left, right = targets[idx["left_thigh"]], targets[idx["right_thigh"]]
    pos = targets[idx["pelvis"]] if "pelvis" in idx else 0.5 * (left + right)
    y = left - right
    z = targets[idx["torso"]] - pos if "torso" in idx else np.array([0.0, 0.0, 1.0])
    y = y / max(np.linalg.norm(y), 1e-9)
    z = z - y * (z @ y)
    z = z / max(np.linalg.norm(z), 1e-9)
    mat = np.stack([np.cross(y, z), y, z], axis=-1)
    return pos, rot.mat_to_quat(mat)


@dataclasses.dataclass(frozen=True)
class IkSettings:
    iterations_first: int = 100
    iterations: int = 20
    damping: float = 1e-4
    tolerance: float = 1e-6


def _ik_frame(m, d, qpos, bodies, offsets, weights, target, lo, hi, iters, s: IkSettings) -> np.ndarray:
    """Damped least squares on the points' positions, hinges kept in [lo, hi]; qpos updated in place."""
    nv = m.nv
    jac = np.zeros((3, nv))
    J = np.zeros((3 * len(bodies), nv))
    for _ in range(iters):
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        pts = d.xpos[bodies] + np.einsum("kij,kj->ki", d.xmat[bodies].reshape(-1, 3, 3), offsets)
        err = ((target - pts) * weights[:, None]).ravel()
        for k, b in enumerate(bodies):
            mujoco.mj_jac(m, d, jac, None, pts[k], b)
            J[3 * k : 3 * k + 3] = jac * weights[k]
        free = np.ones(nv, bool)
        for _pass in range(2):
            Jf = J * free
            dq = np.linalg.solve(Jf.T @ Jf + s.damping * np.eye(nv), Jf.T @ err) * free
            q = qpos[7:]
            out = ((q <= lo + 1e-9) & (dq[6:] < 0)) | ((q >= hi - 1e-9) & (dq[6:] > 0))
            if not out.any():
                break
            free[6:] &= ~out
        mujoco.mj_integratePos(m, qpos, dq, 1.0)
        qpos[7:] = np.clip(qpos[7:], lo, hi)
        if np.linalg.norm(dq) < s.tolerance:
            break
    return qpos


def solve_ik(targets: np.ndarray, mapping: Mapping, settings: IkSettings = IkSettings()) -> np.ndarray:
    """[T, 7 + n_dof] qpos whose mapped points best reach ``targets`` [T, K, 3] (see the module)."""
    ch = character(False)
    m = _model(False)
    d = mujoco.MjData(m)
    bodies = np.array([ch.body_index(t.body) + 1 for t in mapping.targets])
    offsets = np.array([t.offset for t in mapping.targets])
    weights = np.array([t.weight for t in mapping.targets])
    lo, hi = ch.joint_range[:, 0], ch.joint_range[:, 1]
    idx = {t.body: k for k, t in enumerate(mapping.targets) if t.offset == (0.0, 0.0, 0.0)}
    qpos = np.zeros(m.nq)
    qpos[:3], qpos[3:7] = _initial_root(targets[0], idx)
    qpos[7:] = np.clip(0.0, lo, hi)
    out = np.empty((targets.shape[0], m.nq))
    for t in range(targets.shape[0]):
        iters = settings.iterations_first if t == 0 else settings.iterations
        out[t] = _ik_frame(m, d, qpos, bodies, offsets, weights, targets[t], lo, hi, iters, settings)
    return out


def mapped_points(qpos: np.ndarray, mapping: Mapping) -> np.ndarray:
    """[T, K, 3] the mapped points of the character posed by ``qpos``."""
    ch = character(False)
    m = _model(False)
    d = mujoco.MjData(m)
    bodies = np.array([ch.body_index(t.body) + 1 for t in mapping.targets])
    offsets = np.array([t.offset for t in mapping.targets])
    out = np.empty((qpos.shape[0], len(bodies), 3))
    for t in range(qpos.shape[0]):
        d.qpos[:] = qpos[t]
        mujoco.mj_kinematics(m, d)
        out[t] = d.xpos[bodies] + np.einsum("kij,kj->ki", d.xmat[bodies].reshape(-1, 3, 3), offsets)
    return out


def _ranges(frames: np.ndarray) -> tuple[tuple[int, int], ...]:
    """Sorted frame indices -> consecutive runs as [start, stop) pairs."""
    if frames.size == 0:
        return ()
    cuts = np.flatnonzero(np.diff(frames) > 1) + 1
    return tuple((int(r[0]), int(r[-1]) + 1) for r in np.split(frames, cuts))


def _on_floor(qpos: np.ndarray, probe: Clip) -> tuple[np.ndarray, float]:
    """qpos moved vertically as in step 4 of the module docstring, and the global shift (m)."""
    qpos = qpos.copy()
    low = sole_points(probe, qpos)[:, :, 2].min(axis=1)
    shift = -float(np.percentile(low, FLOOR_PERCENTILE))
    qpos[:, 2] += shift + np.maximum(0.0, -(low + shift))
    return qpos, shift


def retarget(
    bvh: bvh_mod.Bvh,
    mapping: Mapping,
    *,
    units: str | float | None = None,
    up: str | None = None,
    name: str = "bvh",
    path: str = "",
    settings: IkSettings = IkSettings(),
    floor: bool = True,
) -> tuple[Clip, RetargetReport]:
    """The BVH's motion on the 15-body character (see the module docstring).

    Args:
        bvh: the parsed file.
        mapping: joint -> body mapping; every joint it names must be in the BVH.
        units, up: override the mapping's (see ``bvh``).
        name, path: of the clip.
        floor: put the feet on the floor (step 4); False keeps the scaled BVH's heights.

    Returns:
        (clip of format "bvh", report).

    Raises:
        ValueError: the BVH lacks joints the mapping needs, fewer than 2 frames, bad units/up.
    """
    missing = [j for j in mapping.joints if j not in bvh.names]
    if missing:
        raise ValueError(
            f"skeleton mapping {mapping.name!r} does not cover this BVH: no joint {', '.join(map(repr, missing[:6]))}"
            f"{' ...' if len(missing) > 6 else ''} (the file's joints: {', '.join(bvh.names[:30])})"
        )
    if bvh.num_frames < 2:
        raise ValueError(f"too few frames ({bvh.num_frames}; need at least 2)")
    up = up or mapping.up
    scale = bvh_mod.metres_per_unit(bvh, mapping.units if units is None else units, up)
    pos = bvh_mod.joint_positions(bvh, scale, up)[:, [bvh.names.index(j) for j in mapping.joints]]
    idx = {t.body: k for k, t in enumerate(mapping.targets) if t.offset == (0.0, 0.0, 0.0)}
    leg = _leg_length(pos, idx)
    if not leg > 1e-6:
        raise ValueError("the BVH's legs have no length (thigh, shin and foot joints at one point)")
    height_scale = _character_leg_length() / leg
    targets = pos * height_scale
    qpos = solve_ik(targets, mapping, settings)
    probe = build_clip(
        name=name, path=path, format="bvh", fps=bvh.fps, loop=False, sword_shield=False,
        root_pos=qpos[:, :3], root_quat=qpos[:, 3:7], dof_pos=qpos[:, 7:],
    )  # fmt: skip
    qpos, shift = _on_floor(qpos, probe) if floor else (qpos, 0.0)
    clip = build_clip(
        name=name, path=path, format="bvh", fps=bvh.fps, loop=False, sword_shield=False,
        root_pos=qpos[:, :3], root_quat=qpos[:, 3:7], dof_pos=qpos[:, 7:],
    )  # fmt: skip
    targets[..., 2] += shift
    dist = np.linalg.norm(mapped_points(clip.qpos, mapping) - targets, axis=-1) * 1000.0
    rng = character(False).joint_range
    at_limit = (clip.dof_pos <= rng[:, 0] + 1e-6) | (clip.dof_pos >= rng[:, 1] - 1e-6)
    names = character(False).joint_names
    clamped = {names[j]: _ranges(np.flatnonzero(at_limit[:, j])) for j in range(len(names)) if at_limit[:, j].any()}
    report = RetargetReport(
        skeleton=mapping.name,
        bvh_joints=len(bvh.names),
        frames=bvh.num_frames,
        fps=bvh.fps,
        metres_per_unit=scale,
        height_scale=height_scale,
        error_mm=dist.mean(axis=1),
        max_error_mm=dist.max(axis=1),
        clamped=clamped,
        clamped_frames=int(at_limit.any(axis=1).sum()),
    )
    return dataclasses.replace(clip, fk_error_m=float(dist.max()) / 1000.0), report


def retarget_file(
    path,
    skeleton: str | None = None,
    units: str | float | None = None,
    up: str | None = None,
    floor: bool = True,
) -> tuple[Clip, RetargetReport]:
    """Reads and retargets a BVH file (``skeleton`` None = the first packaged mapping it fits).

    Raises:
        MotionFileError: one line naming the file: unreadable or malformed BVH, NaN, a skeleton
            no (or not the given) mapping covers, bad units, an implausible result.
    """
    path = Path(path)
    try:
        bvh = bvh_mod.read_bvh(path)
        if skeleton is None:
            mapping = guess_mapping(bvh)
            if mapping is None:
                raise ValueError(
                    f"no skeleton mapping covers this BVH (packaged: {', '.join(skeleton_names())}; the file's "
                    f"joints: {', '.join(bvh.names[:30])}); pass a mapping file with --skeleton"
                )
        else:
            mapping = load_mapping(skeleton)
        problem = plaus.fps_problem(bvh.fps)
        if problem:
            raise ValueError(problem)
        clip, report = retarget(bvh, mapping, units=units, up=up, name=path.stem, path=str(path), floor=floor)
        problem = plaus.motion_problem(clip.fps, clip.root_pos, local_quats(clip), clip.character.body_names)
        if problem:
            raise ValueError(f"retargeted motion: {problem}")
        return clip, report
    except MotionFileError:
        raise
    except ValueError as e:
        raise MotionFileError(path, str(e)) from None


def local_quats(clip: Clip) -> np.ndarray:
    """[T, nb, 4] wxyz: the root's world rotation, then each body's rotation relative to its parent."""
    ch = clip.character
    q = clip.body_quat
    local = q.copy()
    for b in range(1, ch.num_bodies):
        local[:, b] = rot.quat_mul(rot.quat_conj(q[:, ch.parents[b]]), q[:, b])
    return local


def clip_to_json(clip: Clip, note: str = "") -> dict:
    """The clip in the CompositeMotion JSON layout the loaders read (``pelvis: [pos, xyzw]``, every
    other body its xyzw rotation relative to its parent)."""
    names = clip.character.body_names
    xyzw = np.roll(local_quats(clip), -1, axis=-1)
    frames = [
        {"pelvis": [clip.root_pos[t].tolist(), xyzw[t, 0].tolist()]}
        | {n: xyzw[t, b].tolist() for b, n in enumerate(names) if b}
        for t in range(clip.num_frames)
    ]
    return {"_": note, "fps": clip.fps, "frames": frames}
