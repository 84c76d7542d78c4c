"""Two players: scoring forces against MuJoCo's own ``mj_contactForce`` on both backends, the
calibration of the touch threshold, the boxing and fencing rules, mirrored observations,
swapped sides, and a short self-play batch without NaN."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from conftest import jit_enabled
from jaxmotion.envs.bout import BoutEnv, BoutState, place
from jaxmotion.envs.humanoid import EnvConfig
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.physics import arena as A
from jaxmotion.physics import backends
from jaxmotion.physics.sim import PhysicsConfig
from jaxmotion.tasks import TaskConfig

BOX = A.ArenaConfig(sport="boxing")
FENCE = A.ArenaConfig(sport="fencing")


def _gid(m, name):
    return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)


def _model(cfg: A.ArenaConfig, sim_hz: float = 120.0) -> mujoco.MjModel:
    m = A.arena_model(cfg).__copy__()
    m.opt.timestep = 1.0 / sim_hz
    return m


def _c_physics(cfg: A.ArenaConfig, sim_hz: float = 120.0, substeps: int = 4):
    m = _model(cfg, sim_hz)
    return backends.MujocoPhysics(A.arena_mjcf(cfg), m, None, substeps, 2, A.channels(cfg, m)), m


def _pressing(cfg: A.ArenaConfig, own: str, other: str, depth: float = 0.01) -> np.ndarray:
    """qpos with player 1 moved so that its geom ``other`` overlaps player 0's ``own`` by ``depth``
    along x (both players in the zero pose, in the air: only that contact carries force)."""
    m = A.arena_model(cfg)
    d = mujoco.MjData(m)
    lay = A.layout(cfg)
    d.qpos[2] += 0.5
    d.qpos[lay.nq + 2] += 0.5
    mujoco.mj_kinematics(m, d)
    a, b = _gid(m, own), _gid(m, other)
    reach = m.geom_size[a, 0] + m.geom_size[b, 0] - depth
    d.qpos[lay.nq : lay.nq + 3] += d.geom_xpos[a] + np.array([reach, 0, 0]) - d.geom_xpos[b]
    return d.qpos.copy()


def _manual_max_force(m: mujoco.MjModel, qpos: np.ndarray, pairs, substeps: int) -> float:
    """Max over substeps of the summed ``mj_contactForce`` normal of contacts between ``pairs``."""
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    want = {tuple(sorted(p)) for p in pairs}
    f, best = np.zeros(6), 0.0
    for _ in range(substeps):
        mujoco.mj_step(m, d)  # the step's forward pass computes the forces of the pre-step state
        tot = 0.0
        for i in range(d.ncon):
            if tuple(sorted(d.contact[i].geom)) in want:
                mujoco.mj_contactForce(m, d, i, f)
                tot += f[0]
        best = max(best, tot)
    return best


def test_glove_damage_equals_clipped_mj_contact_force():
    phys, m = _c_physics(BOX)
    qpos = _pressing(BOX, "p0_right_hand", "p1_head", depth=0.03)
    forces = phys.host_step(
        qpos[None].astype(np.float32),
        np.zeros((1, m.nv), np.float32),
        np.zeros((1, m.nv), np.float32),
        np.zeros((1, m.nu), np.float32),
    )[4]
    ref = _manual_max_force(m, qpos, A.channels(BOX, m)[0].pairs, 4)
    assert ref > 200.0  # a 3 cm overlap is a hard hit: the clip matters
    np.testing.assert_allclose(forces[0, 0], ref, rtol=1e-4)
    assert forces[0, 1] == 0.0  # player 1 did not score
    # The task's damage: clipped at 200 N, dealt minus received.
    env = _env("boxing")
    frame = env.frames_of(jnp.asarray(qpos, jnp.float32), jnp.zeros(m.nv))
    qv = jnp.zeros((2, env.layout.nv))
    out = env.task.step(
        env.task.init(None, frame),
        frame,
        frame,
        jnp.asarray(forces[0]),
        jnp.zeros(2, bool),
        qv,
        qv,
        jnp.asarray(10),
        None,
    )
    np.testing.assert_allclose(out.rewards[:, 0], [200.0, -200.0])
    np.testing.assert_allclose(out.info["damage_dealt"], [200.0, 0.0])


def test_hit_on_a_non_target_link_scores_nothing():
    """A glove pressed on the opponent's upper arm (a blocking pair: real force, no score)."""
    phys, m = _c_physics(BOX)
    qpos = _pressing(BOX, "p0_right_hand", "p1_left_upper_arm")
    blocked = _manual_max_force(m, qpos, [(_gid(m, "p0_right_hand"), _gid(m, "p1_left_upper_arm"))], 4)
    assert blocked > 10.0
    out = phys.host_step(
        qpos[None].astype(np.float32),
        np.zeros((1, m.nv), np.float32),
        np.zeros((1, m.nv), np.float32),
        np.zeros((1, m.nu), np.float32),
    )
    np.testing.assert_array_equal(out[4], 0.0)


