"""Tasks: goal observations and rewards against hand computation on constructed states, goal
timers, extra terminations, the ω rule, and a quick check of every registered task in the env."""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
from jaxmotion.motion.observations import LinkFrames
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.tasks import TASKS, AimConfig, HeadingConfig, LocationConfig, TaskConfig, combine_weights, make_task
from jaxmotion.tasks.location import AimGoal, HeadingGoal, LocationGoal
from jaxmotion.training.learner import DiscConfig, Learner, NetConfig, PPOConfig, TrainConfig

NB = 15
DT = 1.0 / 30.0


class _Env:
    """What a task needs of its scene: the control step and the character."""

    dt = DT

    def __init__(self):
        from jaxmotion.physics.character import character

        self.character = character()


def _frame(xy=(0.0, 0.0), yaw=0.0, pos=None) -> LinkFrames:
    """Link frames with the root at ``xy`` (height 0.9) turned by ``yaw``; other links at the root."""
    p = np.zeros((NB, 3)) if pos is None else np.array(pos, float)
    p[0] = [xy[0], xy[1], 0.9]
    q = np.tile([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)], (NB, 1))
    z = np.zeros((NB, 3))
    return LinkFrames(*(jnp.asarray(a, jnp.float32) for a in (p, q, z, z)))


def _task(name, **kw):
    return make_task(TaskConfig(name=name, **kw), _Env())


def _loc_goal(target, timer=90, dist0=3.0):
    return LocationGoal(
        target=jnp.asarray(target, jnp.float32),
        timer=jnp.asarray(timer),
        dist0=jnp.asarray(dist0, jnp.float32),
        reached=jnp.zeros((), bool),
    )


# ---- target location --------------------------------------------------------------------
def test_location_goal_features_by_hand():
    task = _task("location")
    g = _loc_goal([3.0, 0.0], timer=90)
    # Facing +x, target 3 m ahead, 90 steps = 3 s left: direction (1, 0), speed 1 m/s, 3/3 = 1.
    np.testing.assert_allclose(task.observe(g, _frame()), [1.0, 0.0, 1.0, 1.0], atol=1e-6)
    # Facing +y: the target is to the right, (0, -1) in the heading frame.
    np.testing.assert_allclose(task.observe(g, _frame(yaw=math.pi / 2)), [0.0, -1.0, 1.0, 1.0], atol=1e-6)
    # 9 m away with 1 step left: speed clipped at 1.5 (walk's upper speed), distance term at 1.5.
    far = _loc_goal([0.0, 9.0], timer=1)
    np.testing.assert_allclose(task.observe(far, _frame()), [0.0, 1.0, 1.5, 1.5], atol=1e-6)


def test_location_reward_by_hand():
    task = _task("location")
    g = _loc_goal([3.0, 0.0], timer=90)  # wanted speed clip(3 / 3 s, 1.2, 1.5) = 1.2 m/s along +x
    # Moving at exactly the wanted velocity: 1.
    r = task.location_reward(g, jnp.zeros(2), jnp.array([1.2 * DT, 0.0]))
    assert float(r) == pytest.approx(1.0, abs=1e-6)
    # Standing still: exp(-3 * 1.2^2 / 1.2^2) = exp(-3).
    assert float(task.location_reward(g, jnp.zeros(2), jnp.zeros(2))) == pytest.approx(math.exp(-3), rel=1e-5)
    # Sideways at 1 m/s: |v - v*|^2 = 1 + 1.44.
    r = task.location_reward(g, jnp.zeros(2), jnp.array([0.0, DT]))
    assert float(r) == pytest.approx(math.exp(-3 * 2.44 / 1.44), rel=1e-5)
    # Inside the radius (0.5 m) the reward is 1 whatever the velocity.
    near = _loc_goal([0.3, 0.0])
    assert float(task.location_reward(near, jnp.zeros(2), jnp.array([0.0, -0.01]))) == 1.0


def test_location_timer_resamples_and_reports_success():
    task = _task("location")
    g = _loc_goal([0.2, 0.0], timer=2)
    out = task.step(g, _frame(), _frame(), jax.random.PRNGKey(0))
    assert int(out.goal.timer) == 1 and not bool(out.info["goal_ended"])
    assert bool(out.goal.reached)  # inside the radius
    out2 = task.step(out.goal, _frame(), _frame(), jax.random.PRNGKey(1))
    assert bool(out2.info["goal_ended"]) and bool(out2.info["goal_reached"])
    lo, hi = task.cfg.location.timer_range
    assert lo <= int(out2.goal.timer) < hi and not bool(out2.goal.reached)
    # The new target is v0 * timer / 30 away, v0 within its truncated range.
    d = float(jnp.linalg.norm(out2.goal.target))
    assert 0.0 <= d <= task.cfg.location.v0_range[1] * int(out2.goal.timer) * DT + 1e-5


