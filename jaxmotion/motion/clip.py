"""One reference motion clip, in the character's MuJoCo coordinates (numpy, float64).

A ``Clip`` holds the root trajectory and the hinge angles (the MuJoCo ``qpos``), the world-frame
body positions/orientations from MuJoCo forward kinematics (``mj_kinematics`` on the character's
model) and finite-difference velocities, all computed once by ``build_clip``.
"""

from __future__ import annotations

from collections.abc import Sequence
import dataclasses
import functools

import mujoco
import numpy as np

from jaxmotion.motion import rotations as rot
from jaxmotion.motion.frame_ranges import format_ranges, resolve_range
from jaxmotion.physics.character import Character, character

FORMATS = ("compositemotion_json", "deepmimic_txt", "poselib_npy", "bvh", "generated")


@dataclasses.dataclass(frozen=True, eq=False)
class Clip:
    """A motion clip: T frames at ``fps``; every array is float64 numpy, world frame, z-up.

    Attributes:
        name: clip name (the file stem).
        path: source file ("" for clips built in code).
        format: one of ``FORMATS``.
        fps: frames per second (> 0).
        loop: True = the clip wraps (time modulo duration), False = clamp at the ends.
        sword_shield: which character (17-body sword-and-shield variant or 15-body humanoid).
        root_pos: [T, 3] root (pelvis) position.
        root_quat: [T, 4] root orientation, wxyz, sign-continuous.
        dof_pos: [T, n_dof] hinge angles (XYZ Euler per 3-DoF joint), radians.
        root_lin_vel: [T, 3] world-frame root linear velocity.
        root_ang_vel: [T, 3] world-frame root angular velocity.
        dof_vel: [T, n_dof] hinge velocities.
        body_pos: [T, nb, 3] body origins.
        body_quat: [T, nb, 4] body orientations, wxyz, sign-continuous over time.
        body_lin_vel: [T, nb, 3] body origin velocities.
        body_ang_vel: [T, nb, 3] body angular velocities (world frame).
        fk_error_m: max over frames and bodies of the distance between the body positions given by
            the file's own rotations/skeleton and MuJoCo FK of ``qpos`` (0 for generated clips).
    """

    name: str
    path: str
    format: str
    fps: float
    loop: bool
    sword_shield: bool
    root_pos: np.ndarray
    root_quat: np.ndarray
    dof_pos: np.ndarray
    root_lin_vel: np.ndarray
    root_ang_vel: np.ndarray
    dof_vel: np.ndarray
    body_pos: np.ndarray
    body_quat: np.ndarray
    body_lin_vel: np.ndarray
    body_ang_vel: np.ndarray
    fk_error_m: float = 0.0

    @property
    def num_frames(self) -> int:
        return int(self.root_pos.shape[0])

    @property
    def num_dof(self) -> int:
        return int(self.dof_pos.shape[1])

    @property
    def dt(self) -> float:
        return 1.0 / self.fps

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame: (T - 1) / fps."""
        return (self.num_frames - 1) / self.fps

    @property
    def character(self) -> Character:
        return character(self.sword_shield)

    @property
    def qpos(self) -> np.ndarray:
        """[T, 7 + n_dof] MuJoCo qpos: root pos, root quat wxyz, hinge angles."""
        return np.concatenate([self.root_pos, self.root_quat, self.dof_pos], axis=-1)

    @property
    def qvel(self) -> np.ndarray:
        """[T, 6 + n_dof] MuJoCo qvel: world linear velocity, root-local angular velocity, hinges."""
        w_local = rot.quat_rotate_inv(self.root_quat, self.root_ang_vel)
        return np.concatenate([self.root_lin_vel, w_local, self.dof_vel], axis=-1)

    def __repr__(self) -> str:
        return (
            f"Clip({self.name!r}, format={self.format!r}, frames={self.num_frames}, "
            f"fps={self.fps:g}, loop={self.loop}, sword_shield={self.sword_shield})"
        )


def mean_root_speed(clip: Clip) -> float:
    """Mean root speed in m/s: 3D root displacement per frame times fps, averaged over frames."""
    step = np.linalg.norm(np.diff(clip.root_pos, axis=0), axis=-1)
    return float(step.mean() * clip.fps)


@functools.cache
def _model(sword_shield: bool) -> mujoco.MjModel:
    return character(sword_shield).mj_model()


def forward_kinematics(sword_shield: bool, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo forward kinematics (``mj_kinematics``) of each frame.

    Args:
        sword_shield: which character.
        qpos: [T, 7 + n_dof].

    Returns:
        (body_pos [T, nb, 3], body_quat [T, nb, 4] wxyz), world frame, without the world body.
    """
    m = _model(sword_shield)
    d = mujoco.MjData(m)
    T = qpos.shape[0]
    pos = np.empty((T, m.nbody - 1, 3))
    quat = np.empty((T, m.nbody - 1, 4))
    for t in range(T):
        d.qpos[:] = qpos[t]
        mujoco.mj_kinematics(m, d)
        pos[t] = d.xpos[1:]
        quat[t] = d.xquat[1:]
    return pos, quat