def test_mjx_and_mujoco_c_scoring_forces_agree():
    cfg = FENCE
    phys, m = _c_physics(cfg)
    mx = mjx.put_model(m)
    px = backends.MJXPhysics(m, mx, 4, A.channels(cfg, m))
    # Player 0's blade tip (the zero pose holds it horizontal, along +x) on player 1's torso.
    qpos = _pressing(cfg, "p0_sword_blade", "p1_torso", depth=0.005)
    c = phys.host_step(
        qpos[None].astype(np.float32),
        np.zeros((1, m.nv), np.float32),
        np.zeros((1, m.nv), np.float32),
        np.zeros((1, m.nu), np.float32),
    )[4][0]
    with jit_enabled():
        d = mjx.make_data(mx).replace(qpos=jnp.asarray(qpos, jnp.float32))
        _, ground, fx = jax.jit(px.step_forces)(d, jnp.zeros(m.nu))
    assert c[0] > 1.0 and c[1] == 0.0
    np.testing.assert_allclose(np.asarray(fx), c, rtol=2e-2, atol=1e-2)


def _scripted_hit(sport: str, sim_hz: float, speed: float, lateral: float) -> np.ndarray:
    """Player 0 lunges at ``speed`` (m/s) with its glove (arm straight ahead) or blade tip leading at
    player 1's chest, from 10 cm away; returns each control step's two channel forces [steps, 2]."""
    cfg = A.ArenaConfig(sport=sport)
    phys, m = _c_physics(cfg, sim_hz, int(round(sim_hz / 30)))
    lay = A.layout(cfg)
    d = mujoco.MjData(m)
    jid = lambda n: m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)]
    d.qpos[jid("p0_right_shoulder_y")] = -np.pi / 2  # the arm straight ahead
    if sport == "fencing":
        d.qpos[jid("p0_right_hand_y")] = np.pi / 2  # the blade along the arm
    d.qpos[[2, lay.nq + 2]] += 0.02
    yaw = np.array([0.0, 0.0, 0.0, 1.0])  # player 1 turned 180 degrees to face player 0
    d.qpos[lay.nq + 3 : lay.nq + 7] = yaw
    mujoco.mj_kinematics(m, d)
    if sport == "boxing":
        tip, r = d.geom_xpos[_gid(m, "p0_right_hand")], m.geom_size[_gid(m, "p0_right_hand"), 0]
    else:
        sword = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "p0_sword")
        tip, r = d.xpos[sword], 0.0
        assert d.xmat[sword].reshape(3, 3)[0, 0] > 0.99  # the blade points along +x
    chest = d.geom_xpos[_gid(m, "p1_torso")]
    gap = 0.10 + r + m.geom_size[_gid(m, "p1_torso"), 0]
    d.qpos[lay.nq : lay.nq + 3] += tip + np.array([gap, lateral, 0.0]) - chest
    qvel = np.zeros(m.nv)
    qvel[0] = speed
    q, v = d.qpos[None].astype(np.float32), qvel[None].astype(np.float32)
    w = np.zeros((1, m.nv), np.float32)
    target = np.concatenate([d.qpos[7 : lay.nq], d.qpos[lay.nq + 7 :]])[None].astype(np.float32)
    out = []
    for _ in range(6):
        q, v, w, _, f = phys.host_step(q, v, w, target)
        out.append(f[0])
    return np.asarray(out)


