"""Recovery trials of a tracker: ``python -m jaxmotion.eval <tracker-run> --recovery``.

The paper (PHC §4.2, Table 4) gives few details and no code; the protocol here:

* **Reference**: one pose held still for ``TRIAL_SECONDS`` (the last frame of
  ``--recovery-pose``, default DeepMimic's face-up get-up, which ends standing), placed where the
  clip leaves it.
* **Scenarios**, ``--trials`` each (seeded, the same for every policy): *fallen*: a pose from a
  fallen-state pool made like the training one but with another seed (``physics/falls.py``: a
  random root orientation, joints at zero, 2.5 s of constant random PD targets) under the
  reference root; *far*: the reference pose itself, 3 m from the reference in a random
  direction; *fallen + far*: both.
* **Play**: the policy's mean action, nothing ends a trial early; the reference clock is frozen
  for the whole trial (the reference stands still either way).
* **Success within s seconds**: the mean body position error is back at or under 0.5 m (the
  tracker's failure rule) at some step up to s and stays there for ``HOLD_SECONDS`` (so a body
  lying under a standing reference does not count). Reported: Succ-5s and Succ-10s per scenario,
  the median time to recover among the trials that did, and the mean body error at the start,
  at its smallest and at the end of the trials (progress short of a recovery).

A tracker trained without recovery is evaluated with its own goal features (no point goal), so
the same trials measure it as a baseline.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.config.errors import ConfigError
from jaxmotion.envs.humanoid import HumanoidEnv
from jaxmotion.evaluation.rollout import program
from jaxmotion.motion.clip import Clip
from jaxmotion.motion.motionlib import MotionLib
from jaxmotion.tasks.recovery import RecoveryConfig

POSE_CLIP = "deepmimic/humanoid3d_getup_faceup.txt"
TRIAL_SECONDS = 10.0
HOLD_SECONDS = 1.0
FAIL_MEAN_M = 0.5
FAR_M = 3.0
SCENARIOS = {"fallen": (1.0, 0.0), "far": (0.0, 1.0), "fallen+far": (1.0, 1.0)}
"""Scenario: (fall probability, far probability)."""


def held_pose(clip: Clip, seconds: float) -> Clip:
    """``clip``'s last frame held still for ``seconds`` (velocities zero)."""
    n = int(np.ceil(seconds * clip.fps)) + 2
    hold = lambda x: np.repeat(x[-1:], n, 0)
    still = lambda x: np.zeros((n,) + x.shape[1:])
    return dataclasses.replace(
        clip,
        name=f"{clip.name} (last frame held)",
        loop=False,
        root_pos=hold(clip.root_pos),
        root_quat=hold(clip.root_quat),
        dof_pos=hold(clip.dof_pos),
        root_lin_vel=still(clip.root_lin_vel),
        root_ang_vel=still(clip.root_ang_vel),
        dof_vel=still(clip.dof_vel),
        body_pos=hold(clip.body_pos),
        body_quat=hold(clip.body_quat),
        body_lin_vel=still(clip.body_lin_vel),
        body_ang_vel=still(clip.body_ang_vel),
    )


def pose_clip(path: str | Path, character) -> Clip:
    """The clip at ``path`` on ``character`` (sword-and-shield clips onto the humanoid without
    their props); one line naming the file when it cannot be used."""
    from jaxmotion.motion.clip import drop_sword_shield
    from jaxmotion.motion.loaders import MotionFileError, load_clips

    try:
        if character.sword_shield:
            return load_clips([path], character)[0]
        return drop_sword_shield(load_clips([path], None)[0])
    except (MotionFileError, FileNotFoundError, ValueError, KeyError) as e:
        raise ConfigError(f"--recovery-pose={path}: {e}") from None


