"""How fast the PD servo can turn each joint: the character's reach, against which clips are judged.

The probe is the same on both engines: the character hangs with its root welded in place (no
free joint), gravity off, every joint starts at one end of its range with its PD target at the
other end, and the peak |qdot| of each joint over ``seconds`` of physics is its reach (both
directions, the larger). A clip whose joints turn faster than this cannot be tracked by any policy.

With the damping inside the clipped actuator (``PhysicsConfig.servo_damping='actuator'``) a
saturated motor pushes with its full torque limit and no damping, and the reach is 12-51 rad/s
at 120 Hz; with the damping on the joint (``'joint'``) no target can drive a joint faster than
``limit / kd``, 2.4-5.3 rad/s, below what running, kicking and punching clips need.
"""

from __future__ import annotations

import mujoco
import numpy as np

from jaxmotion.physics import sim

PROBE_SECONDS = 0.6
"""Long enough for every joint to cross its range from a standstill (measured: the peaks come in
the first 0.2-0.4 s)."""


def fixed_base_model(cfg: sim.PhysicsConfig) -> mujoco.MjModel:
    """The character of ``cfg`` with its root welded 3 m above the floor and no gravity."""
    xml = sim.scene_xml(cfg)
    free = '<freejoint name="root"/>'
    if free not in xml:
        raise ValueError("the scene has no root free joint to weld")
    m = sim.apply_settings(mujoco.MjModel.from_xml_string(xml.replace(free, "", 1)), cfg)
    m.body_pos[m.body("pelvis").id, 2] = 3.0
    m.opt.gravity[:] = 0.0
    return m


def probe_starts(m: mujoco.MjModel) -> list[tuple[np.ndarray, np.ndarray]]:
    """(start qpos, PD targets) of the two sweeps: lower to upper limits and back."""
    lo, hi = m.jnt_range[m.actuator_trnid[:, 0]].T
    return [(lo.copy(), hi.copy()), (hi.copy(), lo.copy())]


def reach(cfg: sim.PhysicsConfig | None = None, seconds: float = PROBE_SECONDS) -> np.ndarray:
    """[n_dof] the peak joint speed (rad/s) the servo of ``cfg`` (default: the default physics)
    reaches per joint, by MuJoCo C."""
    cfg = cfg if cfg is not None else sim.PhysicsConfig()
    m = fixed_base_model(cfg)
    peak = np.zeros(m.nu)
    for q0, target in probe_starts(m):
        d = mujoco.MjData(m)
        d.qpos[:] = q0
        d.ctrl[:] = target
        for _ in range(int(round(seconds * cfg.sim_hz))):
            mujoco.mj_step(m, d)
            peak = np.maximum(peak, np.abs(d.qvel))
    return peak


def clip_speeds(dof_pos: np.ndarray, fps: float, q: float = 99.0) -> np.ndarray:
    """[n_dof] the ``q``-th percentile over frames of each joint's speed (rad/s), by finite
    differences of the clip's joint angles at its own frame rate."""
    if len(dof_pos) < 2:
        return np.zeros(dof_pos.shape[-1])
    return np.percentile(np.abs(np.diff(dof_pos, axis=0)) * fps, q, axis=0)