@pytest.mark.parametrize("sport,speed", [("boxing", 8.0), ("fencing", 10.0)])
def test_scripted_punch_and_thrust_always_register_a_touch(sport, speed):
    """Calibration (recorded in ``physics/arena.py``): a glove at 8 m/s and a blade tip at 10 m/s
    register a touch of at least the 1 N threshold at 120, 240 and 480 Hz, hit centrally or 4 cm off."""
    for hz in (120.0, 240.0, 480.0):
        for lateral in (0.0, 0.04):
            f = _scripted_hit(sport, hz, speed, lateral)
            assert f[:, 0].max() >= 1.0, (sport, hz, lateral, f[:, 0])
            first = int(np.argmax(f[:, 0] >= 1.0))
            # Until then the defender, standing still, scores nothing (later the lunging body
            # runs into its hanging gloves).
            assert f[: first + 1, 1].max() == 0.0


def _arm_punch(sim_hz: float, speed: float, lateral: float, lead_s: float = 0.1) -> np.ndarray:
    """Player 0 stands still and punches with the arm only: shoulder and elbow velocities (least
    squares through the glove's Jacobian) that move the glove at ``speed`` straight at player 1's
    chest 10 cm ahead, and PD targets that lead the pose along them by ``lead_s`` (the servo
    drives the punch). Returns each control step's scoring force of player 0 [steps]."""
    cfg = A.ArenaConfig(sport="boxing")
    phys, m = _c_physics(cfg, sim_hz, int(round(sim_hz / 30)))
    lay = A.layout(cfg)
    d = mujoco.MjData(m)
    joint = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)
    d.qpos[m.jnt_qposadr[joint("p0_right_shoulder_y")]] = -np.pi / 2 + 0.6  # the arm forward, low
    d.qpos[m.jnt_qposadr[joint("p0_right_elbow")]] = -1.2  # and bent
    d.qpos[[2, lay.nq + 2]] += 0.02
    d.qpos[lay.nq + 3 : lay.nq + 7] = [0.0, 0.0, 0.0, 1.0]  # player 1 faces player 0
    mujoco.mj_forward(m, d)
    glove = _gid(m, "p0_right_hand")
    arm = [m.jnt_dofadr[joint(f"p0_right_{n}")] for n in ("shoulder_x", "shoulder_y", "shoulder_z", "elbow")]
    jac = np.zeros((3, m.nv))
    mujoco.mj_jacGeom(m, d, jac, None, glove)
    qd = np.linalg.lstsq(jac[:, arm], np.array([speed, 0.0, 0.0]), rcond=None)[0]
    np.testing.assert_allclose(jac[:, arm] @ qd, [speed, 0.0, 0.0], atol=1e-9)
    gap = 0.10 + m.geom_size[glove, 0] + m.geom_size[_gid(m, "p1_torso"), 0]
    d.qpos[lay.nq : lay.nq + 3] += d.geom_xpos[glove] + np.array([gap, lateral, 0.0]) - d.geom_xpos[_gid(m, "p1_torso")]
    qvel = np.zeros(m.nv)
    qvel[arm] = qd
    target = np.concatenate([d.qpos[7 : lay.nq], d.qpos[lay.nq + 7 :]])
    target[np.asarray(arm) - 6] += lead_s * qd
    q, v, w = d.qpos[None].astype(np.float32), qvel[None].astype(np.float32), np.zeros((1, m.nv), np.float32)
    out = []
    for _ in range(6):
        q, v, w, _, f = phys.host_step(q, v, w, target[None].astype(np.float32))
        out.append(f[0, 0])
    return np.asarray(out)