def test_location_overshoot_terminates():
    task = _task("location")
    g = _loc_goal([3.0, 0.0], timer=90, dist0=3.0)
    assert not bool(task.step(g, _frame(), _frame((-2.9, 0.0)), jax.random.PRNGKey(0)).terminated)
    assert bool(task.step(g, _frame(), _frame((-3.1, 0.0)), jax.random.PRNGKey(0)).terminated)
    off = make_task(TaskConfig(name="location", location=LocationConfig(max_overshoot=0.0)), _Env())
    assert not bool(off.step(g, _frame(), _frame((-30.0, 0.0)), jax.random.PRNGKey(0)).terminated)


def test_location_goals_within_sixty_degrees_without_sharp_turns():
    task = make_task(TaskConfig(name="location", location=LocationConfig(sharp_turns=False)), _Env())
    yaw = 1.0
    goals = jax.vmap(lambda k: task.init(k, _frame(yaw=yaw)))(jax.random.split(jax.random.PRNGKey(0), 200))
    ang = np.arctan2(np.asarray(goals.target[:, 1]), np.asarray(goals.target[:, 0]))
    assert np.all(np.abs(ang - yaw) <= math.pi / 3 + 1e-4)


# ---- heading ----------------------------------------------------------------------------
def test_heading_features_and_reward_by_hand():
    task = _task("heading")
    g = HeadingGoal(direction=jnp.array([0.0, 1.0]), speed=jnp.asarray(1.2), timer=jnp.asarray(50), age=jnp.asarray(40))
    np.testing.assert_allclose(task.observe(g, _frame()), [0.0, 1.0, 1.2], atol=1e-6)
    np.testing.assert_allclose(task.observe(g, _frame(yaw=math.pi / 2)), [1.0, 0.0, 1.2], atol=1e-6)
    on = task.step(g, _frame(), _frame((0.0, 1.2 * DT)), jax.random.PRNGKey(0))
    assert float(on.rewards[0]) == pytest.approx(1.0, abs=1e-5)
    assert float(on.info["heading_error_deg"]) == pytest.approx(0.0, abs=0.1)
    # Along +x at 1.2 m/s: 90 degrees off, |v - v*|^2 = 2 * 1.44.
    off = task.step(g, _frame(), _frame((1.2 * DT, 0.0)), jax.random.PRNGKey(0))
    assert float(off.rewards[0]) == pytest.approx(math.exp(-6), rel=1e-4)
    assert float(off.info["heading_error_deg"]) == pytest.approx(90.0, abs=0.1)


# ---- aiming -----------------------------------------------------------------------------
def test_aim_reward_is_one_on_the_target_line():
    env = _Env()
    task = make_task(TaskConfig(name="aim+location"), env)
    ch = env.character
    aim = jnp.asarray(np.array([1.0, 1.0, 0.5]) / np.linalg.norm([1.0, 1.0, 0.5]), jnp.float32)
    pos = np.zeros((NB, 3))
    pos[ch.body_index("right_lower_arm")] = [0.1, -0.2, 1.3]
    pos[ch.body_index("right_hand")] = pos[ch.body_index("right_lower_arm")] + 0.26 * np.asarray(aim)
    r, ang = task.aim_reward(aim, _frame(pos=pos), jnp.zeros((), bool))
    assert float(r) == pytest.approx(1.0, abs=1e-5) and float(ang) == pytest.approx(0.0, abs=0.2)
    # Forearm pointing down instead: |e + L d* - h| = L |d* - (0,0,-1)|.
    pos[ch.body_index("right_hand")] = pos[ch.body_index("right_lower_arm")] + [0.0, 0.0, -0.26]
    r, _ = task.aim_reward(aim, _frame(pos=pos), jnp.zeros((), bool))
    want = math.exp(-2 * np.linalg.norm(np.asarray(aim) - [0, 0, -1]))
    assert float(r) == pytest.approx(want, rel=1e-4)
    # Inside the goal radius: raise the forearm, clip(z / 0.8, 0, 1); here it points down: 0.
    r, _ = task.aim_reward(aim, _frame(pos=pos), jnp.ones((), bool))
    assert float(r) == 0.0