def finite_diff(x: np.ndarray, dt: float) -> np.ndarray:
    """Time derivative along axis 0: central differences, one-sided at the ends. [T, ...] -> [T, ...]."""
    return np.gradient(x, dt, axis=0, edge_order=1)


def angular_velocity(q: np.ndarray, dt: float) -> np.ndarray:
    """World-frame angular velocity from orientations by finite differences.

    Central ``log(q[t+1] q[t-1]^-1) / (2 dt)``, one-sided at the ends.

    Args:
        q: [T, ..., 4] wxyz unit quaternions (T >= 2).
        dt: frame time in seconds.

    Returns:
        [T, ..., 3] rad/s.
    """
    w = np.empty(q.shape[:-1] + (3,))
    w[0] = rot.quat_to_exp_map(rot.quat_mul(q[1], rot.quat_conj(q[0]))) / dt
    w[-1] = rot.quat_to_exp_map(rot.quat_mul(q[-1], rot.quat_conj(q[-2]))) / dt
    if q.shape[0] > 2:
        w[1:-1] = rot.quat_to_exp_map(rot.quat_mul(q[2:], rot.quat_conj(q[:-2]))) / (2 * dt)
    return w


def build_clip(
    *,
    name: str,
    path: str,
    format: str,
    fps: float,
    loop: bool,
    sword_shield: bool,
    root_pos: np.ndarray,
    root_quat: np.ndarray,
    dof_pos: np.ndarray,
    fk_error_m: float = 0.0,
) -> Clip:
    """Builds a ``Clip`` from root trajectory and hinge angles: MuJoCo FK plus finite differences.

    Args:
        name, path, format, fps, loop, sword_shield, fk_error_m: see ``Clip``.
        root_pos: [T, 3].
        root_quat: [T, 4] wxyz (normalised here, made sign-continuous).
        dof_pos: [T, n_dof] hinge angles. Velocities use the time-unwrapped angles, so a jump of
            2*pi between frames (an Euler angle crossing +-pi) does not give a velocity spike.

    Returns:
        The clip (float64 arrays).
    """
    ch = character(sword_shield)
    root_pos = np.asarray(root_pos, np.float64)
    dof_pos = np.asarray(dof_pos, np.float64)
    root_quat = rot.quat_make_continuous(rot.quat_normalize(np.asarray(root_quat, np.float64)))
    T = root_pos.shape[0]
    if T < 2 or root_quat.shape != (T, 4) or root_pos.shape != (T, 3) or dof_pos.shape != (T, ch.num_dof):
        raise ValueError(
            f"bad clip shapes: root_pos {root_pos.shape}, root_quat {root_quat.shape}, "
            f"dof_pos {dof_pos.shape} (need T >= 2 and {ch.num_dof} dofs)"
        )
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"bad fps {fps!r}")
    dt = 1.0 / fps
    qpos = np.concatenate([root_pos, root_quat, dof_pos], axis=-1)
    body_pos, body_quat = forward_kinematics(sword_shield, qpos)
    body_quat = rot.quat_make_continuous(body_quat)
    body_ang_vel = angular_velocity(body_quat, dt)
    body_lin_vel = finite_diff(body_pos, dt)
    return Clip(
        name=name,
        path=path,
        format=format,
        fps=float(fps),
        loop=bool(loop),
        sword_shield=bool(sword_shield),
        root_pos=root_pos,
        root_quat=root_quat,
        dof_pos=dof_pos,
        root_lin_vel=finite_diff(root_pos, dt),
        root_ang_vel=angular_velocity(root_quat, dt),
        dof_vel=finite_diff(np.unwrap(dof_pos, axis=0), dt),
        body_pos=body_pos,
        body_quat=body_quat,
        body_lin_vel=body_lin_vel,
        body_ang_vel=body_ang_vel,
        fk_error_m=float(fk_error_m),
    )