def trial_env(learner, lib: MotionLib, fall: float, far: float, trials: int, seed: int) -> HumanoidEnv:
    """The learner's scene for one scenario: starts as the scenario says, no termination, the
    reference frozen, the point goal only if the policy was trained with it."""
    cfg = learner.cfg.env
    steps = int(round((TRIAL_SECONDS + HOLD_SECONDS) / learner.env.dt)) + 2
    own = cfg.task.track.recovery
    rec = RecoveryConfig(
        enabled=True,
        point_goal=own.enabled and own.point_goal,
        close_distance=own.close_distance,
        far_distance=own.far_distance,
        far_start=(FAR_M, FAR_M),
        far_prob=far,
        fall_prob=fall,
        recovery_prob=0.0,
        recovery_steps=steps + 1,
        pool_size=trials,
        pool_seed=1000 + seed,
    )
    track = dataclasses.replace(cfg.task.track, recovery=rec, termination="mean", termination_distance=1e6)
    cfg = dataclasses.replace(
        cfg, task=dataclasses.replace(cfg.task, track=track), early_termination=False, episode_steps=steps + 1
    )
    return HumanoidEnv(cfg, motion_libs=learner.env.motion_libs, init_lib=lib, physics=learner.env.physics)


def _trial_program(learner, envs: dict[str, HumanoidEnv], trials: int, steps: int):
    """One compiled program for every scenario: each scenario's scene makes its trials' starts,
    one scene steps them all (the scenarios differ only in how they start, and nothing resets
    during a trial). Returns ``run(ts, key) -> (err [T, S * N], qpos of each scenario's first trial)``."""
    stepper = next(iter(envs.values()))

    @jax.jit
    def run(ts, key):
        starts = []
        for i, env in enumerate(envs.values()):
            keys = jax.random.split(jax.random.fold_in(key, i), trials)
            starts.append(jax.vmap(env.reset_at)(keys, jnp.zeros(trials, jnp.int32), jnp.zeros(trials)))
        state, obs = jax.tree.map(lambda *x: jnp.concatenate(x), *starts)
        # Fallen starts freeze the clock; far ones would let it run: the reference stands still anyway.
        n = obs.shape[0]
        state = state.replace(goal=state.goal.replace(rec=state.goal.rec.replace(frozen=jnp.ones(n, bool))))

        def step(carry, _):
            state, obs = carry
            action = learner.act(ts, obs, None)[0]
            state, out = jax.vmap(stepper.step)(state, action)
            return (state, out.obs), (out.info["body_error_m"], state.data.qpos[::trials])

        _, (err, qpos) = jax.lax.scan(step, (state, obs), None, length=steps)
        return err, qpos

    return run


def recovery_times(err: np.ndarray, dt: float, hold_steps: int) -> np.ndarray:
    """[N] seconds until each trial's mean body error ``err`` [T, N] is at or under 0.5 m and
    stays there for ``hold_steps`` steps (inf: never within the record)."""
    ok = np.asarray(err) <= FAIL_MEAN_M
    out = np.full(ok.shape[1], np.inf)
    if ok.shape[0] < hold_steps:
        return out
    # held[t, n]: trial n is under the threshold at steps t .. t + hold_steps - 1.
    held = np.lib.stride_tricks.sliding_window_view(ok, hold_steps, axis=0).all(-1)
    found = held.any(0)
    out[found] = (held.argmax(0)[found] + 1) * dt
    return out


