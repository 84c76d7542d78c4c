"""Fallen states: where a character lies after it has been dropped and has flailed for a while.

The tracker's fail-state recovery (PHC §3.2, notes phc.md §0 and §4) starts some episodes from
the ground. The authors' recipe (``humanoid_im_getup.py``, ``_generate_fall_states``): a random
root orientation, every joint at zero with no velocity, one constant random PD target per joint
(actions uniform in ±0.5), and 150 physics steps at 60 Hz (2.5 s); the final poses, with their
velocities zeroed, are the pool. Here the same with MuJoCo C on the scene's own model, at its
own physics rate for the same 2.5 s, the root dropped from ``DROP_HEIGHT`` so that no orientation
starts inside the floor. The pool depends only on the physics settings, its size and its seed,
so it is made once per process (cached) and is the same on both backends.
"""

from __future__ import annotations

import functools

import mujoco
import numpy as np

from jaxmotion.physics import sim

DROP_HEIGHT = 1.2
"""Root height (m) the character is dropped from: above the half-height of any pose of the
15-body humanoid, low enough that the fall itself does not throw it."""


@functools.lru_cache(maxsize=4)
def fallen_states(
    cfg: sim.PhysicsConfig, n: int, seed: int = 0, seconds: float = 2.5, action_range: float = 0.5, scale: float = 2.0
) -> np.ndarray:
    """[n, nq] character poses (root position and quaternion, then joint angles) lying where the
    drop left them; ``scale``: ``EnvConfig.action_scale`` (PD target = mid + scale * a * half-range)."""
    from jaxmotion.physics import backends

    backends.WARNINGS.install()
    m = sim.mj_model(cfg)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    jnt = m.actuator_trnid[:, 0]
    lo, hi = m.jnt_range[jnt].T
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    nq_char = 7 + m.nu
    out = np.zeros((n, nq_char))
    steps = int(round(seconds * cfg.sim_hz))
    for i in range(n):
        mujoco.mj_resetData(m, d)
        quat = rng.normal(size=4)
        d.qpos[:3] = (0.0, 0.0, DROP_HEIGHT)
        d.qpos[3:7] = quat / np.linalg.norm(quat)
        d.qpos[7:nq_char] = np.clip(0.0, lo, hi)
        d.ctrl[:] = mid + scale * rng.uniform(-action_range, action_range, m.nu) * half
        for _ in range(steps):
            mujoco.mj_step(m, d)
        if not np.isfinite(d.qpos).all():  # never seen; a diverged drop is dropped again, upright
            mujoco.mj_resetData(m, d)
        out[i] = d.qpos[:nq_char]
    out[:, :2] = 0.0
    return out.astype(np.float32)
