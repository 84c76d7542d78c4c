"""Policy switching (paper Fig. 9): policies that share observation and action spaces take turns
on the same environments; only the acting parameters change between two control steps."""

from __future__ import annotations

import base64
import json

import jax
import numpy as np
import pytest

from jaxmotion.evaluation.imitation import switch_metrics
from jaxmotion.evaluation.rollout import acting_policy, rollout
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.tasks import TaskConfig
from jaxmotion.training.learner import DiscConfig, Learner, NetConfig, PPOConfig, TrainConfig


def _learner() -> Learner:
    lib = MotionLib.from_clips([make_test_clip(30, 30.0, root_vel=(1.0, 0.0, 0.0), root_height=0.87)])
    env_cfg = EnvConfig(
        groups=(GroupConfig(name="full"),), episode_steps=20, policy_frames=2, task=TaskConfig(name="location")
    )
    cfg = TrainConfig(
        env=env_cfg,
        net=NetConfig(policy_hidden=(8,), critic_hidden=(8,), disc_hidden=(8,), disc_heads=2, init_log_std=0.0),
        ppo=PPOConfig(num_envs=2, horizon=2, minibatch_size=4),
        disc=DiscConfig(minibatch_size=4),
    )
    return Learner(cfg, env=HumanoidEnv(env_cfg, motion_libs=(lib,), init_lib=lib))


STEPS, EVERY = 6, 2


@pytest.fixture(scope="module")
def switched():
    """A switched rollout (A acts for 2 steps, then B for 2, then A again) and the same by hand
    on one env batch: ``(learner, ro, qpos, acts, other)``; one compilation serves every test."""
    from conftest import jit_enabled

    learner = _learner()
    with jit_enabled():
        a, b = (learner.init(jax.random.PRNGKey(s)) for s in (0, 1))
        ro = rollout(learner, (a, b), episodes=2, steps=STEPS, switch_steps=EVERY)
        reset, step = jax.jit(jax.vmap(learner.env.reset)), jax.jit(jax.vmap(learner.env.step))
        act = jax.jit(lambda p, o: learner.act(p, o, None)[0])
        state, obs = reset(jax.random.split(jax.random.split(jax.random.PRNGKey(0))[0], 2))
        qpos, acts = [np.asarray(state.data.qpos)], []
        for t in range(STEPS):
            action = act((a, b)[(t // EVERY) % 2], obs)
            acts.append(np.asarray(action))
            state, out = step(state, action)
            obs = out.obs
            qpos.append(np.asarray(state.data.qpos))
        other = np.asarray(act(b, obs))
    return learner, ro, np.stack(qpos), acts, other


def test_switching_keeps_the_env_state_and_changes_only_the_policy(switched):
    learner, ro, qpos, acts, other = switched
    np.testing.assert_allclose(ro["qpos"], qpos, atol=1e-4)
    assert not np.allclose(acts[-1], other)  # the two policies do act differently
    np.testing.assert_array_equal(ro["info"]["switch"][:, 0], [False, False, True, False, True, False])
    m = switch_metrics(ro, learner.env.dt)
    # Switches are counted in episodes still running; both are at the first switch (t = 2).
    assert m["switches"] == int((ro["info"]["switch"] & ro["stepped"]).sum()) >= 2
    assert 0 <= m["falls_after_switch"] <= 2


def test_the_acting_policy_is_recorded_per_frame(switched):
    """``acting`` [T+1, E] names the policy that acts from each recorded frame: A, A, B, B, A, A
    and then B, whose turn it would be; the qpos test above shows these are the ones that acted."""
    _, ro, *_ = switched
    assert ro["acting"].shape == (STEPS + 1, 2) and ro["acting"].dtype.kind == "i"
    for e in range(2):
        np.testing.assert_array_equal(ro["acting"][:, e], [0, 0, 1, 1, 0, 0, 1])
    # A switch (info) is the first step of a new turn: the acting index changes there.
    np.testing.assert_array_equal(ro["info"]["switch"][1:, 0], ro["acting"][1:-1, 0] != ro["acting"][:-2, 0])
    # Without switching (one state, or switch_steps 0) the first policy always acts.
    np.testing.assert_array_equal(acting_policy(np.arange(5), 0, 2), np.zeros(5))
    np.testing.assert_array_equal(acting_policy(np.arange(7), 3, 2), [0, 0, 0, 1, 1, 1, 0])


def test_switched_markers_and_html_show_who_acts(switched, tmp_path):
    """The video's and the page's markers: the task's target, and a sphere over the head in the
    acting policy's colour only when several policies took turns; the page names the acting run
    per frame. Read back from the written file (no browser)."""
    from jaxmotion.viz import render as RD
    from jaxmotion.viz.replay_html import write_rollout_html

    learner, ro, *_ = switched
    n = int(ro["alive"][:, 0].sum())
    single = RD.rollout_markers(learner, ro, 0, n)
    assert set(single) == {"target"}  # the location task's goal: a single-policy video is unchanged
    both = RD.rollout_markers(learner, ro, 0, n, num_policies=2)
    assert set(both) == {"target", "acting0", "acting1"}
    head = ro["pos"][:n, 0, learner.env.character.body_index("head")]
    for t in range(n):
        drawn = [(seg, rgba) for seg, rgba, _ in RD.marker_list({k: v[t] for k, v in both.items()})]
        acting = [(seg, rgba) for seg, rgba in drawn if rgba in (RD.policy_rgba(0), RD.policy_rgba(1))]
        assert len(drawn) == 2 and len(acting) == 1  # the target and one sphere
        seg, rgba = acting[0]
        assert rgba == RD.policy_rgba(int(ro["acting"][t, 0]))
        np.testing.assert_allclose(seg[0], head[t] + [0, 0, RD.ACTING_HEIGHT_M], atol=1e-6)

    data = _page_data(write_rollout_html(learner, ro, tmp_path / "s.html", policies=("runs/a", "runs/b")))
    assert data["T"] == n and data["acting"] == ro["acting"][:n, 0].tolist()
    assert data["policies"] == [
        {"name": "runs/a", "rgba": list(RD.policy_rgba(0))},
        {"name": "runs/b", "rgba": list(RD.policy_rgba(1))},
    ]
    marks = {m["name"]: m for m in data["markers"]}
    assert set(marks) == {"target", "acting0", "acting1"}
    np.testing.assert_allclose(_f32(marks["target"]["seg"]).reshape(n, 2, 3), ro["markers"]["target"][:n, 0])
    assert marks["target"]["rgba"] == list(RD.MARKER_RGBA["target"])
    a1 = _f32(marks["acting1"]["seg"]).reshape(n, 2, 3)
    np.testing.assert_array_equal(np.isfinite(a1[:, 0, 0]), ro["acting"][:n, 0] == 1)
    plain = _page_data(write_rollout_html(learner, ro, tmp_path / "p.html"))
    assert plain["acting"] is None and [m["name"] for m in plain["markers"]] == ["target"]


def _page_data(path) -> dict:
    """The JSON payload of a replay page."""
    text = path.read_text()
    start = text.index('id="replay-data">') + len('id="replay-data">')
    return json.loads(text[start : text.index("</script>", start)])


def _f32(b64: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(b64), "<f4")