def evaluate_recovery(learner, ts, trials: int = 100, seed: int = 0, pose: str | Path = POSE_CLIP) -> tuple[dict, dict]:
    """(metrics, the first trial's qpos and reference qpos per scenario) of ``trials`` trials of
    every scenario (module docstring)."""
    lib = MotionLib.from_clips([held_pose(pose_clip(pose, learner.env.character), TRIAL_SECONDS + HOLD_SECONDS + 1.0)])
    dt = learner.env.dt
    hold = int(round(HOLD_SECONDS / dt))
    steps = int(round((TRIAL_SECONDS + HOLD_SECONDS) / dt))
    res = {"trials": trials, "pose": str(pose), "hold_s": HOLD_SECONDS, "scenarios": {}}

    def build():
        envs = {name: trial_env(learner, lib, fall, far, trials, seed) for name, (fall, far) in SCENARIOS.items()}
        return envs, _trial_program(learner, envs, trials, steps)

    _, run = program(learner, "recovery", (trials, seed, str(pose), steps), build)
    err, qpos = (np.asarray(x) for x in jax.device_get(run(ts, jax.random.PRNGKey(seed))))
    ref = _held_qpos(lib)
    first = {}
    for i, name in enumerate(SCENARIOS):
        e = err[:, i * trials : (i + 1) * trials]
        times = recovery_times(e, dt, hold)
        done = times[np.isfinite(times)]
        res["scenarios"][name] = {
            "succ_5s": float(np.mean(times <= 5.0)),
            "succ_10s": float(np.mean(times <= 10.0)),
            "median_time_s": float(np.median(done)) if done.size else float("nan"),
            "start_error_m": float(np.mean(e[0])),
            "closest_m": float(np.mean(e.min(0))),
            "end_error_m": float(np.mean(e[-1])),
        }
        first[name] = (qpos[:, i], np.broadcast_to(ref, (qpos.shape[0], ref.shape[-1])))
    return res, first


def _held_qpos(lib: MotionLib) -> np.ndarray:
    from jaxmotion.motion.motionlib import qpos_qvel, sample

    return np.asarray(qpos_qvel(sample(lib, jnp.zeros((), jnp.int32), jnp.zeros(())))[0])


def add_arguments(g: argparse._ArgumentGroup) -> None:
    """The recovery flags, in the tracker evaluator's group."""
    g.add_argument(
        "--recovery",
        action="store_true",
        help="run recovery trials (fallen, 3 m away, both) instead of tracking the clips; "
        "Succ-5s/10s as PHC's Table 4 (evaluation/recovery.py gives the protocol)",
    )
    g.add_argument("--trials", type=int, default=100, metavar="N", help="recovery trials per scenario (default 100)")
    g.add_argument(
        "--recovery-pose",
        default=POSE_CLIP,
        metavar="CLIP",
        help=f"clip whose last frame is the reference held still (default {POSE_CLIP})",
    )


def _seconds(t: float) -> str:
    return f"{t:.2f}s" if np.isfinite(t) else "-"


def run(args, experiment: str, cfg, learner, ts) -> int:
    """``--recovery``: print and write the scenarios' success rates."""
    from jaxmotion.viz.render import iter_frames, learner_group_colors, write_video

    res, first = evaluate_recovery(learner, ts, args.trials, args.seed, args.recovery_pose)
    res = {"experiment": experiment, "samples": int(ts.iteration) * cfg.samples_per_iteration, **res}
    print(f"{experiment}: {res['samples']:,} samples, {args.trials} recovery trials per scenario")
    print(
        f"  {'scenario':<12} {'Succ-5s':>8} {'Succ-10s':>9} {'median':>8} "
        f"{'error at start':>15} {'closest':>8} {'end':>6}"
    )
    for name, s in res["scenarios"].items():
        print(
            f"  {name:<12} {100 * s['succ_5s']:>7.1f}% {100 * s['succ_10s']:>8.1f}% "
            f"{_seconds(s['median_time_s']):>8} {s['start_error_m']:>14.2f}m "
            f"{s['closest_m']:>7.2f}m {s['end_error_m']:>5.2f}m"
        )
    if args.json:
        args.json.write_text(json.dumps(res, indent=2))
    if args.video:
        qpos, ref = first["fallen+far"]
        frames = iter_frames(qpos.astype(np.float64), ref.astype(np.float64), learner_group_colors(learner))
        print(f"video: {write_video(frames, args.video, 1.0 / learner.env.dt)} (fallen + far, trial 0)")
    return 0