def test_scripted_arm_only_punch_registers_a_touch():
    """Calibration (recorded in ``physics/arena.py``): an arm-only punch, the body still, with the
    glove at 8 m/s registers a touch at 120, 240 and 480 Hz, centrally or 4 cm off, and saturates
    the 200-N damage clip; at 2 m/s it still touches."""
    for hz in (120.0, 240.0, 480.0):
        for lateral in (0.0, 0.04):
            f = _arm_punch(hz, 8.0, lateral)
            assert f.max() >= 200.0, (hz, lateral, f)
        assert _arm_punch(hz, 2.0, 0.0).max() >= 1.0, hz


def _env(sport: str, backend: str = "mujoco", **kw) -> BoutEnv:
    ss = sport == "fencing"
    clip = make_test_clip(num_frames=40, root_vel=(0.0, 0.0, 0.0), sword_shield=ss)
    lib = MotionLib.from_clips([clip])
    kw.setdefault("task", TaskConfig(name=sport))
    cfg = EnvConfig(
        physics=PhysicsConfig(sim_hz=120.0, sword_shield=ss, backend=backend),
        init_motions=("x",),
        groups=(),
        players=2,
        arena=A.ArenaConfig(sport=sport),
        policy_frames=1,
        **kw,
    )
    return BoutEnv(cfg, init_lib=lib)


def _frames(env: BoutEnv, xy, yaw=(0.0, np.pi)) -> object:
    """Link frames of both players in the zero pose at roots ``xy`` [2, 2] with headings ``yaw``."""
    m = env.mj
    nq = env.layout.nq
    q1 = np.asarray(m.qpos0[:nq], np.float32)
    qs = [
        place(jnp.asarray(q1), jnp.zeros(env.layout.nv), jnp.asarray(p, jnp.float32), jnp.asarray(a))[0]
        for p, a in zip(np.asarray(xy, np.float32), yaw)
    ]
    return env.frames_of(jnp.concatenate(qs), jnp.zeros(m.nv))


def test_boxing_stuck_and_rope_timers():
    env = _env("boxing")
    task, dt = env.task, env.dt
    limit = int(np.floor(task.sub.stuck_seconds / dt)) + 1  # > 5 s: the 151st step at 30 Hz
    qv = jnp.zeros((2, env.layout.nv))
    close = _frames(env, [[0.0, 0.0], [0.3, 0.0]])
    with jit_enabled():  # 2 x 151 steps: compiled once, not dispatched op by op
        step = jax.jit(lambda g, f, t: task.step(g, f, f, jnp.zeros(2), jnp.zeros(2, bool), qv, qv, t, None))
    g = task.init(None, close)
    for t in range(1, limit + 1):
        with jit_enabled():
            out = step(g, close, jnp.asarray(t))
        g = out.goal
        assert bool(out.terminated.any()) == (t == limit), t
    np.testing.assert_array_equal(out.terminated, [True, True])  # a clinch penalises both
    np.testing.assert_allclose(out.rewards[:, 4], [-1.0, -1.0])
    # Near the ropes: only that player, after the same time; moving away resets its timer.
    roped = _frames(env, [[2.4, 0.0], [0.0, 0.0]])
    g = task.init(None, roped)
    for t in range(1, limit + 1):
        with jit_enabled():
            out = step(g, roped, jnp.asarray(t))
        g = out.goal
    np.testing.assert_array_equal(out.terminated, [True, False])
    free = _frames(env, [[1.0, 0.0], [0.0, 0.0]])
    out = task.step(dataclasses.replace(g), free, free, jnp.zeros(2), jnp.zeros(2, bool), qv, qv, jnp.asarray(1), None)
    np.testing.assert_array_equal(out.goal.rope_steps, [0, 0])