def test_aim_features_zeroed_inside_radius_and_new_aim_with_new_goal():
    task = make_task(TaskConfig(name="aim+location", aim=AimConfig(yaw_deg=(30.0, 30.0), pitch_deg=(0.0, 0.0))), _Env())
    g = task.init(jax.random.PRNGKey(0), _frame())
    # Yaw 30 degrees left of the root-to-target direction, level.
    d = np.asarray(g.loc.target) / np.linalg.norm(np.asarray(g.loc.target))
    want = [
        math.cos(math.atan2(d[1], d[0]) + math.radians(30)),
        math.sin(math.atan2(d[1], d[0]) + math.radians(30)),
        0.0,
    ]
    np.testing.assert_allclose(g.aim, want, atol=1e-5)
    assert np.linalg.norm(np.asarray(g.loc.target)) > 0.5
    np.testing.assert_allclose(np.asarray(task.observe(g, _frame()))[4:], want, atol=1e-5)  # heading = world here
    inside = AimGoal(loc=_loc_goal([0.1, 0.0]), aim=g.aim)
    np.testing.assert_array_equal(np.asarray(task.observe(inside, _frame()))[4:], 0.0)
    expiring = AimGoal(loc=_loc_goal([3.0, 0.0], timer=1), aim=jnp.array([0.0, 0.0, 1.0]))
    out = task.step(expiring, _frame(), _frame(), jax.random.PRNGKey(3))
    assert float(out.goal.aim[2]) == pytest.approx(0.0, abs=1e-6)  # redrawn level with the new goal


# ---- ω ----------------------------------------------------------------------------------
def test_combine_weights_authors_rule():
    np.testing.assert_allclose(combine_weights((0.2, 0.3), (0.25, 0.25)), [0.2, 0.3, 0.25, 0.25])
    np.testing.assert_allclose(combine_weights((None, None), (0.5,)), [0.25, 0.25, 0.5])
    np.testing.assert_allclose(combine_weights((0.06, 0.24), (0.6, 0.1)), [0.06, 0.24, 0.6, 0.1])
    np.testing.assert_allclose(combine_weights((0.6, None, None), ()), [0.6, 0.2, 0.2])
    np.testing.assert_allclose(combine_weights((2.0, 6.0), (0.5,)), [0.125, 0.375, 0.5])
    with pytest.raises(ValueError):
        combine_weights((None,), (0.7, 0.4))


# ---- every registered task in the scene -------------------------------------------------
def _scene(task: str) -> HumanoidEnv:
    lib = MotionLib.from_clips([make_test_clip(30, 30.0, root_vel=(1.0, 0.0, 0.0), root_height=0.87)])
    cfg = EnvConfig(
        groups=(GroupConfig(name="upper"), GroupConfig(name="lower")),
        episode_steps=2,
        policy_frames=2,
        task=TaskConfig(name=task),
    )
    return HumanoidEnv(cfg, motion_libs=(lib, lib), init_lib=lib)


# track: tests/test_track.py; tennis (needs its racket and ball): tests/test_tennis.py; the
# two-player tasks (boxing, fencing): tests/test_bout.py
@pytest.mark.parametrize(
    "name", sorted(n for n in TASKS if n not in ("track", "tennis") and not getattr(TASKS[n], "two_player", False))
)
def test_every_task_quick_check(name):
    """Jitted and vmapped init/observe/step on moving frames: shapes, no NaN, rewards >= floor."""
    # Short goal timers, so every goal runs out and is redrawn within the loop.
    task = make_task(
        TaskConfig(name=name, location=LocationConfig(timer_range=(4, 8)), heading=HeadingConfig(timer_range=(4, 8))),
        _Env(),
    )
    frames = jax.vmap(lambda x, y: _frame())(jnp.zeros(3), jnp.zeros(3))
    goal = jax.jit(jax.vmap(task.init))(jax.random.split(jax.random.PRNGKey(0), 3), frames)
    observe, step = jax.jit(jax.vmap(task.observe)), jax.jit(jax.vmap(task.step))
    rng = jax.random.PRNGKey(1)
    for _t in range(12):
        rng, k, k_move = jax.random.split(rng, 3)
        moved = frames.replace(
            pos=frames.pos + jnp.concatenate([0.04 * jax.random.normal(k_move, (3, 1, 2)), jnp.zeros((3, 1, 1))], -1)
        )
        out = step(goal, frames, moved, jax.random.split(k, 3))
        frames, goal = moved, out.goal
        g = observe(goal, frames)
        assert g.shape == (3, task.goal_size) and bool(jnp.isfinite(g).all())
        assert out.rewards.shape == (3, len(task.reward_names)) and bool(jnp.isfinite(out.rewards).all())
        assert bool((out.rewards >= task.min_reward).all()) and out.terminated.shape == (3,)
        for v in out.info.values():
            assert v.shape == (3,) and bool(jnp.isfinite(jnp.asarray(v, jnp.float32)).all())
    assert len(task.weights()) == len(task.reward_names)
    summary = task.summary(jax.tree.map(lambda v: np.asarray(v)[None], out.info), np.ones((1, 3), bool))
    assert all(isinstance(v, (int, float)) for v in summary.values())


