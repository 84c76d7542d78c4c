"""Tests of jaxmotion.motion: rotations, loaders (shared clips + bad files), MotionLib, mirror, groups, CLI."""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from jaxmotion.motion import rotations as rot
from jaxmotion.motion import (
    BodyGroup,
    MotionFileError,
    MotionLib,
    default_groups,
    find_motion_files,
    group_indices,
    load_clip,
    make_test_clip,
    mean_root_speed,
    mirror_clip,
    qpos_qvel,
    resolve_group,
    sample,
    sample_times,
    sample_windows,
)
from jaxmotion.motion.convert import range_violation, range_wrap, viterbi_branch
from jaxmotion.motion.motionlib import qpos_of
from jaxmotion.physics.character import character

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ["JAXMOTION_DATA"]) if os.environ.get("JAXMOTION_DATA") else REPO.parent / "shared" / "motions"
SHARED = find_motion_files(DATA) if DATA.is_dir() and any(DATA.iterdir()) else []
FORMAT_OF_SET = {
    "compositemotion": "compositemotion_json",
    "deepmimic": "deepmimic_txt",
    "isaacgymenvs": "poselib_npy",
    "ase_sword_shield": "poselib_npy",
}
needs_data = pytest.mark.skipif(not SHARED, reason=f"shared motion data not found at {DATA} (set JAXMOTION_DATA)")


@functools.cache
def _load(path: str):
    return load_clip(path)


def _shared(rel: str) -> str:
    p = DATA / rel
    if not p.exists():
        pytest.skip(f"{p} not found")
    return str(p)


# ----------------------------------------------------------------------------- rotations