def test_fencing_rules_on_scripted_touch_sequences():
    env = _env("fencing")
    task = env.task
    window = int(round(task.sub.counter_seconds / env.dt))

    def run(touches):
        g = task.init(None, None)
        for t, touch in enumerate(touches, 1):
            g, ended, win = task.rules(g, jnp.asarray(touch), jnp.asarray(t))
            if bool(ended):
                return t, np.asarray(win)
        return None, None

    none = [(False, False)]
    # A lone touch by player 0 at step 5 wins on the first step after the 1-s window.
    t, win = run(none * 4 + [(True, False)] + none * (window + 5))
    assert t == 5 + window + 1 and list(win) == [1.0, -1.0]
    # Counter-touches inside the window, up to exactly 1 s later: a draw, at the counter.
    for k in (1, window - 1, window):
        t, win = run(none * 4 + [(False, True)] + none * (k - 1) + [(True, False)] + none * (window + 5))
        assert t == 5 + k and list(win) == [0.0, 0.0], k
    # One step later: too late, the first toucher has won.
    t, win = run(none * 4 + [(False, True)] + none * window + [(True, False)] + none * 5)
    assert t == 5 + window + 1 and list(win) == [-1.0, 1.0]
    # Simultaneous touches: a draw at once.
    t, win = run(none * 3 + [(True, True)] + none * 3)
    assert t == 4 and list(win) == [0.0, 0.0]
    # No touch: no result.
    assert run(none * (window + 3))[0] is None


def test_fencing_out_of_area_ends_the_bout_with_a_penalty():
    env = _env("fencing")
    task = env.task
    qv = jnp.zeros((2, env.layout.nv))
    f = _frames(env, [[-2.0, 1.2], [2.0, 0.0]])  # player 0 is 0.2 m off the 2-m-wide piste
    out = task.step(task.init(None, f), f, f, jnp.zeros(2), jnp.zeros(2, bool), qv, qv, jnp.asarray(3), None)
    np.testing.assert_array_equal(out.terminated, [True, False])
    np.testing.assert_allclose(out.rewards[:, 2], [-1.0, 0.0])


@pytest.mark.parametrize("sport", ["boxing", "fencing"])
def test_players_see_mirror_images_in_a_mirrored_scene(sport):
    """Player 1 = player 0 turned 180 degrees about the arena's centre: identical observations."""
    env = _env(sport)
    f = _frames(env, [[-1.0, 0.3], [1.0, -0.3]], yaw=(0.2, 0.2 + np.pi))
    state = BoutState(data=None, frame=f, steps=jnp.zeros((), jnp.int32), rng=None, goal=env.task.init(None, f))
    obs = np.asarray(env.policy_obs(state))
    assert obs.shape == (2, env.obs_size)
    np.testing.assert_allclose(obs[0], obs[1], atol=2e-5)
    # Not trivially equal: a different placement of player 1 changes player 0's view.
    f2 = _frames(env, [[-1.0, 0.3], [1.5, -0.3]], yaw=(0.2, 0.2 + np.pi))
    obs2 = np.asarray(env.policy_obs(state.replace(frame=f2)))
    assert np.abs(obs2[0] - obs[0]).max() > 0.1


def _swap(env: BoutEnv, s: BoutState) -> BoutState:
    swap = lambda x, n: jnp.concatenate([x[n:], x[:n]])
    lay = env.layout
    data = s.data.replace(
        qpos=swap(s.data.qpos, lay.nq),
        qvel=swap(s.data.qvel, lay.nv),
        qacc_warmstart=swap(s.data.qacc_warmstart, lay.nv),
    )
    return s.replace(
        data=data,
        frame=jax.tree.map(lambda x: x[::-1], s.frame),
        goal=s.goal.replace(rope_steps=s.goal.rope_steps[::-1], hit_wait=s.goal.hit_wait[::-1]),
    )


