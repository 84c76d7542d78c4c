"""Bout rules without physics: fencing's closeness at the start."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.tasks import TaskConfig
from test_bout import _env, _frames


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v rotated by the unit quaternion q (wxyz), by hand."""
    w, u = q[0], q[1:]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def test_fencing_closeness_is_visible_at_the_default_start():
    """At the default 4-m start the blade points are ~3.3 m from the opponent's targets: the
    authors' exp(-3 d) is ~5e-5, the paper's exp(-3 d^2) ~1e-14 (below the advantage eps, 1e-8)."""
    env = _env("fencing")
    task = env.task
    assert not task.sub.close_squared and task.sub.close_k == 3.0 and task.sub.start_distance == 4.0
    xy, yaw = task.start(jax.random.PRNGKey(0))
    f = _frames(env, np.asarray(xy), np.asarray(yaw))
    ch = env.character
    pos, quat = np.asarray(f.pos, np.float64), np.asarray(f.quat, np.float64)
    sword, torso, pelvis = (ch.body_index(b) for b in ("sword", "torso", "pelvis"))
    d = []
    for k in range(2):
        blade = [pos[k, sword] + _rotate(quat[k, sword], np.array([-x, 0.0, 0.0])) for x in (0.0, 0.2, 0.4)]
        op = 1 - k
        targets = [
            pos[op, torso] + _rotate(quat[op, torso], np.array([0.0, 0.0, 0.12])),
            pos[op, pelvis] + _rotate(quat[op, pelvis], np.array([0.0, 0.0, 0.205])),
        ]
        d.append(min(np.linalg.norm(b - t) for b in blade for t in targets))
    d = np.asarray(d)
    assert np.all((d > 2.5) & (d < 4.0)), d
    qv = jnp.zeros((2, env.layout.nv))
    out = task.step(task.init(None, f), f, f, jnp.zeros(2), jnp.zeros(2, bool), qv, qv, jnp.asarray(1), None)
    close = np.asarray(out.info["close"])
    np.testing.assert_allclose(close, np.exp(-3.0 * d), rtol=1e-3)
    np.testing.assert_allclose(np.asarray(out.rewards[:, 1]), close)
    assert np.all(close > 2e-5), close
    # The paper's squared kernel at the same start: nothing to learn from.
    env_sq = _env("fencing", task=TaskConfig(name="fencing", fencing=dataclasses.replace(task.sub, close_squared=True)))
    sq = np.asarray(env_sq.task.close_reward(f))
    np.testing.assert_allclose(sq, np.exp(-3.0 * d**2), rtol=1e-2)
    assert np.all(sq < 1e-10), sq