@pytest.fixture(scope="module")
def scene():
    lib = MotionLib.from_clips([make_test_clip(30, 30.0, root_vel=(1.0, 0.0, 0.0), root_height=0.87)])
    cfg = EnvConfig(
        groups=(GroupConfig(name="upper"), GroupConfig(name="lower")),
        episode_steps=2,
        policy_frames=2,
        task=TaskConfig(name="aim+location"),
    )
    return HumanoidEnv(cfg, motion_libs=(lib, lib), init_lib=lib)


def test_task_in_the_scene(scene):
    """The env carries the goal, appends its features, reports its rewards, redraws it on reset."""
    from conftest import jit_enabled

    env, task = scene, scene.task
    with jit_enabled():
        state, obs = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 2))
        step = jax.jit(jax.vmap(env.step))
        assert obs.shape == (2, env.body_obs_size + task.goal_size) and env.obs_size == obs.shape[1]
        goals = [state.goal.loc.target]
        for t in range(3):  # past the 2-step time limit: the automatic reset draws a new goal
            state, out = step(state, 0.3 * jax.random.normal(jax.random.PRNGKey(t), (2, env.action_size)))
            goals.append(state.goal.loc.target)
            assert out.obs.shape == obs.shape and out.task_reward.shape == (2, len(task.reward_names))
            assert bool(jnp.isfinite(out.obs).all()) and bool(jnp.isfinite(out.task_reward).all())
            if t == 0:  # no reset yet: the observation ends with the goal features of the state
                np.testing.assert_allclose(
                    out.obs[:, env.body_obs_size :],
                    jax.vmap(task.observe)(state.goal, jax.tree.map(lambda x: x[:, -1], state.hist)),
                    atol=1e-5,
                )
    np.testing.assert_array_equal(goals[1], goals[0])  # kept while the timer runs
    assert not np.allclose(goals[2], goals[1])  # the reset after step 2 drew new goals
    # What the video draws: the target on the floor and the aim as an arrow from the right hand.
    frame = jax.tree.map(lambda x: x[0, -1], state.hist)
    mk = task.markers(jax.tree.map(lambda x: x[0], state.goal), frame)
    np.testing.assert_allclose(mk["target"][0, :2], state.goal.loc.target[0])
    np.testing.assert_array_equal(mk["target"][0], mk["target"][1])
    hand = env.character.body_index("right_hand")
    np.testing.assert_allclose(mk["aim"][0], frame.pos[hand])
    np.testing.assert_allclose(mk["aim"][1] - mk["aim"][0], 0.6 * state.goal.aim[0], atol=1e-6)


def test_learner_makes_one_objective_per_task_reward(scene):
    env = scene
    cfg = TrainConfig(
        env=env.cfg,
        net=NetConfig(policy_hidden=(8,), critic_hidden=(8,), disc_hidden=(8,), disc_heads=2),
        ppo=PPOConfig(num_envs=2, horizon=2, minibatch_size=4),
        disc=DiscConfig(minibatch_size=4),
    )
    learner = Learner(cfg, env=env)
    assert learner.objective_names == ("upper", "lower", "location", "aim")
    assert learner.num_objectives == 4
    v = learner.critic.apply(learner.critic.init(jax.random.PRNGKey(0)), jnp.zeros((1, env.obs_size)))
    assert v.shape == (1, 4)
    # Goal features reach the networks raw; the body state is normalised and clipped.
    from jaxmotion.algos import normalizer as N

    obs = jnp.ones((1, env.obs_size)) * 7.0
    nobs = learner.normalize_obs(N.normalizer_init(env.body_obs_size), obs)
    np.testing.assert_allclose(nobs[0, env.body_obs_size :], 7.0)
    assert float(jnp.max(jnp.abs(nobs[0, : env.body_obs_size]))) <= cfg.ppo.obs_clip
    with pytest.raises(ValueError, match="location, aim"):
        Learner(dataclasses.replace(cfg, ppo=dataclasses.replace(cfg.ppo, objective_weights=(1.0, 1.0))), env=env)


