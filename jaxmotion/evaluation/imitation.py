"""The imitation evaluator: DTW error per body group, coverage, falls, the task's summary.

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
(``tracking.py``), two-player runs bout by bout (``bouts.py``: ``--against RUN``, ``--bouts N``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from jaxmotion.envs.reference import group_frame_positions, reference_sequence, world_aligned
from jaxmotion.evaluation import metrics as M
from jaxmotion.evaluation.rollout import rollout
from jaxmotion.training.learner import Learner, TrainConfig, TrainState
from jaxmotion.training.run import Hook
from jaxmotion.training.runs import load_run, spaces_mismatch
from jaxmotion.viz.plot import learning_curves, plot_meta_weights
from jaxmotion.viz.render import policy_legend, render_rollout
from jaxmotion.viz.replay_html import write_rollout_html


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
        groups[gcfg.name] = {
            "dtw_error_m_mean": m,
            "dtw_error_m_std": s,
            "dtw_error_world_m_mean": mw,
            "dtw_error_world_m_std": sw,
        }
        if shown:
            # One pass of the clip against every frame played: the share of the reference shown.
            groups[gcfg.name]["coverage"] = M.coverage(np.concatenate(shown, 0), ref_group[:n_clip])
        if int(anchor) < 0:
            # Heading-frame groups drive the root: its height against the reference's shows a
            # held pose that DTW pairs with part of a cyclic clip.
            played = [ro["pos"][: int(n), e, 0, 2] for e, n in enumerate(lengths)]
            groups[gcfg.name]["root_height_m"] = M.height_stats(played, ref_pos[: int(lengths.max()), 0, 2])
    task = learner.env.task
    summary = {"name": learner.cfg.env.task.name, **task.summary(ro["info"], ro["stepped"])}
    for k, name in enumerate(task.reward_names):
        summary[f"reward_{name}"] = float(ro["task_reward"][..., k][ro["stepped"]].mean())
    return {
        "groups": groups,
        "episode_length_s": float(np.mean((lengths - 1) * learner.env.dt)),
        "fall_rate": float(np.mean(ro["fell"])),
        "episodes": episodes,
        "task": summary,
    }


def switch_metrics(ro: dict[str, np.ndarray], dt: float, window_s: float = 1.0) -> dict:
    """Falls per policy switch: falls within ``window_s`` after a switch, over switches made."""
    switch, stepped = ro["info"]["switch"], ro["stepped"]
    ended = stepped & ~ro["alive"][1:]  # the episode ended at this step (each env runs one)...
    ended_fell = ro["fell"][None, :] & ended  # ...by a fall
    w = max(int(round(window_s / dt)), 1)
    near = np.zeros_like(switch)
    for k in range(min(w, len(switch))):
        near[k:] |= switch[: len(switch) - k]
    made = int((switch & stepped).sum())
    falls = int((ended_fell & near).sum())
    return {"switches": made, "falls_after_switch": falls, "falls_per_switch": falls / made if made else float("nan")}


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


def evaluate(learner: Learner, ts: TrainState, episodes: int = 4, steps: int | None = None, seed: int = 0) -> dict:
    """The metrics dict (see the module docstring) of ``episodes`` deterministic rollouts."""
    steps = learner.cfg.env.episode_steps if steps is None else steps
    return rollout_metrics(learner, rollout(learner, ts, episodes, steps, seed))


def _log_eval(learner: Learner, ts: TrainState, end) -> None:
    """Logs one evaluation row: DTW error and coverage per group, episode length, fall rate, task."""
    res = evaluate(learner, ts, learner.cfg.eval_episodes)
    row = {"eval/episode_length_s": res["episode_length_s"], "eval/fall_rate": res["fall_rate"]}
    for g, m in res["groups"].items():
        row[f"eval/{g}/dtw_error_m"] = m["dtw_error_m_mean"]
        row[f"eval/{g}/dtw_error_world_m"] = m["dtw_error_world_m_mean"]
        if "coverage" in m:
            row[f"eval/{g}/coverage_m"] = m["coverage"]["error_m"]
            row[f"eval/{g}/coverage_within"] = m["coverage"]["within"]
    for k, v in res["task"].items():
        if isinstance(v, (int, float)):
            row[f"eval/task/{k}"] = v
    end.log(row)


PERIODIC_EVAL = Hook(
    run=_log_eval, due=lambda cfg, end: bool(cfg.eval_every) and (end.chunks % cfg.eval_every == 0 or end.done)
)
"""Deterministic evaluations during training (``TrainConfig.eval_every``), logged as ``eval/...``."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    """This evaluator's flags (its own group of ``python -m jaxmotion.eval``'s)."""
    g = p.add_argument_group("imitation runs")
    g.add_argument(
        "--switch",
        type=Path,
        nargs="+",
        default=(),
        metavar="RUN",
        help="other run folders whose policies take turns with this one's (same observation and action sizes)",
    )
    g.add_argument(
        "--switch-every",
        type=float,
        default=3.0,
        metavar="SECONDS",
        help="seconds between policy switches with --switch (default 3)",
    )


def run(args, experiment: str, cfg: TrainConfig, learner: Learner, ts: TrainState) -> int:
    """``python -m jaxmotion.eval <run>`` for an imitation or goal-task run."""
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
    ro = rollout(
        learner,
        policies,
        args.episodes or cfg.eval_episodes,
        args.steps or cfg.env.episode_steps,
        args.seed,
        switch_steps=switch_steps,
        actors=actors,
    )
    res = rollout_metrics(learner, ro)
    res = {"experiment": experiment, "samples": int(ts.iteration) * cfg.samples_per_iteration, **res}
    if switch_steps:
        res["switching"] = {
            "runs": [str(args.run)] + [str(r) for r in args.switch],
            "every_s": switch_steps * learner.env.dt,
            **switch_metrics(ro, learner.env.dt),
        }
        sw = res["switching"]
        print(
            f"  switching every {sw['every_s']:.1f} s among {len(sw['runs'])} policies: {sw['switches']} switches, "
            f"{sw['falls_after_switch']} falls within 1 s after one ({sw['falls_per_switch']:.2f} per switch)"
        )
    print(
        f"{experiment}: {res['samples']:,} samples, {res['episodes']} episodes, "
        f"episode length {res['episode_length_s']:.2f} s, fall rate {res['fall_rate']:.2f}"
    )
    for name, g in res["groups"].items():
        print(
            f"  {name:>8}: DTW error {g['dtw_error_m_mean']:.3f} ± {g['dtw_error_m_std']:.3f} m (group frame), "
            f"{g['dtw_error_world_m_mean']:.3f} ± {g['dtw_error_world_m_std']:.3f} m (world)"
        )
        if "coverage" in g:
            c = g["coverage"]
            print(
                f"  {'':>8}  reference shown: {c['within']:.0%} of its frames within {c['radius_m']:.2f} m of a "
                f"simulated frame, nearest {c['error_m']:.3f} m on average"
            )
        if "root_height_m" in g:
            h = g["root_height_m"]
            print(
                f"  {'':>8}  root height {h['sim_mean']:.2f} ± {h['sim_std']:.2f} m ({h['sim_min']:.2f}-"
                f"{h['sim_max']:.2f}), reference {h['ref_mean']:.2f} ± {h['ref_std']:.2f} m "
                f"({h['ref_min']:.2f}-{h['ref_max']:.2f})"
            )
    if ro["meta_w"].shape[-1] and learner.meta is None:  # a gate over experts or primitives
        w = np.abs(ro["meta_w"][ro["stepped"]])
        res["policy_weights"] = {"mean_abs": [float(x) for x in w.mean(0)]}
        print("  gate weights, mean |w| per expert: " + " ".join(f"{x:.2f}" for x in w.mean(0)))
    elif ro["meta_w"].shape[-1]:
        res["meta_weights"] = meta_weight_summary(learner, ro)
        mw = res["meta_weights"]
        print(
            f"  meta weights w (meta: {learner.meta.run_dir}): "
            + ", ".join(f"{g} {v:.2f}" for g, v in mw["group_mean"].items())
            + f", all {mw['mean']:.2f}"
        )
    if len(res["task"]) > 1:
        print(
            f"  task {res['task']['name']}: "
            + ", ".join(
                f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in res["task"].items() if k != "name"
            )
        )
    if args.json:
        args.json.write_text(json.dumps(res, indent=2))
    names = res["switching"]["runs"] if switch_steps else ()  # ro["acting"] indexes these
    if names and (args.video or args.html):
        print(f"  acting policy (sphere over the head): {policy_legend(names)}")
    if args.html:
        print(f"html: {write_rollout_html(learner, ro, args.html, policies=names)}")
    if args.video:
        print(f"video: {render_rollout(learner, ro, args.video, policies=names)}")
    if not args.no_plots and ro["meta_w"].shape[-1]:
        print(f"meta weights: {plot_meta_weights(learner, ro, args.run / 'meta_weights.png')}")
    if not args.no_plots:
        learning_curves(args.run)
    return 0