def test_swapping_sides_swaps_the_results_and_bouts_have_no_nan():
    env = _env("boxing")
    with jit_enabled():
        reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
        s, obs = reset(jax.random.split(jax.random.PRNGKey(3), 8))
        sw = jax.vmap(lambda x: _swap(env, x))(s)
        # Each player's own view is the same after the swap, except its position and facing in
        # the arena, which it sees from its side (player 1's view is turned by 180 degrees).
        flip = np.ones(env.obs_size)
        flip[env.body_obs_size : env.body_obs_size + 4] = -1.0
        np.testing.assert_allclose(jax.vmap(env.policy_obs)(sw), obs[:, ::-1] * flip, atol=1e-5)
        rng = np.random.default_rng(0)
        for _t in range(12):
            a = jnp.asarray(rng.normal(0, 0.3, (8, 2, env.action_size)), jnp.float32)
            s, out = step(s, a)
            sw, out_sw = step(sw, a[:, ::-1])
            for x in (out.obs, out.task_reward):
                assert np.all(np.isfinite(np.asarray(x)))
            np.testing.assert_allclose(out_sw.task_reward[:, ::-1], out.task_reward, rtol=1e-3, atol=1e-2)
            np.testing.assert_array_equal(out_sw.terminated[:, ::-1], out.terminated)


def _learner(sport: str = "boxing", **kw):
    from jaxmotion.training.learner import NetConfig, PPOConfig, TrainConfig
    from jaxmotion.training.runs import make_learner

    env = _env(
        sport,
        task=TaskConfig(name=sport, boxing=dataclasses.replace(TaskConfig().boxing, start_distance=(0.7, 0.9))),
        episode_steps=30,
    )
    cfg = TrainConfig(
        env=env.cfg,
        net=NetConfig(policy_hidden=(16,), critic_hidden=(16,)),
        ppo=PPOConfig(
            num_envs=2,
            horizon=4,
            minibatch_size=8,
            multi_objective=False,
            terminate_reward=None,
            absorbing_termination=False,
        ),
        **kw,
    )
    return make_learner(cfg, env=env)


def test_self_play_iteration_and_an_antisymmetric_evaluation(tmp_path):
    from jaxmotion.evaluation.bouts import play, write_bout_html

    learner = _learner()
    assert learner.players == 2 and learner.cfg.samples_per_iteration == 2 * 4 * 2
    with jit_enabled():
        ts, ts2 = learner.init(jax.random.PRNGKey(0)), learner.init(jax.random.PRNGKey(1))  # one compile
        _, traj = jax.eval_shape(learner.rollout, ts)
        assert traj.obs.shape == (4, 4, learner.env.obs_size) and traj.task_reward.shape == (4, 4, 5)
        new, m = jax.jit(learner.iteration)(ts)
        assert all(np.all(np.isfinite(np.asarray(v))) for v in jax.tree.leaves(m))
        assert int(new.iteration) == 1
        ab, ro = play(learner, ts, (learner, ts2), bouts=8)  # bouts as long as the config's round, 30 steps
        ba, _ = play(learner, ts2, (learner, ts), bouts=8, steps=30)
    # Pairs of bouts share a start state with the sides swapped: A vs B is exactly -(B vs A).
    assert ab["damage_diff_mean"] == pytest.approx(-ba["damage_diff_mean"], abs=1e-3)
    assert (ab["wins"], ab["draws"], ab["losses"]) == (ba["losses"], ba["draws"], ba["wins"])
    assert ab["falls"] == {"self": ba["falls"]["opponent"], "opponent": ba["falls"]["self"]}
    assert ab["falls"]["self"] + ab["falls"]["opponent"] > 0  # something happened in these bouts
    assert ab["round_s"] == pytest.approx(1.0) and ab["minutes_played"] <= 8 / 60
    assert ab["falls_per_minute"]["self"] == pytest.approx(ab["falls"]["self"] / ab["minutes_played"])
    assert ro["qpos"].shape[:2] == (30, 8) and np.all(np.isfinite(ro["qpos"]))
    page = write_bout_html(learner, ro, tmp_path / "bout.html").read_text()
    assert "player 0" in page and "player 1" in page


