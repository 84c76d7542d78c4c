"""All clips as one pytree of float32 frames, sampled at any time with pure ``jnp`` gathers.

Frames of every clip are concatenated along axis 0 (``F`` frames in all); clip ``c`` owns frames
``clip_start[c] .. clip_start[c] + clip_len[c] - 1``. Sampling is jit/vmap friendly: the clip and
time arrays may have any (matching or broadcastable) leading shape.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxmotion.motion import rotations as rot
from jaxmotion.motion.clip import Clip
from jaxmotion.physics.character import Character

FRAME_FIELDS = (
    "root_pos",
    "root_quat",
    "root_lin_vel",
    "root_ang_vel",
    "dof_pos",
    "dof_vel",
    "body_pos",
    "body_quat",
    "body_lin_vel",
    "body_ang_vel",
)
_QUAT_FIELDS = ("root_quat", "body_quat")
_VEL_FIELDS = ("root_lin_vel", "root_ang_vel", "dof_vel", "body_lin_vel", "body_ang_vel")


@struct.dataclass
class MotionState:
    """Reference state at some times; leading shape [...] of the query (world frame, wxyz).

    Attributes:
        root_pos: [..., 3].
        root_quat: [..., 4].
        root_lin_vel: [..., 3] world frame.
        root_ang_vel: [..., 3] world frame.
        dof_pos: [..., n_dof].
        dof_vel: [..., n_dof].
        body_pos: [..., nb, 3].
        body_quat: [..., nb, 4].
        body_lin_vel: [..., nb, 3].
        body_ang_vel: [..., nb, 3] world frame.
    """

    root_pos: jax.Array
    root_quat: jax.Array
    root_lin_vel: jax.Array
    root_ang_vel: jax.Array
    dof_pos: jax.Array
    dof_vel: jax.Array
    body_pos: jax.Array
    body_quat: jax.Array
    body_lin_vel: jax.Array
    body_ang_vel: jax.Array


@struct.dataclass
class MotionLib:
    """Flat float32 frames of all clips (see ``MotionState`` for the per-frame fields) + clip table.

    Attributes:
        root_pos ... body_ang_vel: [F, ...] frames of all clips, same fields as ``MotionState``.
        clip_start: [C] int32 first frame of each clip.
        clip_len: [C] int32 number of frames of each clip (>= 2).
        clip_fps: [C] float32.
        clip_loop: [C] bool (True = wrap with period duration, False = clamp).
        clip_weight: [C] float32 sampling probabilities (sum 1).
        clip_names: static tuple of clip names.
        clip_paths: static tuple of source paths.
        sword_shield: static, which character.
    """

    root_pos: jax.Array
    root_quat: jax.Array
    root_lin_vel: jax.Array
    root_ang_vel: jax.Array
    dof_pos: jax.Array
    dof_vel: jax.Array
    body_pos: jax.Array
    body_quat: jax.Array
    body_lin_vel: jax.Array
    body_ang_vel: jax.Array
    clip_start: jax.Array
    clip_len: jax.Array
    clip_fps: jax.Array
    clip_loop: jax.Array
    clip_weight: jax.Array
    clip_names: tuple[str, ...] = struct.field(pytree_node=False, default=())
    clip_paths: tuple[str, ...] = struct.field(pytree_node=False, default=())
    sword_shield: bool = struct.field(pytree_node=False, default=False)

    @property
    def num_clips(self) -> int:
        return int(self.clip_start.shape[0])

    @property
    def num_frames(self) -> int:
        return int(self.root_pos.shape[0])

    @property
    def clip_duration(self) -> jax.Array:
        """[C] seconds: (len - 1) / fps."""
        return (self.clip_len - 1).astype(jnp.float32) / self.clip_fps

    def clip_index(self, name: str) -> int:
        """Index of a clip by name (first match); a clear error lists the names otherwise."""
        try:
            return self.clip_names.index(name)
        except ValueError:
            raise KeyError(f"no clip {name!r}; clips are {list(self.clip_names)}") from None

    @classmethod
    def from_clips(cls, clips: Sequence[Clip], weights: Sequence[float] | None = None) -> MotionLib:
        """Packs clips (all of one character) into a library.

        Args:
            clips: the clips (C >= 1).
            weights: [C] non-negative sampling weights; None = proportional to duration.
                Normalised to sum 1.

        Returns:
            The library (jnp float32 arrays).
        """
        if not clips:
            raise ValueError("MotionLib needs at least one clip")
        kinds = {c.sword_shield for c in clips}
        if len(kinds) > 1:
            raise ValueError(
                "clips mix the 15-body and the sword-shield character: "
                + ", ".join(f"{c.name} (sword_shield={c.sword_shield})" for c in clips)
            )
        if weights is None:
            w = np.array([c.duration for c in clips], np.float64)
        else:
            w = np.asarray(weights, np.float64).reshape(-1)
            if w.shape != (len(clips),):
                raise ValueError(f"got {w.shape[0]} weights for {len(clips)} clips")
        if not (np.isfinite(w).all() and (w >= 0).all() and w.sum() > 0):
            raise ValueError(f"clip weights must be finite, >= 0 and not all 0, got {w.tolist()}")
        lens = np.array([c.num_frames for c in clips], np.int32)
        starts = np.concatenate([[0], np.cumsum(lens)[:-1]]).astype(np.int32)
        frames = {f: jnp.asarray(np.concatenate([getattr(c, f) for c in clips]), jnp.float32) for f in FRAME_FIELDS}
        return cls(
            **frames,
            clip_start=jnp.asarray(starts),
            clip_len=jnp.asarray(lens),
            clip_fps=jnp.asarray([c.fps for c in clips], jnp.float32),
            clip_loop=jnp.asarray([c.loop for c in clips], bool),
            clip_weight=jnp.asarray(w / w.sum(), jnp.float32),
            clip_names=tuple(c.name for c in clips),
            clip_paths=tuple(c.path for c in clips),
            sword_shield=bool(clips[0].sword_shield),
        )


def load_motionlib(
    paths: str | os.PathLike | Iterable[str | os.PathLike],
    character: Character | None = None,
    weights: Sequence[float] | None = None,
    drop_props: bool = False,
    level: Sequence[str] = (),
) -> MotionLib:
    """Loads files/folders (see ``loaders.load_clips``) into a ``MotionLib``. ``drop_props``: load
    sword-and-shield clips onto the 15-body humanoid (``clip.drop_sword_shield``). ``level``: clip
    names (file stems) or path endings whose frames with both feet planted are levelled
    (``level.level_feet``)."""
    from jaxmotion.motion.clip import drop_sword_shield
    from jaxmotion.motion.level import level_feet
    from jaxmotion.motion.loaders import load_clips

    if drop_props and character is not None and not character.sword_shield:
        clips = [drop_sword_shield(c) for c in load_clips(paths, None)]
    else:
        clips = load_clips(paths, character)
    wanted = lambda c: any(c.name == p or (c.path and c.path.endswith(p)) for p in level)
    return MotionLib.from_clips([level_feet(c) if wanted(c) else c for c in clips], weights)


def reweighted(lib: MotionLib, sampling: str) -> MotionLib:
    """``lib`` with its clip probabilities by ``sampling``: 'duration' keeps them (the weights it
    was built with, by default each clip's length), 'uniform' makes every clip equally likely."""
    if sampling == "duration":
        return lib
    if sampling == "uniform":
        return lib.replace(clip_weight=jnp.full((lib.num_clips,), 1.0 / lib.num_clips, jnp.float32))
    raise ValueError(f"init_sampling must be 'duration' or 'uniform', got {sampling!r}")


def _frame_pair(lib: MotionLib, clip: jax.Array, tc: jax.Array):
    """Global frame indices around clip time ``tc`` (wrapped or clamped) and the blend weight."""
    n = lib.clip_len[clip]
    fps = lib.clip_fps[clip]
    dur = (n - 1).astype(jnp.float32) / fps
    # A loop wraps only outside [0, duration]: its last frame stays the last frame, not the first.
    wrap = lib.clip_loop[clip] & ((tc < 0.0) | (tc > dur))
    tw = jnp.where(wrap, jnp.mod(tc, dur), jnp.clip(tc, 0.0, dur))
    f = tw * fps
    i0 = jnp.clip(jnp.floor(f).astype(jnp.int32), 0, n - 2)
    alpha = jnp.clip(f - i0.astype(jnp.float32), 0.0, 1.0)
    g0 = lib.clip_start[clip] + i0
    return g0, g0 + 1, alpha


_LIN_FIELDS = tuple(f for f in FRAME_FIELDS if f not in _QUAT_FIELDS)


def _sample_clip_time(
    lib: MotionLib, clip: jax.Array, tc: jax.Array, vel_scale, pose_only: bool = False
) -> MotionState:
    """State at clip time ``tc`` (seconds of the clip itself); velocities times ``vel_scale``.

    All vector fields are gathered and blended as one packed [..., D] array and both quaternion
    fields with one slerp, to keep the number of primitives small (cheap to compile, and fast
    when the suite runs op by op with ``JAX_DISABLE_JIT``). ``pose_only``: only the generalised
    coordinates (root position and rotation, hinge angles); the other fields are None.
    """
    lin_fields = ("root_pos", "dof_pos") if pose_only else _LIN_FIELDS
    clip = jnp.asarray(clip, jnp.int32)
    tc = jnp.asarray(tc, jnp.float32)
    clip, tc = jnp.broadcast_arrays(clip, tc)
    scale = jnp.broadcast_to(jnp.asarray(vel_scale, jnp.float32), tc.shape)
    g0, g1, alpha = _frame_pair(lib, clip, tc)
    idx = jnp.stack([g0, g1], axis=-1)  # [..., 2]
    lead = tc.shape
    tails = [getattr(lib, f).shape[1:] for f in lin_fields]
    sizes = [int(np.prod(s)) for s in tails]
    x = jnp.concatenate(
        [getattr(lib, f)[idx].reshape(lead + (2, n)) for f, n in zip(lin_fields, sizes)], axis=-1
    )  # [..., 2, D]
    is_dof = np.concatenate([np.full(n, f == "dof_pos") for f, n in zip(lin_fields, sizes)])
    is_vel = np.concatenate([np.full(n, f in _VEL_FIELDS) for f, n in zip(lin_fields, sizes)])
    x0 = x[..., 0, :]
    diff = x[..., 1, :] - x0
    # Hinge angles blend the short way round the circle (a stored angle may jump by 2*pi).
    diff = jnp.where(is_dof, rot.wrap_angle(diff), diff)
    v = (x0 + alpha[..., None] * diff) * jnp.where(is_vel, scale[..., None], 1.0)
    out = {}
    for f, part, tail in zip(lin_fields, jnp.split(v, np.cumsum(sizes)[:-1], axis=-1), tails):
        out[f] = part.reshape(lead + tail)
    if pose_only:
        q = lib.root_quat[idx]
        out["root_quat"] = rot.slerp(q[..., 0, :], q[..., 1, :], alpha)
        out.update({f: None for f in FRAME_FIELDS if f not in out})
        return MotionState(**out)
    q = jnp.concatenate([lib.root_quat[idx][..., None, :], lib.body_quat[idx]], axis=-2)
    qs = rot.slerp(q[..., 0, :, :], q[..., 1, :, :], alpha[..., None])  # [..., 1 + nb, 4]
    out["root_quat"], out["body_quat"] = qs[..., 0, :], qs[..., 1:, :]
    return MotionState(**out)


def sample(lib: MotionLib, clip, t, speed=1.0) -> MotionState:
    """Reference state of clips at times ``t`` replayed at ``speed``.

    The state is the clip's pose at clip time ``t * speed`` (wrapped modulo the duration for loop
    clips, clamped to [0, duration] otherwise), linearly interpolated between the two nearest
    frames (positions, velocities, hinge angles) or slerped (quaternions). Velocities are
    multiplied by ``speed``.

    Args:
        lib: the library.
        clip: [...] int32 clip indices.
        t: [...] float times in seconds (broadcast against ``clip``).
        speed: scalar or [...] replay speed.

    Returns:
        ``MotionState`` with leading shape [...].
    """
    speed = jnp.asarray(speed, jnp.float32)
    return _sample_clip_time(lib, clip, jnp.asarray(t, jnp.float32) * speed, speed)


def sample_times(lib: MotionLib, rng: jax.Array, n: int) -> tuple[jax.Array, jax.Array]:
    """Random (clip, time) pairs: clips with probability ``clip_weight``, t ~ U[0, duration].

    Args:
        lib: the library.
        rng: PRNG key.
        n: number of samples (static).

    Returns:
        (clip [n] int32, t [n] float32 seconds).
    """
    k_clip, k_t = jax.random.split(rng)
    clip = jax.random.categorical(k_clip, jnp.log(lib.clip_weight), shape=(n,)).astype(jnp.int32)
    t = jax.random.uniform(k_t, (n,)) * lib.clip_duration[clip]
    return clip, t


def sample_windows(
    lib: MotionLib,
    rng: jax.Array,
    n: int,
    num_frames: int,
    dt: float,
    speed_range: tuple[float, float] = (1.0, 1.0),
    pose_only: bool = False,
) -> MotionState:
    """Random windows of consecutive reference states (e.g. discriminator inputs).

    Each window picks a clip (probability ``clip_weight``) and a speed ~ U(speed_range); frame k
    is the state at clip time ``start + k * dt * speed`` with velocities times speed. For non-loop
    clips the start is uniform over the positions where the window fits (0 if it never fits; the
    window then clamps at the end); for loop clips it is uniform over [0, duration).

    Args:
        lib: the library.
        rng: PRNG key.
        n: number of windows (static).
        num_frames: frames per window (static).
        dt: seconds between window frames (the policy's control step).
        speed_range: (low, high) replay speeds, > 0.
        pose_only: only root position, root rotation and hinge angles (the rest None): what
            ``qpos_of`` needs, at a fraction of the cost.

    Returns:
        ``MotionState`` with leading shape [n, num_frames].
    """
    k_clip, k_speed, k_start = jax.random.split(rng, 3)
    clip = jax.random.categorical(k_clip, jnp.log(lib.clip_weight), shape=(n,)).astype(jnp.int32)
    speed = jax.random.uniform(k_speed, (n,), minval=speed_range[0], maxval=speed_range[1])
    dur = lib.clip_duration[clip]
    span = (num_frames - 1) * dt * speed
    start_max = jnp.where(lib.clip_loop[clip], dur, jnp.maximum(dur - span, 0.0))
    start = jax.random.uniform(k_start, (n,)) * start_max
    tc = start[:, None] + jnp.arange(num_frames, dtype=jnp.float32)[None, :] * (dt * speed[:, None])
    return _sample_clip_time(
        lib, jnp.broadcast_to(clip[:, None], tc.shape), tc, jnp.broadcast_to(speed[:, None], tc.shape), pose_only
    )


def qpos_of(state: MotionState) -> jax.Array:
    """MuJoCo generalised positions [..., 7 + n_dof] of reference states."""
    return jnp.concatenate([state.root_pos, state.root_quat, state.dof_pos], axis=-1)


def qpos_qvel(state: MotionState) -> tuple[jax.Array, jax.Array]:
    """MuJoCo coordinates of reference states.

    Args:
        state: leading shape [...].

    Returns:
        (qpos [..., 7 + n_dof], qvel [..., 6 + n_dof]); the root angular velocity in qvel is in the
        root body's local frame (MuJoCo free joint), the linear velocity in the world frame.
    """
    qpos = jnp.concatenate([state.root_pos, state.root_quat, state.dof_pos], axis=-1)
    w_local = rot.quat_rotate_inv(state.root_quat, state.root_ang_vel)
    qvel = jnp.concatenate([state.root_lin_vel, w_local, state.dof_vel], axis=-1)
    return qpos, qvel
