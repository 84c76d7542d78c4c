"""``python -m jaxmotion.play``: policy switching and target steering without a display, and the
clear exit where there is no display."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import REPO, jit_enabled
from jaxmotion.viz import play
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.tasks import HeadingConfig, TaskConfig
from jaxmotion.training.learner import DiscConfig, Learner, NetConfig, PPOConfig, TrainConfig


def _learner(task: str) -> Learner:
    lib = MotionLib.from_clips([make_test_clip(30, 30.0, root_vel=(0.0, 0.0, 0.0), root_height=0.87)])
    # No fall termination: an untrained character that fell mid-test restarted with a new goal,
    # and the steering test could only skip (it did with the 16-iteration contact solver).
    env_cfg = EnvConfig(
        groups=(GroupConfig(name="full"),),
        episode_steps=4,
        policy_frames=2,
        early_termination=False,
        task=TaskConfig(name=task, heading=HeadingConfig(speed_range=(1.0, 1.5))),
    )
    cfg = TrainConfig(
        env=env_cfg,
        net=NetConfig(policy_hidden=(8,), critic_hidden=(8,), disc_hidden=(8,), disc_heads=2),
        ppo=PPOConfig(num_envs=2, horizon=2, minibatch_size=4),
        disc=DiscConfig(minibatch_size=4),
    )
    return Learner(cfg, env=HumanoidEnv(env_cfg, motion_libs=(lib,), init_lib=lib))


@pytest.fixture(scope="module")
def aim_player():
    learner = _learner("aim+location")
    with jit_enabled():
        a, b = (learner.init(jax.random.PRNGKey(s)) for s in (0, 1))
        yield play.Player(learner, [a, b], seed=0)


def test_keys_switch_policies_and_keep_the_state(aim_player):
    p = aim_player
    with jit_enabled():
        p.tick()
        before = p.state
        p.key(ord("2"))
        assert p.active == 1
        p.key(ord("9"))  # there is no ninth policy: ignored
        assert p.active == 1
        # The switch only changes the acting parameters: the step from the same state equals
        # what policy 2 does from it, and differs from what policy 1 does.
        qpos_b, _, _ = p.tick()
        ref_b = p._steps[1](p.policies[1], before, jnp.zeros(2), jnp.zeros(()))[1]
        ref_a = p._steps[0](p.policies[0], before, jnp.zeros(2), jnp.zeros(()))[1]
    np.testing.assert_allclose(qpos_b, ref_b, atol=1e-6)
    assert not np.allclose(qpos_b, ref_a, atol=1e-4)


def test_arrows_move_the_target_and_page_keys_turn_the_aim(aim_player):
    p = aim_player
    with jit_enabled():
        p.tick()
        target0, aim0 = np.asarray(p.state.goal.loc.target), np.asarray(p.state.goal.aim)
        for code in (play.KEY_RIGHT, play.KEY_RIGHT, play.KEY_UP, play.KEY_PAGE_UP):
            p.key(code)
        _, markers, _ = p.tick()
        target1, aim1 = np.asarray(p.state.goal.loc.target), np.asarray(p.state.goal.aim)
        # The steered goal never runs out while playing: many steps later it is still there.
        for _ in range(6):
            p.tick()
        target_later = np.asarray(p.state.goal.loc.target)
    if not np.allclose(target1, target0 + [1.0, 0.5], atol=1e-5):
        pytest.skip("the character fell on this step and restarted with a new goal")
    np.testing.assert_allclose(markers["target"][0, :2], target1, atol=1e-6)
    c, s = math.cos(play.TURN_STEP_RAD), math.sin(play.TURN_STEP_RAD)
    np.testing.assert_allclose(aim1, [c * aim0[0] - s * aim0[1], s * aim0[0] + c * aim0[1], aim0[2]], atol=1e-5)
    if p.restarts == 0:
        np.testing.assert_allclose(target_later, target1, atol=1e-6)
    # Past the 4-step episode limit with no restart: the time limit does not apply in play.
    assert p.restarts > 0 or int(p.state.steps) <= p.env.cfg.episode_steps


def test_heading_is_turned_and_its_speed_kept_in_range():
    from jaxmotion.motion.observations import LinkFrames
    from jaxmotion.physics.character import character
    from jaxmotion.tasks import make_task

    class _Env:
        dt = 1.0 / 30.0

    _Env.character = character()
    task = make_task(TaskConfig(name="heading", heading=HeadingConfig(speed_range=(1.0, 1.5))), _Env())
    nb = len(_Env.character.body_names)
    frame = LinkFrames(
        jnp.zeros((nb, 3)), jnp.tile(jnp.asarray([1.0, 0, 0, 0]), (nb, 1)), jnp.zeros((nb, 3)), jnp.zeros((nb, 3))
    )
    goal = task.init(jax.random.PRNGKey(0), frame)
    d0 = np.asarray(goal.direction)
    steered = task.steer(goal, frame, jnp.asarray(10.0 * d0), jnp.asarray(math.pi / 2))
    np.testing.assert_allclose(np.asarray(steered.direction), [-d0[1], d0[0]], atol=1e-6)
    assert float(steered.speed) == pytest.approx(1.5)  # pushed along the heading, held at the top
    assert int(steered.timer) == task.cfg.heading.timer_range[1]  # a steered goal does not expire


def test_no_display_is_one_clear_line():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["JAX_PLATFORMS"] = "cpu"
    r = subprocess.run(
        [sys.executable, "-m", "jaxmotion.play", "runs/none/0"],
        env=env,
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2
    assert "no display" in r.stderr and "--video" in r.stderr
    assert "Traceback" not in r.stderr


def test_runs_with_other_spaces_cannot_take_turns():
    from jaxmotion.training.runs import spaces_mismatch

    loc, head = _learner("location"), _learner("heading")
    assert spaces_mismatch([("a", loc), ("b", _learner("location"))]) is None
    msg = spaces_mismatch([("a", loc), ("b", head)])
    assert msg and "b has observation/action sizes" in msg and "cannot take turns" in msg
