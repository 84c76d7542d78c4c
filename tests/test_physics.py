"""The character and its PD servo: MJCF facts, the servo law, standing, MJX vs MuJoCo C."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from conftest import jit_enabled
from jaxmotion.physics import servo, sim
from jaxmotion.physics.character import build_mjcf, character

STAND_Z = 0.89  # root height with feet on the floor in the zero pose


def _standing(m: mujoco.MjModel) -> mujoco.MjData:
    d = mujoco.MjData(m)
    d.qpos[:] = 0
    d.qpos[2], d.qpos[3] = STAND_Z, 1.0
    return d


@pytest.mark.parametrize("sword_shield, nb, ndof", [(False, 15, 28), (True, 17, 31)])
def test_character_matches_reference_model(sword_shield, nb, ndof):
    ch = character(sword_shield)
    m = ch.mj_model()
    assert ch.num_bodies == nb and ch.num_dof == ndof
    assert m.nq == 7 + ndof and m.nv == 6 + ndof and m.nu == ndof
    if not sword_shield:
        # Same total mass as shared/models/compositemotion/humanoid.xml (48.9 kg).
        assert abs(m.body_mass.sum() - 48.89) < 0.01
        # Floor contacts only: one candidate pair per body geom, none between body parts.
        d = _standing(m)
        d.qpos[2] = 0.0  # sink everything into the floor
        mujoco.mj_forward(m, d)
        assert all(0 in (d.contact[i].geom1, d.contact[i].geom2) for i in range(d.ncon))
    else:
        assert ch.body_names[6] == "sword" and ch.body_names[9] == "shield"
        assert "right_hand_x" in ch.joint_names


def test_servo_is_the_clipped_pd_law():
    """The actuators apply clip(kp*(target-q) - kd*qdot, ±max_torque), per DoF."""
    ch = character()
    m = ch.mj_model()
    d = _standing(m)
    rng = np.random.default_rng(0)
    d.qpos[7:] = rng.uniform(-0.3, 0.3, ch.num_dof)
    d.qvel[6:] = rng.uniform(-3, 3, ch.num_dof)
    d.ctrl[:] = rng.uniform(-1.0, 1.0, ch.num_dof)
    mujoco.mj_forward(m, d)
    expected = sim.pd_torque(ch, d.qpos[7:], d.qvel[6:], d.ctrl)
    np.testing.assert_allclose(d.actuator_force, expected, rtol=1e-6, atol=1e-6)
    assert np.any(np.abs(expected) == ch.max_torque)  # some torques do hit the limit


@pytest.mark.parametrize("sword_shield", [False, True])
def test_servo_holds_standing_pose_mujoco_c(sword_shield):
    cfg = sim.PhysicsConfig(sword_shield=sword_shield)
    m = sim.mj_model(cfg)
    d = _standing(m)
    for _ in range(int(2 * cfg.sim_hz)):
        mujoco.mj_step(m, d)
    assert d.qpos[2] > 0.8
    # Without gains the same character collapses.
    m.actuator_gainprm[:, 0] = 0
    m.actuator_biasprm[:, 1:3] = 0
    d = _standing(m)
    for _ in range(int(2 * cfg.sim_hz)):
        mujoco.mj_step(m, d)
    assert d.qpos[2] < 0.4


def test_mjx_control_step_matches_mujoco_c():
    """One control step of the MJX servo (4 substeps in a scan) equals 4 MuJoCo C steps.

    In the air, so that the two contact solvers (which legitimately differ) do not enter, and
    with targets near the pose so no torque saturates: MuJoCo C drops a clamped actuator's
    velocity derivative from the implicit step, MJX 3.17 keeps it, so they differ there.
    """
    cfg = sim.PhysicsConfig()
    m = sim.mj_model(cfg)
    d = _standing(m)
    d.qpos[2] = 2.0
    rng = np.random.default_rng(1)
    lo, hi = character().joint_range.T + np.array([[0.1], [-0.1]])  # away from joint limits
    d.qpos[7:] = np.clip(rng.uniform(-0.2, 0.2, m.nu), lo, hi)
    target = d.qpos[7:] + rng.uniform(-0.05, 0.05, m.nu)
    mx = sim.mjx_model(cfg)
    dx = mjx.make_data(mx).replace(qpos=jnp.asarray(d.qpos, jnp.float32))
    with jit_enabled():
        dx = jax.jit(sim.pd_step, static_argnums=3)(mx, dx, jnp.asarray(target, jnp.float32), cfg.substeps)
    d.ctrl[:] = target
    for _ in range(cfg.substeps):
        mujoco.mj_step(m, d)
    np.testing.assert_allclose(np.asarray(dx.qpos), d.qpos, atol=1e-4)
    np.testing.assert_allclose(np.asarray(dx.qvel), d.qvel, atol=1e-2)


def test_substeps_validation():
    assert sim.PhysicsConfig().substeps == 4
    with pytest.raises(ValueError, match="multiple"):
        _ = sim.PhysicsConfig(sim_hz=100, control_hz=30).substeps


def test_mjcf_has_no_passive_springs():
    m = mujoco.MjModel.from_xml_string(build_mjcf())
    assert np.all(m.jnt_stiffness == 0) and np.all(m.dof_damping == 0)


def _squat_peak_speed(clip, cfg: sim.PhysicsConfig, frame: int, seed: int, sigma: float = 0.3) -> float:
    """Peak |qvel| over 1 s of PD control from a squat frame resting on the floor, each control
    step's target the frame's pose plus N(0, sigma) rad (an exploring policy), in MuJoCo C."""
    from jaxmotion.motion.level import _lowest_points

    ch = character(False)
    lo, hi = ch.joint_range[:, 0], ch.joint_range[:, 1]
    q = clip.qpos[frame].copy()
    q[7:] = np.clip(q[7:], lo, hi)
    m = sim.mj_model(cfg)
    d = mujoco.MjData(m)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    d.qpos[2] -= min(_lowest_points(m, d, [g])[2] for g in range(m.ngeom) if m.geom_bodyid[g] > 0)
    rng, peak = np.random.default_rng(seed), 0.0
    for _ in range(30):
        d.ctrl[:] = np.clip(q[7:] + sigma * rng.standard_normal(ch.num_dof), lo, hi)
        for _ in range(cfg.substeps):
            mujoco.mj_step(m, d)
            peak = max(peak, float(np.abs(d.qvel).max()))
    return peak


def test_contact_solver_converges_in_a_squat(data_dir):
    """Feet planted in the shared squat under exploring PD targets: with the default solver
    iteration cap no joint speed reaches the env's unstable-physics limit (``max_qvel`` 100
    rad/s, a reset that training and evaluation count as a fall). Capped at 4 iterations the
    unconverged contacts throw the ankles past it (measured: 20 of 60 such runs, up to 355 rad/s)."""
    from jaxmotion.envs.humanoid import EnvConfig
    from jaxmotion.motion.loaders import load_clips

    clip = load_clips([data_dir / "compositemotion/gym/squat.json"], character(False))[0]
    limit = EnvConfig().max_qvel
    runs = [(f, s) for f in range(6, 40, 6) for s in range(2)]
    default = [_squat_peak_speed(clip, sim.PhysicsConfig(), f, s) for f, s in runs]
    capped = [_squat_peak_speed(clip, sim.PhysicsConfig(solver_iterations=4, ls_iterations=8), f, s) for f, s in runs]
    assert max(default) < 0.7 * limit, default
    assert sum(p > limit for p in capped) >= 3, capped


def _mjx_reach(cfg: sim.PhysicsConfig) -> np.ndarray:
    """``servo.reach`` on MJX: the same welded-root sweeps, stepped by the MJX backend's substep."""
    from jaxmotion.physics import backends

    m = servo.fixed_base_model(cfg)
    mx = mjx.put_model(m)
    n = int(round(servo.PROBE_SECONDS * cfg.sim_hz))

    def sweep(q0, target):
        d = mjx.make_data(mx).replace(qpos=q0, ctrl=target)
        _, qd = jax.lax.scan(lambda d, _: (lambda d1: (d1, jnp.abs(d1.qvel)))(backends.mjx_substep(mx, d)), d, None, n)
        return qd.max(0)

    with jit_enabled():
        f = jax.jit(sweep)
        return np.max(
            [np.asarray(f(jnp.asarray(q, jnp.float32), jnp.asarray(t, jnp.float32))) for q, t in servo.probe_starts(m)],
            0,
        )