def test_self_play_on_a_frozen_imitation_policy(tmp_path, data_dir):
    """``boxing/selfplay_meta``: both players act through the shared incremental policy on a frozen
    one-character imitation policy (``policy_frames=1``, the bout's body state): each player's
    meta action is that policy's on the player's own body observation, the policy starts as
    w * a_meta, and an iteration leaves the imitation policy as it was."""
    from jaxmotion.training import checkpoint as ckpt
    from jaxmotion.envs.humanoid import GroupConfig
    from jaxmotion.training.learner import DiscConfig, Learner, NetConfig, PPOConfig, TrainConfig

    walk = ("compositemotion/locomotion/lafan1_walk1_subject1_100_1170.json",)
    icfg = TrainConfig(
        env=EnvConfig(
            init_motions=walk, groups=(GroupConfig(name="full", motions=walk),), policy_frames=1, episode_steps=20
        ),
        net=NetConfig(policy_hidden=(16,), critic_hidden=(16,), disc_hidden=(8,), disc_heads=2),
        ppo=PPOConfig(num_envs=4, horizon=2, minibatch_size=8),
        disc=DiscConfig(minibatch_size=8),
    )
    with jit_enabled():
        meta_ts = Learner(icfg).init(jax.random.PRNGKey(3))
    mean = meta_ts.policy_params["params"]["mean"]  # actions far from zero, so that following shows
    meta_ts = meta_ts.replace(
        policy_params={"params": {**meta_ts.policy_params["params"], "mean": {**mean, "kernel": 20.0 * mean["kernel"]}}}
    )
    run = tmp_path / "imitate" / "boxing" / "20260101-000000"
    ckpt.write_config(run, "imitate/boxing", icfg)
    mgr = ckpt.manager(run)
    ckpt.save(mgr, 1, meta_ts)
    mgr.close()
    learner = _learner(meta=str(run.parent))
    body = learner.env.body_obs_size
    with jit_enabled():
        ts = learner.init(jax.random.PRNGKey(0))
        a, _, a_meta = jax.jit(lambda o: learner.act(ts, o, None))(ts.obs)
        ref = jax.jit(lambda o: learner.meta.learner.act(ts.meta, o, None)[0])(ts.obs[..., :body])
        new, m = jax.jit(learner.iteration)(ts)
    assert a_meta.shape == (2, 2, learner.env.action_size)
    np.testing.assert_allclose(a_meta, ref, atol=1e-6)
    assert float(np.abs(a_meta).mean()) > 0.3
    np.testing.assert_allclose(a, 1 / (1 + np.exp(-3.0)) * a_meta, atol=0.02)
    assert all(np.all(np.isfinite(np.asarray(v))) for v in jax.tree.leaves(m))
    for x, y in zip(jax.tree.leaves(new.meta), jax.tree.leaves(ts.meta)):
        np.testing.assert_array_equal(x, y)


def test_two_player_config_errors_are_clear():
    lib = MotionLib.from_clips([make_test_clip(num_frames=10)])
    base = dict(init_motions=("x",), groups=(), players=2, task=TaskConfig(name="fencing"))
    with pytest.raises(ValueError, match="sword_shield"):
        BoutEnv(EnvConfig(arena=A.ArenaConfig(sport="fencing"), **base), init_lib=lib)
    with pytest.raises(ValueError, match="arena.sport"):
        BoutEnv(EnvConfig(arena=A.ArenaConfig(sport="boxing"), **base), init_lib=lib)
    with pytest.raises(ValueError, match="not one of"):
        A.ArenaConfig(sport="tennis")
    with pytest.raises(ValueError, match="two-player task"):
        BoutEnv(
            EnvConfig(arena=A.ArenaConfig(sport="boxing"), **dict(base, task=TaskConfig(name="location"))), init_lib=lib
        )