def _random_quats(n, seed=0):
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def test_quat_ops_match_scipy():
    q, p = _random_quats(50, 1), _random_quats(50, 2)
    v = np.random.default_rng(3).normal(size=(50, 3))
    R = lambda x: Rotation.from_quat(x, scalar_first=True)  # noqa: E731
    np.testing.assert_allclose(rot.quat_rotate(q, v), R(q).apply(v), atol=1e-12)
    np.testing.assert_allclose(rot.quat_to_mat(q), R(q).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(rot.quat_to_mat(rot.quat_mul(q, p)), (R(q) * R(p)).as_matrix(), atol=1e-12)
    back = rot.mat_to_quat(R(q).as_matrix())
    np.testing.assert_allclose(np.abs(np.sum(back * q, -1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(rot.quat_to_exp_map(q), R(q).as_rotvec(), atol=1e-10)
    np.testing.assert_allclose(np.abs(np.sum(rot.exp_map_to_quat(R(q).as_rotvec()) * q, -1)), 1, atol=1e-12)
    # jax arrays give jax results with the same values (float32).
    out = rot.quat_rotate(jnp.asarray(q, jnp.float32), jnp.asarray(v, jnp.float32))
    assert isinstance(out, jax.Array)
    np.testing.assert_allclose(out, R(q).apply(v), atol=1e-5)


def test_euler_xyz_roundtrip_and_mujoco_convention():
    e = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(200, 3))
    e[:, 1] /= 2.0  # b in [-pi/2, pi/2]
    q = rot.quat_from_euler_xyz(e)
    np.testing.assert_allclose(rot.quat_to_mat(q), Rotation.from_euler("XYZ", e).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(rot.euler_xyz_from_quat(q), e, atol=1e-9)
    # Gimbal lock still reproduces the rotation.
    lock = rot.quat_from_euler_xyz(np.array([[0.3, np.pi / 2, 0.4], [0.3, -np.pi / 2, -0.2]]))
    again = rot.quat_from_euler_xyz(rot.euler_xyz_from_quat(lock))
    np.testing.assert_allclose(np.abs(np.sum(again * lock, -1)), 1.0, atol=1e-12)


def test_slerp_matches_scipy_and_is_safe():
    q0, q1 = _random_quats(20, 4), _random_quats(20, 5)
    t = np.random.default_rng(6).uniform(size=20)
    ours = rot.slerp(q0, q1, t)
    for i in range(20):
        ref = Slerp([0, 1], Rotation.from_quat([q0[i], q1[i]], scalar_first=True))(t[i])
        assert abs(abs(np.dot(ours[i], ref.as_quat(scalar_first=True))) - 1) < 1e-10
    # Identical and antipodal (same rotation) inputs, jitted, give no NaN.
    f = jax.jit(rot.slerp)
    with jax.disable_jit(False):
        same = f(jnp.asarray(q0[:3], jnp.float32), jnp.asarray(-q0[:3], jnp.float32), jnp.float32(0.3))
    assert np.isfinite(np.asarray(same)).all()
    np.testing.assert_allclose(np.abs(np.sum(np.asarray(same) * q0[:3], -1)), 1.0, atol=1e-6)


def test_heading_and_tan_norm():
    yaw = rot.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.7)
    tilt = rot.quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.3)
    q = rot.quat_mul(yaw, tilt)
    np.testing.assert_allclose(rot.heading_angle(q), 0.7, atol=1e-12)
    np.testing.assert_allclose(rot.heading_quat(q), yaw, atol=1e-12)
    np.testing.assert_allclose(rot.quat_mul(rot.heading_inv(q), q), tilt, atol=1e-12)
    m = rot.quat_to_mat(q)
    np.testing.assert_allclose(rot.quat_to_tan_norm(q), np.concatenate([m[:, 0], m[:, 2]]), atol=1e-12)


# ----------------------------------------------------------------------------- shared clips


@needs_data
@pytest.mark.parametrize(
    "path", [str(p) for p in SHARED] or ["none"], ids=[str(p.relative_to(DATA)) for p in SHARED] or ["none"]
)
def test_shared_clip_loads(path):
    clip = _load(path)
    ch = clip.character
    T, nb = clip.num_frames, ch.num_bodies
    set_name = Path(path).relative_to(DATA).parts[0]
    assert clip.format == FORMAT_OF_SET[set_name]
    assert clip.sword_shield == (set_name == "ase_sword_shield")
    assert clip.qpos.shape == (T, 7 + ch.num_dof) and clip.qvel.shape == (T, 6 + ch.num_dof)
    assert clip.body_pos.shape == (T, nb, 3) and clip.body_quat.shape == (T, nb, 4)
    for f in ("root_lin_vel", "root_ang_vel", "dof_vel", "body_lin_vel", "body_ang_vel"):
        assert np.isfinite(getattr(clip, f)).all(), f
    np.testing.assert_allclose(np.linalg.norm(clip.body_quat, axis=-1), 1.0, atol=1e-9)
    assert clip.fps > 0 and clip.duration > 0
    # The file's own rotations composed along its skeleton == MuJoCo FK of the extracted qpos.
    assert clip.fk_error_m < 1e-3, f"{clip.name}: fk error {clip.fk_error_m:.3g} m"


@needs_data
def test_shared_sets_present_and_exact():
    sets = {Path(p).relative_to(DATA).parts[0] for p in SHARED}
    assert set(FORMAT_OF_SET) <= sets
    errs = {
        s: max(_load(str(p)).fk_error_m for p in SHARED if p.relative_to(DATA).parts[0] == s) for s in FORMAT_OF_SET
    }
    # JSON sets are float64 in the file: exact; npy files are float32.
    assert errs["compositemotion"] < 1e-12 and errs["deepmimic"] < 1e-12
    assert errs["isaacgymenvs"] < 1e-6 and errs["ase_sword_shield"] < 1e-6


@needs_data
def test_deepmimic_mapping_matches_poselib_backflip():
    # The same backflip ships as DeepMimic (y-up) and poselib (z-up): the y-up mapping must agree.
    a = _load(_shared("deepmimic/humanoid3d_backflip.txt"))
    b = _load(_shared("isaacgymenvs/amp_humanoid_backflip.npy"))
    assert a.loop and not b.loop and a.fps == pytest.approx(16.0)
    np.testing.assert_allclose(a.body_pos, b.body_pos, atol=1e-4)


@needs_data
def test_compositemotion_layouts_and_loaders_accept_relative_paths(monkeypatch):
    old = _load(_shared("compositemotion/gym/squat.json"))  # base_position layout
    assert old.num_frames == 85 and old.root_pos[0, 2] == pytest.approx(0.8420249448928833)
    monkeypatch.setenv("JAXMOTION_DATA", str(DATA))
    rel = load_clip("compositemotion/iccgan/kick.json")
    assert rel.num_frames == 57 and rel.fps == 30


# ----------------------------------------------------------------------------- synthetic clips


def test_make_test_clip_known_values():
    clip = make_test_clip(num_frames=31, fps=30.0, root_vel=(1.0, 0.0, 0.0), yaw_rate=0.5)
    assert mean_root_speed(clip) == pytest.approx(1.0, abs=1e-12)
    assert clip.duration == pytest.approx(1.0)
    np.testing.assert_allclose(clip.root_lin_vel, np.tile([1.0, 0, 0], (31, 1)), atol=1e-12)
    np.testing.assert_allclose(clip.root_ang_vel, np.tile([0, 0, 0.5], (31, 1)), atol=1e-12)
    np.testing.assert_allclose(clip.body_ang_vel, np.tile([0, 0, 0.5], (31, 15, 1)), atol=1e-12)
    np.testing.assert_allclose(clip.dof_vel, 0.0)
    # qvel: root angular velocity in the root's local frame (a pure yaw: the same vector).
    np.testing.assert_allclose(clip.qvel[:, 3:6], np.tile([0, 0, 0.5], (31, 1)), atol=1e-12)
    # Body origins move with the root: pelvis at the root, torso 0.236151 above it.
    np.testing.assert_allclose(clip.body_pos[:, 0], clip.root_pos, atol=1e-12)
    np.testing.assert_allclose(clip.body_pos[:, 1, 2] - clip.root_pos[:, 2], 0.236151, atol=1e-9)


def _wavy_clip(T=61, fps=60.0, loop=False, sword_shield=False):
    n = character(sword_shield).num_dof
    t = np.arange(T)[:, None] / fps
    dof = 0.3 * np.sin(2 * np.pi * 0.7 * t + np.arange(n)[None] * 0.37)
    return make_test_clip(
        T, fps, root_vel=(0.8, 0.2, 0.0), yaw_rate=0.4, dof_pos=dof, loop=loop, sword_shield=sword_shield
    )


def test_qvel_matches_mujoco_body_velocities():
    # MuJoCo's body velocities from (qpos, qvel) agree with the finite-difference body velocities
    # (central differences at 60 fps on 0.3-rad, 0.7-Hz joint waves: a few mm/s of error).
    clip = _wavy_clip()
    m = clip.character.mj_model()
    d = mujoco.MjData(m)
    for t in (10, 30, 50):
        d.qpos[:], d.qvel[:] = clip.qpos[t], clip.qvel[t]
        mujoco.mj_forward(m, d)
        for b in range(1, m.nbody):
            v = np.zeros(6)
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, v, 0)
            lin_origin = v[3:] + np.cross(v[:3], d.xpos[b] - d.xipos[b])
            np.testing.assert_allclose(v[:3], clip.body_ang_vel[t, b - 1], atol=3e-3)
            np.testing.assert_allclose(lin_origin, clip.body_lin_vel[t, b - 1], atol=3e-3)


# ----------------------------------------------------------------------------- MotionLib


@pytest.fixture(scope="module")
def lib_and_clips():
    clips = [_wavy_clip(loop=False), _wavy_clip(T=31, fps=30.0, loop=True)]
    return MotionLib.from_clips(clips), clips


def test_motionlib_layout(lib_and_clips):
    lib, clips = lib_and_clips
    assert lib.num_clips == 2 and lib.num_frames == 61 + 31
    np.testing.assert_array_equal(lib.clip_start, [0, 61])
    assert lib.root_pos.dtype == jnp.float32 and lib.clip_start.dtype == jnp.int32
    np.testing.assert_allclose(lib.clip_weight, [0.5, 0.5], atol=1e-6)  # both last 1 s
    np.testing.assert_allclose(lib.clip_duration, [1.0, 1.0], atol=1e-6)


# Every un-jitted query below has the same shapes (8 clips/times, scalar speed): with
# JAX_DISABLE_JIT each new shape recompiles every primitive, which costs seconds.
def _query(lib, clip, t, speed=1.0):
    assert len(clip) == len(t) == 8
    return sample(lib, jnp.asarray(clip, jnp.int32), jnp.asarray(t, jnp.float32), speed)


def test_sample_at_frames_and_halfway(lib_and_clips):
    lib, clips = lib_and_clips
    c = clips[0]
    k = np.array([0, 7, 33, 60])
    s = _query(lib, [0] * 8, np.concatenate([k, [7.5, 7.25, 59.5, 0.5]]) / c.fps)
    at = jax.tree.map(lambda x: np.asarray(x)[:4], s)
    for f in ("root_pos", "dof_pos", "body_pos", "body_lin_vel", "dof_vel"):
        np.testing.assert_allclose(getattr(at, f), getattr(c, f)[k], atol=1e-5, err_msg=f)
    np.testing.assert_allclose(np.abs(np.sum(at.body_quat * c.body_quat[k], -1)), 1, atol=1e-6)
    qpos, qvel = qpos_qvel(at)
    np.testing.assert_allclose(qpos, c.qpos[k], atol=1e-5)
    np.testing.assert_allclose(qvel, c.qvel[k], atol=1e-4)
    # Between frames: linear for vectors, slerp for quaternions (scipy's Slerp as the reference).
    for i, (f0, a) in enumerate([(7, 0.5), (7, 0.25), (59, 0.5), (0, 0.5)]):
        j = 4 + i
        np.testing.assert_allclose(s.root_pos[j], (1 - a) * c.root_pos[f0] + a * c.root_pos[f0 + 1], atol=1e-5)
        np.testing.assert_allclose(s.dof_vel[j], (1 - a) * c.dof_vel[f0] + a * c.dof_vel[f0 + 1], atol=1e-4)
        for b in range(15):
            ref = Slerp([0, 1], Rotation.from_quat(c.body_quat[f0 : f0 + 2, b], scalar_first=True))(a)
            assert abs(abs(np.dot(s.body_quat[j, b], ref.as_quat(scalar_first=True))) - 1) < 1e-6
        ref = Slerp([0, 1], Rotation.from_quat(c.root_quat[f0 : f0 + 2], scalar_first=True))(a)
        assert abs(abs(np.dot(s.root_quat[j], ref.as_quat(scalar_first=True))) - 1) < 1e-6


def test_sample_wraps_loop_and_clamps_otherwise(lib_and_clips):
    lib, clips = lib_and_clips
    s = _query(lib, [0, 0, 1, 1, 1, 0, 1, 1], [5.0, -3.0, 0.25, 3.25, -0.75, 0.25, 1.0, 0.0])
    np.testing.assert_allclose(s.root_pos[0], clips[0].root_pos[-1], atol=1e-5)  # clamped
    np.testing.assert_allclose(s.root_pos[1], clips[0].root_pos[0], atol=1e-5)
    for i in (3, 4):  # period = duration = (T - 1) / fps = 1 s
        np.testing.assert_allclose(s.dof_pos[i], s.dof_pos[2], atol=1e-4)
        np.testing.assert_allclose(s.root_pos[i], s.root_pos[2], atol=1e-4)
    # t = duration is the last frame (continuous from below: a tracked loop ends there), not frame 0
    np.testing.assert_allclose(s.root_pos[6], clips[1].root_pos[-1], atol=1e-5)
    np.testing.assert_allclose(s.root_pos[7], clips[1].root_pos[0], atol=1e-5)
    assert not np.allclose(s.dof_pos[5], s.dof_pos[2])  # different clips really differ


def test_sample_speed_and_jit(lib_and_clips):
    lib, _ = lib_and_clips
    clip = np.array([0, 1, 0, 1, 0, 1, 0, 1])
    t = np.linspace(0.05, 1.9, 8)
    slow = _query(lib, clip, t, 0.5)
    ref = _query(lib, clip, t * 0.5)
    np.testing.assert_allclose(slow.body_pos, ref.body_pos, atol=1e-6)
    np.testing.assert_allclose(slow.root_lin_vel, 0.5 * ref.root_lin_vel, atol=1e-6)
    np.testing.assert_allclose(slow.body_ang_vel, 0.5 * ref.body_ang_vel, atol=1e-6)

    def both(lib, c, t):
        return sample(lib, c, t, 0.5), jax.vmap(sample, in_axes=(None, 0, 0, None))(lib, c, t, 0.5)

    with jax.disable_jit(False):
        jitted, vmapped = jax.jit(both)(lib, jnp.asarray(clip, jnp.int32), jnp.asarray(t, jnp.float32))
    for f in ("root_pos", "root_quat", "dof_pos", "body_quat", "body_ang_vel"):
        np.testing.assert_allclose(getattr(jitted, f), getattr(slow, f), atol=1e-5, err_msg=f)
        np.testing.assert_allclose(getattr(vmapped, f), getattr(slow, f), atol=1e-5, err_msg=f)


def test_pose_only_windows_are_the_full_windows_coordinates(lib_and_clips):
    lib, _ = lib_and_clips
    with jax.disable_jit(False):
        full, pose = jax.jit(
            lambda k: (
                sample_windows(lib, k, 16, 5, 1 / 30, (0.8, 1.2)),
                sample_windows(lib, k, 16, 5, 1 / 30, (0.8, 1.2), pose_only=True),
            )
        )(jax.random.PRNGKey(4))
    np.testing.assert_array_equal(qpos_of(pose), qpos_of(full))
    np.testing.assert_array_equal(qpos_of(full), qpos_qvel(full)[0])
    assert pose.body_pos is None and pose.dof_vel is None


def test_sample_times_and_windows(lib_and_clips):
    lib, clips = lib_and_clips

    def draw(lib, key):
        k0, k1 = jax.random.split(key)
        return sample_times(lib, k0, 256), sample_windows(lib, k1, 8, 5, 1 / 30, (0.5, 1.5))

    with jax.disable_jit(False):  # jax.random op by op is slow to compile: one jit instead
        (clip, t), w = jax.jit(draw)(lib, jax.random.PRNGKey(0))
    assert clip.shape == t.shape == (256,)
    assert set(np.unique(clip)) == {0, 1}
    assert (t >= 0).all() and (t <= 1.0 + 1e-6).all()
    assert w.body_pos.shape == (8, 5, 15, 3) and w.dof_pos.shape == (8, 5, 28)
    # Every window is a moving root at ~ the clip's speed (0.8, 0.2) m/s times its replay speed.
    speed = np.linalg.norm(w.root_lin_vel[..., :2], axis=-1)
    assert (speed.std(axis=1) < 1e-3).all() and (speed > 0.4).all() and (speed < 1.3).all()
    step = np.linalg.norm(np.diff(w.root_pos[..., :2], axis=1), axis=-1)
    np.testing.assert_allclose(step, speed[:, :-1] / 30, rtol=1e-3, atol=1e-5)


def test_motionlib_rejects_mixed_characters():
    with pytest.raises(ValueError, match="sword"):
        MotionLib.from_clips([make_test_clip(), make_test_clip(sword_shield=True)])
    with pytest.raises(ValueError, match="weights"):
        MotionLib.from_clips([make_test_clip()], weights=[-1.0])


# ----------------------------------------------------------------------------- mirror


def test_mirror_twice_is_identity_and_reflects_bodies():
    clip = _wavy_clip()
    m = mirror_clip(clip)
    mm = mirror_clip(m)
    assert m.name == "test_mirror" and mm.name == "test"
    for f in ("root_pos", "root_quat", "dof_pos", "body_pos", "body_quat", "body_lin_vel", "dof_vel"):
        np.testing.assert_allclose(getattr(mm, f), getattr(clip, f), atol=1e-10, err_msg=f)
    # Mirrored FK == mirror image of the original bodies, with left/right swapped.
    names = clip.character.body_names
    swap = [names.index(n.replace("left_", "@").replace("right_", "left_").replace("@", "right_")) for n in names]
    np.testing.assert_allclose(m.body_pos, clip.body_pos[:, swap] * [1, -1, 1], atol=1e-10)
    with pytest.raises(ValueError, match="sword"):
        mirror_clip(make_test_clip(sword_shield=True))


@needs_data
def test_mirrored_walk_keeps_speed():
    clip = _load(_shared("deepmimic/humanoid3d_walk.txt"))
    m = mirror_clip(clip)
    assert mean_root_speed(m) == pytest.approx(mean_root_speed(clip), rel=1e-9)
    np.testing.assert_allclose(
        m.body_pos[..., 1], -clip.body_pos[..., 1][:, [0, 1, 2, 6, 7, 8, 3, 4, 5, 12, 13, 14, 9, 10, 11]], atol=1e-9
    )


# ----------------------------------------------------------------------------- joint ranges


def test_range_wrap_and_branch_choice():
    lo, hi = np.deg2rad([-180.0]), np.deg2rad([45.0])
    a = np.deg2rad([179.0])  # == -181 deg: 1 deg outside instead of 134
    np.testing.assert_allclose(np.rad2deg(range_wrap(a, lo, hi)), [-181.0], atol=1e-9)

    # Two candidates per frame, range [-1, 1]; branch 0 always at 2.5 (1.5 outside). A short
    # excursion of branch 1 is not worth two jumps to branch 0: stay. A long, worse one is.
    def run(c1):
        c0 = np.full((len(c1), 1, 1, 1), 2.5)
        cands = np.concatenate([c0, np.reshape(c1, (-1, 1, 1, 1))], axis=2)
        return viterbi_branch(cands, np.array([[-1.0]]), np.array([[1.0]]))[:, 0]

    np.testing.assert_array_equal(run([0.0, 0.0, -2.0, 0.0, 0.0]), [1] * 5)
    np.testing.assert_array_equal(run([0.0] * 5 + [-3.0] * 8 + [0.0] * 5), [1] * 5 + [0] * 8 + [1] * 5)
    assert range_violation(np.array([2.0]), np.array([-1.0]), np.array([1.0]))[0] == 1.0


# ----------------------------------------------------------------------------- groups


def test_default_groups_and_indices():
    ch, ss = character(False), character(True)
    g = default_groups(ch)
    assert set(g) == {"upper", "lower", "arms", "rest", "full"}
    assert g["upper"].anchor == "pelvis" and g["arms"].anchor == "torso" and g["lower"].anchor is None
    assert set(g["upper"].links) | set(g["lower"].links) == set(ch.body_names)
    assert set(g["rest"].links) | set(g["arms"].links) == set(ch.body_names)
    links, anchor = group_indices("arms", ch)
    assert links.dtype == np.int32 and anchor == ch.body_index("torso")
    assert [ch.body_names[i] for i in links] == list(g["arms"].links)
    gs = default_groups(ss)
    assert {"sword", "shield"} <= set(gs["upper"].links) and len(gs["full"].links) == 17
    assert group_indices("lower", ss)[1] == -1


def test_resolve_group_specs_and_errors():
    ch = character(False)
    g = resolve_group({"name": "hands", "links": ["left_hand", "right_hand"], "anchor": "torso"}, ch)
    assert g == BodyGroup("hands", ("left_hand", "right_hand"), "torso")
    assert resolve_group(g, ch) == g
    with pytest.raises(ValueError, match="left_hnd.*valid bodies.*pelvis"):
        resolve_group({"links": ["left_hnd"]}, ch)
    with pytest.raises(ValueError, match="anchor 'tail'"):
        resolve_group(BodyGroup("x", ("head",), "tail"), ch)
    with pytest.raises(ValueError, match="default groups"):
        resolve_group("legs", ch)
    with pytest.raises(ValueError, match="sword"):
        resolve_group({"links": ["sword"]}, ch)


# ----------------------------------------------------------------------------- bad files


def _composite_frames(n=3):
    ch = character(False)
    frames = []
    for t in range(n):
        f = {b: [0.0, 0.0, 0.0, 1.0] for b in ch.body_names[1:]}
        f["pelvis"] = [[0.01 * t, 0.0, 0.9], [0.0, 0.0, 0.0, 1.0]]
        frames.append(f)
    return frames


def _write_json(path: Path, d) -> Path:
    path.write_text(d if isinstance(d, str) else json.dumps(d))
    return path


def _poselib_dict(sword_shield: bool, T=4):
    ch = character(sword_shield)
    rotq = np.zeros((T, ch.num_bodies, 4), np.float32)
    rotq[..., 3] = 1
    arr = lambda a: {"arr": a, "context": {"dtype": str(a.dtype)}}  # noqa: E731
    return {
        "rotation": arr(rotq),
        "root_translation": arr(np.tile(np.float32([0, 0, 0.9]), (T, 1))),
        "skeleton_tree": {
            "node_names": list(ch.body_names),
            "parent_indices": arr(np.array(ch.parents)),
            "local_translation": arr(ch.body_offsets.astype(np.float32)),
        },
        "is_local": True,
        "fps": 30,
        "__name__": "SkeletonMotion",
    }


def test_good_small_files_load(tmp_path):
    c = load_clip(_write_json(tmp_path / "ok.json", {"fps": 30, "frames": _composite_frames()}))
    assert c.num_frames == 3 and mean_root_speed(c) == pytest.approx(0.3)
    p = tmp_path / "ss.npy"
    np.save(p, _poselib_dict(True), allow_pickle=True)
    s = load_clip(p)
    assert s.sword_shield and s.num_dof == 31 and s.fk_error_m < 1e-6


def test_deepmimic_yup_mapping_and_uneven_dt(tmp_path):
    # Root at (1, 2, 3) y-up -> (1, -3, 2) z-up; a turn by 0.4 about vertical y -> about z; a
    # DeepMimic knee angle of -0.5 about z -> +0.5 about y. dt 0.1, 0.1, 0.2: resampled at 10 fps.
    ident = [1.0, 0.0, 0.0, 0.0]
    yaw = [np.cos(0.2), 0.0, np.sin(0.2), 0.0]
    frame = [1.0, 2.0, 3.0] + yaw + ident * 3 + [-0.5] + ident * 2 + [0.0] + ident + [0.0] + ident * 2 + [0.0]
    frames = [[dt] + frame for dt in (0.1, 0.1, 0.2, 0.0)]
    frames[3][1] = 4.0  # x moves 1 -> 4 over the last 0.2 s
    clip = load_clip(_write_json(tmp_path / "m.txt", {"Loop": "none", "Frames": frames}))
    assert clip.format == "deepmimic_txt" and not clip.loop and clip.fps == pytest.approx(10.0)
    assert clip.num_frames == 5
    np.testing.assert_allclose(clip.root_pos[:, 0], [1.0, 1.0, 1.0, 2.5, 4.0], atol=1e-12)
    np.testing.assert_allclose(clip.root_pos[:, 1:], np.tile([-3.0, 2.0], (5, 1)), atol=1e-12)
    turn = np.tile([np.cos(0.2), 0, 0, np.sin(0.2)], (5, 1))
    np.testing.assert_allclose(clip.root_quat, turn, atol=1e-12)
    ch = clip.character
    np.testing.assert_allclose(clip.dof_pos[:, ch.joint_names.index("right_knee")], 0.5, atol=1e-12)
    assert clip.fk_error_m < 1e-12


@pytest.mark.parametrize(
    "case",
    ["broken_json", "missing_body", "nan", "fps0", "no_fps", "one_frame", "deepmimic_width", "npy17_as_15", "bad_ext"],
)
def test_bad_files_raise_motion_file_error(tmp_path, case):
    frames = _composite_frames()
    character_arg = None
    if case == "broken_json":
        p, expect = _write_json(tmp_path / "a.json", '{"fps": 30, "frames": [{"pelvis": '), "malformed JSON"
    elif case == "missing_body":
        del frames[1]["left_shin"]
        p, expect = (
            _write_json(tmp_path / "a.json", {"fps": 30, "frames": frames}),
            "missing body 'left_shin' in frame 1",
        )
    elif case == "nan":
        frames[2]["torso"][0] = float("nan")
        p, expect = _write_json(tmp_path / "a.json", {"fps": 30, "frames": frames}), "'torso' at frame 2"
    elif case == "fps0":
        p, expect = _write_json(tmp_path / "a.json", {"fps": 0, "frames": frames}), "bad fps"
    elif case == "no_fps":
        p, expect = _write_json(tmp_path / "a.json", {"frames": frames}), "bad fps"
    elif case == "one_frame":
        p, expect = _write_json(tmp_path / "a.json", {"fps": 30, "frames": frames[:1]}), "too few frames"
    elif case == "deepmimic_width":
        p, expect = _write_json(tmp_path / "a.txt", {"Loop": "wrap", "Frames": [[0.1] * 43] * 3}), "44 numbers"
    elif case == "npy17_as_15":
        p = tmp_path / "a.npy"
        np.save(p, _poselib_dict(True), allow_pickle=True)
        character_arg, expect = character(False), "wrong skeleton"
    else:
        p, expect = _write_json(tmp_path / "a.fbx", "Kaydara FBX Binary"), "unsupported file type"  # .bvh reads now
    with pytest.raises(MotionFileError) as info:
        load_clip(p, character_arg)
    assert str(p) in str(info.value) and expect in str(info.value)


def test_cli_reports_bad_file_and_writes_json(tmp_path):
    folder = tmp_path / "clips"
    (folder / "sub").mkdir(parents=True)
    _write_json(folder / "good.json", {"fps": 30, "frames": _composite_frames(4)})
    _write_json(folder / "sub" / "bad.json", '{"fps": 30, "frames": [')
    (folder / "LICENSE.txt").write_text("not a motion")  # skipped by the folder scan
    out = tmp_path / "report.json"
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    r = subprocess.run(
        [sys.executable, "-m", "jaxmotion.motion", str(folder), "--json", str(out)],
        capture_output=True,
        text=True,
        cwd=REPO,
        env=env,
        timeout=120,
    )
    assert r.returncode != 0
    text = r.stdout + r.stderr
    assert "Traceback" not in text
    assert f"ERROR {folder / 'sub' / 'bad.json'}: malformed JSON" in r.stdout
    assert "good.json" in r.stdout
    report = json.loads(out.read_text())
    assert [c["path"] for c in report["clips"]] == [str(folder / "good.json")]
    row = report["clips"][0]
    assert row["frames"] == 4 and row["root_speed_mps"] == pytest.approx(0.3)
    assert set(row) == {
        "path",
        "format",
        "frames",
        "fps",
        "duration_s",
        "root_speed_mps",
        "fk_error_m",
        "peak_joint_speed_rad_s",
        "servo_reach_ratio",
        "limiting_joint",
    }
    assert len(report["errors"]) == 1 and "malformed JSON" in report["errors"][0]["error"]


# ----------------------------------------------------------------------------- frame ranges


def test_frame_ranges_parse_and_join_without_a_jump(tmp_path):
    from jaxmotion.motion.clip import select_frames
    from jaxmotion.motion.loaders import load_clips, split_frame_ranges

    assert split_frame_ranges("a/squat.json[0:28, 56:]") == ("a/squat.json", ((0, 28), (56, None)))
    assert split_frame_ranges("C:/x[1].json") == ("C:/x[1].json", None)
    # A root walking at 1 m/s along x (30 fps): frames 0-4, then 20-29 carried on from frame 4.
    clip = make_test_clip(30, root_vel=(1.0, 0.0, 0.0))
    part = select_frames(clip, ((0, 5), (20, None)))
    assert part.num_frames == 15 and not part.loop and part.name == "test[0:5,20:]"
    np.testing.assert_allclose(part.root_pos[:5], clip.root_pos[:5])
    np.testing.assert_allclose(part.root_pos[:, 0], np.arange(15) / 30, atol=1e-12)
    np.testing.assert_allclose(part.root_lin_vel[:, 0], 1.0, atol=1e-9)
    with pytest.raises(ValueError, match="not within"):
        select_frames(clip, ((25, 31),))
    with pytest.raises(ValueError, match="at least 2"):
        select_frames(clip, ((3, 4),))
    # Through the loader, as an experiment names it; a bad range is a MotionFileError.
    path = _write_json(tmp_path / "walk.json", {"fps": 30, "frames": _composite_frames(6)})
    (c,) = load_clips([f"{path}[1:4]"])
    np.testing.assert_allclose(c.root_pos[:, 0], [0.01, 0.02, 0.03], atol=1e-6)
    with pytest.raises(MotionFileError, match="not within"):
        load_clips([f"{path}[0:9]"])
