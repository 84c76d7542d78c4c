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
    reaches per joint, by MuJoCo C (``probe_problem`` says when the probe went unstable)."""
    return _sweeps(cfg if cfg is not None else sim.PhysicsConfig(), seconds)[0]


def clip_speeds(dof_pos: np.ndarray, fps: float, q: float = 99.0) -> np.ndarray:
    """[n_dof] the ``q``-th percentile over frames of each joint's speed (rad/s), by finite
    differences of the clip's joint angles at its own frame rate."""
    if len(dof_pos) < 2:
        return np.zeros(dof_pos.shape[-1])
    return np.percentile(np.abs(np.diff(dof_pos, axis=0)) * fps, q, axis=0)


UNSTABLE_OVERSHOOT = 0.5
"""Radians a joint may end up past its range during the probe before the probe counts as unstable
(measured: at most 0.10 rad on the 15-body character in both modes and on the sword-and-shield
character with ``'joint'``)."""


def probe_problem(cfg: sim.PhysicsConfig | None = None, seconds: float = PROBE_SECONDS) -> str | None:
    """Why ``reach(cfg)`` is no measurement, or None: the probe's sweeps went unstable (a joint more
    than ``UNSTABLE_OVERSHOOT`` past its range, a non-finite state, or MuJoCo's bad-acceleration
    reset), so its peaks are artefacts of the integration, not speeds the servo reaches.

    Measured: the sword-and-shield character at 120 Hz with ``'actuator'`` damping. Its 3-DoF
    wrist (light, 50 N m, armature 0.003) accelerates at ~17000 rad/s^2 when its motor saturates,
    crosses its whole range in two steps, flies 1.5 rad past its limit and the arm diverges
    (1e6 rad/s); at 240 Hz (the sword-and-shield experiments' rate) the same probe is stable."""
    return _sweeps(cfg if cfg is not None else sim.PhysicsConfig(), seconds)[1]


def _sweeps(cfg: sim.PhysicsConfig, seconds: float) -> tuple[np.ndarray, str | None]:
    """(peak |qdot| per joint, the first sign of instability or None) of the two probe sweeps.
    MuJoCo's warnings go to ``backends.WARNINGS`` (counted), not to ``MUJOCO_LOG.TXT``."""
    from jaxmotion.physics import backends

    backends.WARNINGS.install()
    m = fixed_base_model(cfg)
    jnt = m.actuator_trnid[:, 0]
    qadr, vadr = m.jnt_qposadr[jnt], m.jnt_dofadr[jnt]
    lo, hi = m.jnt_range[jnt].T
    names = [m.joint(j).name for j in jnt]
    peak, problem = np.zeros(m.nu), None
    for k, (q0, target) in enumerate(probe_starts(m)):
        d = mujoco.MjData(m)
        d.qpos[:] = q0
        d.ctrl[:] = target
        for _ in range(int(round(seconds * cfg.sim_hz))):
            mujoco.mj_step(m, d)
            peak = np.maximum(peak, np.abs(d.qvel[vadr]))
            if problem is not None:
                continue
            when = f"at {d.time:.3f} s of sweep {k + 1} of 2"
            past = np.maximum(lo - d.qpos[qadr], d.qpos[qadr] - hi)
            i = int(np.argmax(past))
            if d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number or not np.isfinite(d.qvel).all():
                problem = f"the simulation diverged {when} (MuJoCo reset it)"
            elif past[i] > UNSTABLE_OVERSHOOT:
                problem = (
                    f"{names[i]} ended up {past[i]:.2f} rad past its range {when} "
                    f"(at {d.qvel[vadr[i]]:.0f} rad/s: the {1 / cfg.sim_hz:.4g} s step cannot resolve it)"
                )
    return peak, problem
