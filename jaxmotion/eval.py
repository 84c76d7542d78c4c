"""``python -m jaxmotion.eval <run-folder> [--episodes N] [--json FILE]``: imitation metrics.

Rebuilds the learner from the run folder alone (``config.json`` + the latest orbax checkpoint),
rolls the policy out deterministically (mean actions) from reference-state initialisation, and
reports per body group the DTW imitation error of the Composite Motion paper (Eq. 11): per
frame, the mean over the group's links of ‖p_sim − p_ref‖ in metres, after aligning the
simulated and reference sequences with dynamic time warping; mean ± std over episodes.

Two frames of reference are reported, because a partial-body reference clip does not share the
simulated character's root trajectory (the upper body of a chest-open clip over a squatting
pelvis):

* ``dtw_error_m_*``: link positions in the group's own frame, the one its discriminator judges
  (the anchor link's frame, e.g. the pelvis for ``upper``; for anchor-less groups the per-frame
  heading frame, which keeps height and body lean but removes root drift and yaw).
* ``dtw_error_world_m_*``: world-frame positions, with the reference clip placed so that its
  first frame's root heading frame coincides with the simulation's first frame (only meaningful
  for groups whose reference also drives the root, e.g. ``lower``/``full``).

The reference sequence of a group is its first clip, repeated to cover the episode.

``coverage`` is the other direction: for each frame of one pass of that clip, the distance (group
frame) to the nearest frame any episode played after its first 2 s (``COVERAGE_SKIP_S``),
averaged (``error_m``), and the share within 0.1 m (``within``). DTW forgives a policy that
repeats one part of the clip (the bottom of a squat, held); coverage does not.

The task's metrics (``Task.summary``: e.g. the location success rate) come under ``"task"``. With
``--switch RUN2 [...] --switch-every S`` the policies of several runs that share observation and
action spaces take turns every S seconds on the same environments (paper Fig. 9), and
``"switching"`` counts the falls within 1 s of a switch. Tracker runs are evaluated clip by clip
(``track_eval.py``), two-player runs bout by bout (``bout_eval.py``: ``--against RUN``, ``--bouts N``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion import checkpoint as ckpt
from jaxmotion import metrics as M
from jaxmotion.envs import observations as O
from jaxmotion.motion import rotations as R
from jaxmotion.motion.motionlib import MotionState, sample
from jaxmotion.trainer import Learner, TrainConfig, TrainState
from jaxmotion.data import cli_errors


def load_run(run_dir: Path) -> tuple[str, TrainConfig, Learner, TrainState]:
    """(experiment, config, learner, restored state) of a run folder."""
    experiment, cfg = ckpt.read_config(run_dir, TrainConfig)
    learner = Learner(cfg)
    like = learner.init(jax.random.PRNGKey(cfg.seed))
    mgr = ckpt.manager(run_dir)
    ts, _ = ckpt.restore(mgr, like)
    mgr.close()
    return experiment, cfg, learner, ts


def spaces_mismatch(runs: list[tuple[Path, Learner]]) -> str | None:
    """Why the policies of these runs cannot take turns on one character (their observation or
    action sizes differ from the first run's), or None."""
    (first, l0), sizes = runs[0], lambda lr: (lr.env.obs_size, lr.env.action_size)
    for r, lr in runs[1:]:
        if sizes(lr) != sizes(l0):
            return (f"{r} has observation/action sizes {lr.env.obs_size}/{lr.env.action_size}, "
                    f"{first} has {l0.env.obs_size}/{l0.env.action_size}: they cannot take turns")
    return None


def acting_policy(t: jax.Array, switch_steps: int, num_policies: int) -> jax.Array:
    """Index of the policy that chooses the action at control step ``t`` when ``num_policies``
    take turns every ``switch_steps`` steps (0: the first one always). One definition serves the
    choice of the action and its record, so what the video shows is what acted."""
    if not switch_steps:
        return jnp.zeros_like(t)
    return (t // switch_steps) % num_policies


def _rollout_fn(learner: Learner, episodes: int, steps: int, deterministic: bool, switch_steps: int = 0,
                actors: tuple[Learner, ...] = ()):
    """The jitted rollout program ``(ts, key) -> arrays``, compiled once per learner and shape.

    ``ts`` may be a tuple of states whose policies take turns every ``switch_steps`` control
    steps (policy switching: only the acting parameters change, the env state carries on).
    ``actors`` are the learners whose networks act for those states, one each (default: all
    ``learner``): runs that share spaces may differ in networks, e.g. one with a meta policy."""
    cache = learner.__dict__.setdefault("_eval_rollout_cache", {})
    sig = (episodes, steps, deterministic, switch_steps, tuple(id(a) for a in actors))
    if sig in cache:
        return cache[sig]
    env = learner.env

    @jax.jit
    def run(ts, key):
        policies = ts if isinstance(ts, tuple) else (ts,)
        k_reset, k_act = jax.random.split(key)
        state, obs = jax.vmap(env.reset)(jax.random.split(k_reset, episodes))
        markers = lambda s: jax.vmap(env.task.markers)(s.goal, jax.tree.map(lambda x: x[:, -1], s.hist))

        def step(carry, xs):
            state, obs, alive = carry
            k, t = xs
            which = acting_policy(t, switch_steps, len(policies))
            acts = [(actors[i] if actors else learner).act(p, obs, None if deterministic else k)[0]
                    for i, p in enumerate(policies)]
            action = jnp.stack(acts)[which]
            # Incremental learning: the weights w of the meta action (paper Figs. 7-8).
            w = (learner.meta_weights(policies[0], obs) if learner.meta is not None and len(policies) == 1
                 else jnp.zeros((episodes, 0)))
            state, out = jax.vmap(env.step)(state, action)
            done = out.terminated | out.truncated
            # The recorded frame t + 1 is where step t + 1 begins: its acting policy is that step's.
            acting = jnp.full((episodes,), acting_policy(t + 1, switch_steps, len(policies)), jnp.int32)
            # A terminal frame is replaced by the auto-reset state, so it is dropped (masked).
            rec = (state.hist.pos[:, -1], state.hist.quat[:, -1], env.character_qpos(state.data.qpos), alive & ~done,
                   alive & out.terminated, out.info, alive, out.task_reward, w, markers(state), acting)
            return (state, out.obs, alive & ~done), rec

        alive0 = jnp.ones((episodes,), bool)
        _, (pos, quat, qpos, alive, fell, info, stepped, task_reward, meta_w, mk, acting) = jax.lax.scan(
            step, (state, obs, alive0), (jax.random.split(k_act, steps), jnp.arange(steps)))
        first = lambda x, xs: jnp.concatenate([x[None], xs], 0)
        acting0 = jnp.full((episodes,), acting_policy(jnp.int32(0), switch_steps, len(policies)), jnp.int32)
        return (first(state.hist.pos[:, -1], pos), first(state.hist.quat[:, -1], quat),
                first(env.character_qpos(state.data.qpos), qpos), first(alive0, alive), fell.any(0), info, stepped, task_reward,
                meta_w, jax.tree.map(first, markers(state), mk), first(acting0, acting))

    cache[sig] = run
    return run


def rollout(learner: Learner, ts: TrainState | tuple[TrainState, ...], episodes: int, steps: int, seed: int = 0,
            deterministic: bool = True, switch_steps: int = 0,
            actors: tuple[Learner, ...] = ()) -> dict[str, np.ndarray]:
    """Runs ``episodes`` environments for ``steps`` control steps with the policy's mean action.

    With a tuple of states and ``switch_steps`` > 0, their policies take turns every
    ``switch_steps`` steps on the same environments (they must share observation and action
    spaces; ``actors`` gives each its own learner); ``info`` then also holds ``switch`` [T, E], true at the first step of each turn.

    Returns numpy arrays: ``pos`` [T+1, E, nb, 3], ``quat`` [T+1, E, nb, 4] (world frame, the
    initial state first), ``qpos`` [T+1, E, nq] (MuJoCo generalised positions, for rendering),
    ``alive`` [T+1, E] (the episode has not ended yet), ``fell`` [E]; the task's per-step
    ``info`` {name: [T, E]}, ``stepped`` [T, E] (the step belongs to the episode, its last one
    included), ``task_reward`` [T, E, R] and, for an incremental policy, ``meta_w`` [T, E, A]
    (the weights of the meta action; [T, E, 0] otherwise), ``markers`` {name: [T+1, E, 2, 3]}:
    what the task draws of its goal (``Task.markers``) at each recorded state, and ``acting``
    [T+1, E] int: the index (in ``ts``) of the policy that chooses the action at each recorded
    state (the last: the one whose turn it would be; all zeros without switching).
    """
    run = _rollout_fn(learner, episodes, steps, deterministic, switch_steps if isinstance(ts, tuple) else 0,
                      tuple(actors) if isinstance(ts, tuple) else ())
    pos, quat, qpos, alive, fell, info, stepped, task_reward, meta_w, markers, acting = jax.device_get(
        run(ts, jax.random.PRNGKey(seed)))
    if isinstance(ts, tuple) and switch_steps:
        t = np.arange(steps)
        info = dict(info, switch=np.broadcast_to(((t % switch_steps) == 0) & (t > 0), (episodes, steps)).T)
    return {"pos": pos, "quat": quat, "qpos": qpos, "alive": alive, "fell": fell, "info": info,
            "stepped": stepped, "task_reward": task_reward, "meta_w": meta_w, "markers": markers, "acting": acting}


def group_frame_positions(pos: np.ndarray, quat: np.ndarray, links: np.ndarray, anchor: int) -> np.ndarray:
    """[T, L, 3] link positions in each frame's own group frame (anchor link or heading frame)."""
    if anchor >= 0:
        origin, inv_q = pos[:, anchor], R.quat_conj(quat[:, anchor])
    else:
        origin, inv_q = O.heading_frame(pos[:, 0], quat[:, 0])
        origin, inv_q = np.asarray(origin), np.asarray(inv_q)
    rel = pos[:, links] - origin[:, None]
    return np.asarray(R.quat_rotate(np.broadcast_to(inv_q[:, None], rel.shape[:-1] + (4,)), rel))


def align_to_start(ref_root_pos: np.ndarray, ref_root_quat: np.ndarray, sim_root_pos0: np.ndarray,
                   sim_root_quat0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rigid xy + yaw motion taking the reference's first root heading frame onto the
    simulation's first one: ``(q_align [4] wxyz, offset [3])`` with
    ``p' = rotate(q_align, p) + offset``.

    Args:
      ref_root_pos: [T, 3], ref_root_quat: [T, 4] (only frame 0 is used).
      sim_root_pos0: [3], sim_root_quat0: [4].
    """
    f32 = lambda x: np.asarray(x, np.float32)  # heading_frame is jnp (float32 without x64)
    o_ref, inv_ref = (np.asarray(x, np.float64) for x in O.heading_frame(
        f32(ref_root_pos[0]), f32(ref_root_quat[0])))
    o_sim, inv_sim = (np.asarray(x, np.float64) for x in O.heading_frame(
        f32(sim_root_pos0), f32(sim_root_quat0)))
    q = np.asarray(R.quat_mul(R.quat_conj(inv_sim), inv_ref))  # ref heading frame -> sim's
    return q, o_sim - np.asarray(R.quat_rotate(q, o_ref))


def align_pose(q_align: np.ndarray, offset: np.ndarray, pos: np.ndarray,
               quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Applies ``align_to_start``'s motion to positions [..., 3] and orientations [..., 4]."""
    pos, quat = np.asarray(pos, np.float64), np.asarray(quat, np.float64)
    p = np.asarray(R.quat_rotate(np.broadcast_to(q_align, pos.shape[:-1] + (4,)), pos)) + offset
    q = np.asarray(R.quat_mul(np.broadcast_to(q_align, quat.shape), quat))
    return p, q


def world_aligned(ref_pos: np.ndarray, ref_quat: np.ndarray, sim_pos0: np.ndarray, sim_quat0: np.ndarray) -> np.ndarray:
    """Reference positions [T, nb, 3] moved rigidly (xy + yaw) onto the simulation's first root frame."""
    q, off = align_to_start(ref_pos[:, 0], ref_quat[:, 0], sim_pos0[0], sim_quat0[0])
    return align_pose(q, off, ref_pos, ref_quat)[0]


def reference_state(learner: Learner, group: int, num_frames: int) -> MotionState:
    """The group's first clip at the control rate, repeated to ``num_frames`` frames."""
    lib = learner.env.motion_libs[group]
    dur = float(lib.clip_duration[0])
    t = (np.arange(num_frames) * learner.env.dt) % max(dur, 1e-6)
    return sample(lib, jnp.zeros(num_frames, jnp.int32), jnp.asarray(t, jnp.float32))


def reference_sequence(learner: Learner, group: int, num_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """``reference_state``'s link positions [T, nb, 3] and orientations [T, nb, 4]."""
    ms = reference_state(learner, group, num_frames)
    return np.asarray(ms.body_pos), np.asarray(ms.body_quat)


COVERAGE_SKIP_S = 2.0
"""Coverage ignores each episode's first seconds: started from a reference state, a policy plays
the reference on for a while before it settles into what it does (measured: a policy that stood
still from 2 s on covered all of the squat's frames counting its first second)."""


def rollout_metrics(learner: Learner, ro: dict[str, np.ndarray]) -> dict:
    """The metrics dict (see the module docstring) of a ``rollout``'s episodes."""
    episodes = ro["alive"].shape[1]
    lengths = ro["alive"].sum(0)  # frames including the initial one
    skip = int(round(COVERAGE_SKIP_S / learner.env.dt))
    groups = {}
    for g, (gcfg, (links, anchor)) in enumerate(zip(learner.cfg.env.groups, learner.env.group_idx)):
        # One reference for every episode (a shorter one is a prefix of the longest), long enough
        # for one pass of the clip (coverage); group frames are per frame, so computed once.
        n_clip = max(int(round(float(learner.env.motion_libs[g].clip_duration[0]) / learner.env.dt)), 1)
        ref_pos, ref_quat = reference_sequence(learner, g, max(int(lengths.max()), n_clip))
        ref_group = group_frame_positions(ref_pos, ref_quat, links, int(anchor))
        errs, errs_w, shown = [], [], []
        for e in range(episodes):
            n = int(lengths[e])
            if n < 2:
                continue
            sp, sq = ro["pos"][:n, e], ro["quat"][:n, e]
            gp = group_frame_positions(sp, sq, links, int(anchor))
            errs.append(M.dtw_imitation_error(gp, ref_group[:n])[0])
            if n > skip:
                shown.append(gp[skip:])
            rw = world_aligned(ref_pos[:n], ref_quat[:n], sp[0], sq[0])
            errs_w.append(M.dtw_imitation_error(sp[:, links], rw[:, links])[0])
        m, s = M.mean_std(errs) if errs else (float("nan"), float("nan"))
        mw, sw = M.mean_std(errs_w) if errs_w else (float("nan"), float("nan"))
        groups[gcfg.name] = {"dtw_error_m_mean": m, "dtw_error_m_std": s,
                             "dtw_error_world_m_mean": mw, "dtw_error_world_m_std": sw}
        if shown:
            # One pass of the clip against every frame played: the share of the reference shown.
            groups[gcfg.name]["coverage"] = M.coverage(np.concatenate(shown, 0), ref_group[:n_clip])
        if int(anchor) < 0:
            # Heading-frame groups drive the root: its height against the reference's shows a
            # held pose that DTW pairs with part of a cyclic clip.
            played = [ro["pos"][:int(n), e, 0, 2] for e, n in enumerate(lengths)]
            groups[gcfg.name]["root_height_m"] = M.height_stats(played, ref_pos[:int(lengths.max()), 0, 2])
    task = learner.env.task
    summary = {"name": learner.cfg.env.task.name, **task.summary(ro["info"], ro["stepped"])}
    for k, name in enumerate(task.reward_names):
        summary[f"reward_{name}"] = float(ro["task_reward"][..., k][ro["stepped"]].mean())
    return {"groups": groups,
            "episode_length_s": float(np.mean((lengths - 1) * learner.env.dt)),
            "fall_rate": float(np.mean(ro["fell"])), "episodes": episodes, "task": summary}


def switch_metrics(ro: dict[str, np.ndarray], dt: float, window_s: float = 1.0) -> dict:
    """Falls per policy switch: falls within ``window_s`` after a switch, over switches made."""
    switch, stepped = ro["info"]["switch"], ro["stepped"]
    ended = stepped & ~ro["alive"][1:]  # the episode ended at this step (each env runs one)...
    ended_fell = ro["fell"][None, :] & ended  # ...by a fall
    w = max(int(round(window_s / dt)), 1)
    near = np.zeros_like(switch)
    for k in range(min(w, len(switch))):
        near[k:] |= switch[:len(switch) - k]
    made = int((switch & stepped).sum())
    falls = int((ended_fell & near).sum())
    return {"switches": made, "falls_after_switch": falls,
            "falls_per_switch": falls / made if made else float("nan")}


def meta_weight_summary(learner: Learner, ro: dict[str, np.ndarray]) -> dict:
    """Mean meta-action weight w overall, per body group (the DoFs of the group's links) and per
    DoF, over the steps of every episode."""
    w, stepped = ro["meta_w"], ro["stepped"]
    mean = w[stepped].mean(0)  # [A]
    ch = learner.env.character
    out = {"mean": float(mean.mean()), "group_mean": {}, "dof": {n: float(v) for n, v in zip(ch.joint_names, mean)}}
    for g, (links, _) in zip(learner.cfg.env.groups, learner.env.group_idx):
        dofs = [d for b in np.asarray(links) for d in ch.body_joints(int(b))]
        if dofs:
            out["group_mean"][g.name] = float(mean[dofs].mean())
    return out


def evaluate(learner: Learner, ts: TrainState, episodes: int = 4, steps: int | None = None,
             seed: int = 0) -> dict:
    """The metrics dict (see the module docstring) of ``episodes`` deterministic rollouts."""
    steps = learner.cfg.env.episode_steps if steps is None else steps
    return rollout_metrics(learner, rollout(learner, ts, episodes, steps, seed))


@cli_errors
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m jaxmotion.eval", description=__doc__.split("\n")[0])
    p.add_argument("run", type=Path, help="run folder (runs/<experiment>/<timestamp>)")
    p.add_argument("--episodes", type=int, default=None, help="episodes (default: the config's eval_episodes)")
    p.add_argument("--json", type=Path, default=None, help="also write the metrics here")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--clips", type=Path, nargs="+", default=None, metavar="PATH",
                   help="tracker runs: clip files or folders to track (default: the run's own clips)")
    p.add_argument("--noise", type=float, default=0.0, metavar="LEVEL",
                   help="tracker runs: follow clips perturbed like a video pose estimate (1: the defaults of "
                        "motion/noise.PoseNoise), scored against the clean clips")
    p.add_argument("--untrained", action="store_true",
                   help="evaluate the run's configuration with freshly initialised networks (its seed): the baseline")
    p.add_argument("--switch", type=Path, nargs="+", default=(), metavar="RUN",
                   help="other run folders whose policies take turns with this one's (same observation and action sizes)")
    p.add_argument("--against", type=Path, nargs="+", default=(), metavar="RUN",
                   help="two-player runs: opponent run folders (default: the run plays itself)")
    p.add_argument("--bouts", type=int, default=32, help="two-player runs: bouts per opponent (even; default 32)")
    p.add_argument("--switch-every", type=float, default=3.0, metavar="SECONDS",
                   help="seconds between policy switches with --switch (default 3)")
    # --- visualisation flags (jaxmotion.render / replay_html / plot) ---
    p.add_argument("--video", type=Path, default=None,
                   help="render rollout episode 0 with the first group's reference as a ghost (.mp4, or .gif)")
    p.add_argument("--html", type=Path, default=None,
                   help="write rollout episode 0 as a self-contained 3D replay page (.html)")
    p.add_argument("--no-plots", action="store_true",
                   help="do not write learning-curve PNGs (plot_*.png) into the run folder")
    # --- end visualisation flags ---
    args = p.parse_args(argv)
    try:
        experiment, cfg, learner, ts = load_run(args.run)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if args.untrained:
        ts = learner.init(jax.random.PRNGKey(cfg.seed))
        experiment += " (untrained)"
    if cfg.env.task.name == "track":
        return _main_track(args, experiment, cfg, learner, ts)
    if cfg.env.players == 2:
        from jaxmotion import bout_eval
        return bout_eval.main(args, experiment, cfg, learner, ts)
    policies, switch_steps, actors = ts, 0, ()
    if args.switch:
        others = [load_run(r) for r in args.switch]
        problem = spaces_mismatch([(args.run, learner)] + [(r, o[2]) for r, o in zip(args.switch, others)])
        if problem:
            print(f"error: {problem}", file=sys.stderr)
            return 2
        policies = (ts,) + tuple(o[3] for o in others)
        actors = (learner,) + tuple(o[2] for o in others)  # each run acts through its own networks
        switch_steps = max(int(round(args.switch_every / learner.env.dt)), 1)
    # One rollout serves the metrics and the video / HTML replay (its episode 0).
    ro = rollout(learner, policies, args.episodes or cfg.eval_episodes, cfg.env.episode_steps, args.seed,
                 switch_steps=switch_steps, actors=actors)
    res = rollout_metrics(learner, ro)
    res = {"experiment": experiment, "samples": int(ts.iteration) * cfg.samples_per_iteration, **res}
    if switch_steps:
        res["switching"] = {"runs": [str(args.run)] + [str(r) for r in args.switch],
                            "every_s": switch_steps * learner.env.dt, **switch_metrics(ro, learner.env.dt)}
        sw = res["switching"]
        print(f"  switching every {sw['every_s']:.1f} s among {len(sw['runs'])} policies: {sw['switches']} switches, "
              f"{sw['falls_after_switch']} falls within 1 s after one ({sw['falls_per_switch']:.2f} per switch)")
    print(f"{experiment}: {res['samples']:,} samples, {res['episodes']} episodes, "
          f"episode length {res['episode_length_s']:.2f} s, fall rate {res['fall_rate']:.2f}")
    for name, g in res["groups"].items():
        print(f"  {name:>8}: DTW error {g['dtw_error_m_mean']:.3f} ± {g['dtw_error_m_std']:.3f} m (group frame), "
              f"{g['dtw_error_world_m_mean']:.3f} ± {g['dtw_error_world_m_std']:.3f} m (world)")
        if "coverage" in g:
            c = g["coverage"]
            print(f"  {'':>8}  reference shown: {c['within']:.0%} of its frames within {c['radius_m']:.2f} m of a "
                  f"simulated frame, nearest {c['error_m']:.3f} m on average")
        if "root_height_m" in g:
            h = g["root_height_m"]
            print(f"  {'':>8}  root height {h['sim_mean']:.2f} ± {h['sim_std']:.2f} m ({h['sim_min']:.2f}-"
                  f"{h['sim_max']:.2f}), reference {h['ref_mean']:.2f} ± {h['ref_std']:.2f} m "
                  f"({h['ref_min']:.2f}-{h['ref_max']:.2f})")
    if ro["meta_w"].shape[-1]:
        res["meta_weights"] = meta_weight_summary(learner, ro)
        mw = res["meta_weights"]
        print(f"  meta weights w (meta: {learner.meta.run_dir}): " + ", ".join(
            f"{g} {v:.2f}" for g, v in mw["group_mean"].items()) + f", all {mw['mean']:.2f}")
    if len(res["task"]) > 1:
        print(f"  task {res['task']['name']}: " + ", ".join(
            f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in res["task"].items() if k != "name"))
    if args.json:
        args.json.write_text(json.dumps(res, indent=2))
    # --- visualisation (jaxmotion.render / replay_html / plot) ---
    names = res["switching"]["runs"] if switch_steps else ()  # ro["acting"] indexes these
    if names and (args.video or args.html):
        from jaxmotion.render import policy_legend
        print(f"  acting policy (sphere over the head): {policy_legend(names)}")
    if args.video:
        from jaxmotion.render import render_rollout
        print(f"video: {render_rollout(learner, ro, args.video, policies=names)}")
    if args.html:
        from jaxmotion.replay_html import write_rollout_html
        print(f"html: {write_rollout_html(learner, ro, args.html, policies=names)}")
    if not args.no_plots and ro["meta_w"].shape[-1]:
        from jaxmotion.plot import plot_meta_weights
        print(f"meta weights: {plot_meta_weights(learner, ro, args.run / 'meta_weights.png')}")
    if not args.no_plots:
        _learning_curves(args.run)
    # --- end visualisation ---
    return 0


def _learning_curves(run: Path) -> None:
    """The run's learning-curve PNGs (``plot.plot_run``), or why there are none."""
    from jaxmotion.plot import plot_run
    try:
        print(f"plots: {len(plot_run(run))} PNGs in {run}")
    except FileNotFoundError as e:
        print(f"plots skipped: {e}", file=sys.stderr)


def _main_track(args, experiment: str, cfg: TrainConfig, learner: Learner, ts: TrainState) -> int:
    """``main`` for a tracker run: every clip once from t = 0 (``track_eval.py``)."""
    from jaxmotion import track_eval as TE

    res, ro = TE.evaluate_clips(learner, ts, args.clips, noise=args.noise, seed=args.seed)
    res = {"experiment": experiment, "samples": int(ts.iteration) * cfg.samples_per_iteration, **res}
    noisy = f" (inputs perturbed at noise level {args.noise:g})" if args.noise else ""
    print(f"{experiment}: {res['samples']:,} samples, {res['successes']}/{res['clips_total']} clips tracked{noisy} "
          f"(mean body error <= 0.5 m throughout), {res.get('success_rate_0.25', float('nan')):.2f} at 0.25 m")
    if res["clips"]:
        print(f"  on successful clips: g-MPJPE {res['g_mpjpe_mm']:.1f} mm, MPJPE {res['mpjpe_mm']:.1f} mm, "
              f"acc {res['acc_mm']:.2f} mm/frame^2, vel {res['vel_mm']:.2f} mm/frame")
        print(f"  {'clip':<60} {'frames':>6} {'ok':>3} {'g-MPJPE':>8} {'MPJPE':>7}")
        for c in res["clips"]:
            print(f"  {Path(c['path']).name[:60]:<60} {c['frames']:>6} {'yes' if c['success'] else 'no':>3} "
                  f"{c['g_mpjpe_mm']:>8.1f} {c['mpjpe_mm']:>7.1f}")
    for e in res["errors"]:
        print(f"  cannot use {e['path']}: {e['error']}", file=sys.stderr)
    if args.json:
        args.json.write_text(json.dumps(res, indent=2))
    if args.video and ro is not None:
        from jaxmotion.render import iter_frames, learner_group_colors, write_video
        n = int(ro["played"][:, 0].sum())
        frames = iter_frames(ro["qpos"][:n, 0].astype(np.float64), ro["ref_qpos"][:n, 0].astype(np.float64),
                             learner_group_colors(learner))
        print(f"video: {write_video(frames, args.video, 1.0 / learner.env.dt)} (clip 0, its reference as the ghost)")
    if args.html and ro is not None:
        print(f"html: {TE.write_track_html(learner, ro, args.html)} (clip 0, its reference as the ghost)")
    if not args.no_plots:
        _learning_curves(args.run)
    return 0


if __name__ == "__main__":
    sys.exit(main())