def select_frames(clip: Clip, ranges: Sequence[tuple[int, int | None]]) -> Clip:
    """The frames of ``ranges`` (Python slices ``[start, stop)`` of frame indices, negative ends
    counted from the end, ``stop`` None = to the end), joined in order into one clip that does not
    loop.

    Each later range's root is shifted horizontally (xy only, no turn) to carry on from where the
    previous one ended, at its last horizontal step, and the velocities are recomputed across the
    seams, so join ranges whose poses match there (e.g. two points of a squat on either side of a
    bounce at its bottom, cutting the bounce out).
    For parts that do not meet, list the file twice with one range each: two clips.

    Raises:
        ValueError: a range outside the clip, an empty range, or fewer than 2 frames in all.
    """
    n = clip.num_frames
    parts = []
    for start, stop in ranges:
        lo, hi = resolve_range(start, stop, n)
        if lo >= hi:
            raise ValueError(f"frames [{format_ranges(((start, stop),))}] select no frame of the clip's {n}")
        parts.append(np.arange(lo, hi))
    root = [clip.root_pos[parts[0]]]
    for idx in parts[1:]:
        seg = clip.root_pos[idx].copy()
        prev = root[-1]
        step = prev[-1, :2] - prev[-2, :2] if len(prev) > 1 else 0.0
        seg[:, :2] += prev[-1, :2] + step - seg[0, :2]
        root.append(seg)
    idx = np.concatenate(parts)
    spec = format_ranges(ranges)
    if idx.size < 2:
        raise ValueError(f"frames [{spec}] select {idx.size} frame of the clip's {n}; a clip needs at least 2")
    return build_clip(
        name=f"{clip.name}[{spec}]",
        path=clip.path,
        format=clip.format,
        fps=clip.fps,
        loop=False,
        sword_shield=clip.sword_shield,
        root_pos=np.concatenate(root),
        root_quat=clip.root_quat[idx],
        dof_pos=clip.dof_pos[idx],
        fk_error_m=clip.fk_error_m,
    )


def make_test_clip(
    num_frames: int = 31,
    fps: float = 30.0,
    *,
    root_vel=(1.0, 0.0, 0.0),
    root_height: float = 0.9,
    yaw_rate: float = 0.0,
    dof_pos=None,
    loop: bool = False,
    sword_shield: bool = False,
    name: str = "test",
) -> Clip:
    """A synthetic clip with hand-known values: a root moving at constant velocity.

    Args:
        num_frames: T.
        fps: frames per second.
        root_vel: (3,) constant world-frame root velocity, m/s.
        root_height: root z at frame 0.
        yaw_rate: constant rotation rate about world z, rad/s (root_quat = yaw(yaw_rate * t)).
        dof_pos: None (all zero), an [n_dof] pose held constant, or a [T, n_dof] trajectory.
        loop, sword_shield, name: see ``Clip``.

    Returns:
        The clip, format "generated".
    """
    n_dof = character(sword_shield).num_dof
    t = np.arange(num_frames) / fps
    root_pos = np.array([0.0, 0.0, root_height]) + t[:, None] * np.asarray(root_vel, np.float64)
    half = 0.5 * yaw_rate * t
    root_quat = np.stack([np.cos(half), 0 * t, 0 * t, np.sin(half)], axis=-1)
    if dof_pos is None:
        dof_pos = np.zeros((num_frames, n_dof))
    dof_pos = np.broadcast_to(np.asarray(dof_pos, np.float64), (num_frames, n_dof))
    return build_clip(
        name=name,
        path="",
        format="generated",
        fps=fps,
        loop=loop,
        sword_shield=sword_shield,
        root_pos=root_pos,
        root_quat=root_quat,
        dof_pos=dof_pos,
    )


def drop_sword_shield(clip: Clip) -> Clip:
    """A sword-and-shield clip (17 bodies) on the 15-body humanoid: the sword, the shield and the
    right wrist's three hinges dropped, every other joint angle kept (the two characters share
    their other links and offsets); link poses rebuilt by the 15-body forward kinematics. A clip
    of the 15-body humanoid comes back unchanged."""
    if not clip.sword_shield:
        return clip
    names15 = set(character(False).joint_names)
    keep = [i for i, n in enumerate(character(True).joint_names) if n in names15]
    return build_clip(
        name=clip.name,
        path=clip.path,
        format=clip.format,
        fps=clip.fps,
        loop=clip.loop,
        sword_shield=False,
        root_pos=clip.root_pos,
        root_quat=clip.root_quat,
        dof_pos=clip.dof_pos[:, keep],
    )