@pytest.mark.physics
def test_servo_reaches_past_the_tracker_clips_on_both_backends(data_dir):
    """Every joint turns faster than the 99th-percentile speed of the tracker's training clips
    (``track/medium``: a run, a kick, a jump, punches), on MuJoCo C and on MJX alike; with the
    damping on the joint (``servo_damping='joint'``) most joints cannot."""
    from jaxmotion.config import load_experiment
    from jaxmotion.motion import load_clips

    cfg = load_experiment("track/medium")
    clips = load_clips(cfg.env.init_motions)
    # Pooled over every frame of every clip (one 47-frame kick alone has a 45 rad/s shoulder
    # spike in its Euler angles, above its own 99th percentile of frames).
    need = np.percentile(np.concatenate([np.abs(np.diff(c.dof_pos, axis=0)) * c.fps for c in clips]), 99, axis=0)
    assert need.max() > 15.0  # the punches' shoulders and the run's knees
    phys = sim.PhysicsConfig()
    c_reach, mjx_reach = servo.reach(phys), _mjx_reach(phys)
    np.testing.assert_allclose(mjx_reach, c_reach, rtol=0.05)
    assert (c_reach > need).all(), dict(zip(character().joint_names, np.round(c_reach / need, 2)))
    damped = servo.reach(dataclasses.replace(phys, servo_damping="joint"))
    assert (damped < need).mean() > 0.5 and damped.max() < 6.0