def test_unknown_task_is_a_clear_error():
    with pytest.raises(ValueError, match="registered tasks"):
        make_task(TaskConfig(name="locaton"), _Env())


# ---- a short learning run ---------------------------------------------------------------
@pytest.mark.slow
def test_short_location_training_beats_untrained_policies():
    """A policy trained for a few CPU minutes on target location must end its episodes nearer
    the targets than untrained policies do, by more than the spread of untrained seeds."""
    from conftest import jit_enabled, train_scoring_last
    from jaxmotion.evaluation.imitation import rollout_metrics
    from jaxmotion.evaluation.rollout import rollout
    from jaxmotion.training.loop import make_mesh, make_train_chunk, shard_state

    iters, chunk, seeds, episodes = 400, 40, 3, 32
    stand = MotionLib.from_clips([make_test_clip(30, 30.0, root_vel=(0.0, 0.0, 0.0), root_height=0.87)])
    # Targets 1-2 m away, ahead within ±60 degrees; no fall termination, so getting closer (by a
    # step, a lean or a fall) is what the reward pays for. The discriminator's weight is small.
    loc = LocationConfig(
        v0_mean=0.5,
        v0_std=0.01,
        v0_range=(0.4, 0.6),
        timer_range=(60, 61),
        sharp_turns=False,
        max_overshoot=0.0,
        weight=0.9,
    )
    env_cfg = EnvConfig(
        groups=(GroupConfig(name="full"),),
        episode_steps=45,
        policy_frames=2,
        early_termination=False,
        task=TaskConfig(name="location", location=loc),
    )
    cfg = TrainConfig(
        env=env_cfg,
        net=NetConfig(
            policy_hidden=(64, 64),
            critic_hidden=(64, 64),
            disc_hidden=(64, 32),
            disc_heads=4,
            init_log_std=-1.7,
            state_dependent_std=False,
        ),
        ppo=PPOConfig(num_envs=32, horizon=8, minibatch_size=64, epochs=4, actor_lr=2e-4, critic_lr=1e-3),
        disc=DiscConfig(lr=1e-4, minibatch_size=64),
        iterations=iters,
        chunk=chunk,
    )

    def final_distance(learner, ts):
        ro = rollout(learner, ts, episodes=episodes, steps=env_cfg.episode_steps - 1)
        return float(np.mean(ro["info"]["distance"][-1])), rollout_metrics(learner, ro)["task"]

    with jit_enabled():
        learner = Learner(cfg, env=HumanoidEnv(env_cfg, motion_libs=(stand,), init_lib=stand))
        mesh = make_mesh(jax.devices()[:1])
        untrained = [shard_state(learner.init(jax.random.PRNGKey(s)), mesh) for s in range(seeds)]
        base = np.array([final_distance(learner, u)[0] for u in untrained])
        ts = jax.tree.map(lambda x: x.copy(), untrained[0])  # the chunk donates its input
        run = make_train_chunk(learner, mesh, chunk, ts)
        ts, last = train_scoring_last(run, ts, iters // chunk, lambda t: final_distance(learner, t))
        trained, summary = float(np.mean([d for d, _ in last])), last[-1][1]
    print(f"final distance to the target: untrained {base}, trained {[round(d, 3) for d, _ in last]}; {summary}")
    # Measured: untrained 1.26-1.57 m (their random falls scatter), trained 1.08 m after 240
    # iterations; with the 16-iteration contact solver untrained 1.20-1.73 m and 1.022 m at 240, a
    # margin of 0.08 m over the bar. Then 320 iterations and the last three chunks' policies
    # averaged: 1.022 / 0.768 / 0.811 m on an AMD host, 1.42 / 1.42 / 0.55 m on an Intel one
    # (the same untrained figures: training diverges with the CPU's float rounding). Now 400
    # iterations, 32 episodes per evaluation: untrained 1.20-1.76 m, trained 0.77 / 0.43 / 0.55 m
    # (Intel). Below the best untrained seed by 0.1 m, a margin none of the untrained seeds has
    # over another's best.
    assert trained < base.min() - 0.1
    assert summary["name"] == "location" and "mean_distance_m" in summary
