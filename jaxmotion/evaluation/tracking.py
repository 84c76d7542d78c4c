"""Tracker evaluation: every clip once from t = 0, deterministically (PHC's protocol, notes phc.md §6).

A clip fails when the mean body position error exceeds 0.5 m at any frame (the episode then ends
there); ``success_rate_0.25`` applies 0.25 m to the frames the tracker played. On successful
clips, frame-weighted as the authors' metric code: g-MPJPE (global body positions, mm), MPJPE
(positions relative to the root, mm), acceleration error (second differences, mm/frame^2) and
velocity error (first differences, mm/frame), all at the control rate against the clean clip.

``python -m jaxmotion.eval <tracker-run> [--clips FILE-OR-FOLDER ...]`` calls ``evaluate_clips``;
a clip the character cannot use is reported under ``errors``, not as a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import sys
from pathlib import Path
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.envs.humanoid import HumanoidEnv
from jaxmotion.evaluation import recovery
from jaxmotion.evaluation.rollout import program
from jaxmotion.motion.loaders import MotionFileError, load_clips
from jaxmotion.motion.motionlib import MotionLib
from jaxmotion.training.run import Hook
from jaxmotion.viz.plot import learning_curves
from jaxmotion.viz.render import iter_frames, learner_group_colors, write_video
from jaxmotion.viz.replay_html import character_geoms, write_html

FAIL_MEAN_M = 0.5


def eval_env(learner, lib: MotionLib | None = None) -> HumanoidEnv:
    """The learner's scene set up for evaluation on ``lib`` (default: its own tracked clips): the
    paper's failure rule (mean body error > 0.5 m) ends an episode, nothing else does before the
    clip's end."""
    cfg = learner.cfg.env
    lib = learner.env.init_lib if lib is None else lib
    longest = int(np.max(np.asarray(lib.clip_len)))
    # A tracker trained with recovery keeps its goal features; its fallen and far starts and
    # recovery episodes are training's, not the protocol's (every clip from its first frame).
    rec = dataclasses.replace(cfg.task.track.recovery, fall_prob=0.0, far_prob=0.0, recovery_prob=0.0)
    track = dataclasses.replace(cfg.task.track, termination="mean", termination_distance=FAIL_MEAN_M, recovery=rec)
    task = dataclasses.replace(cfg.task, track=track)
    cfg = dataclasses.replace(cfg, task=task, early_termination=False, episode_steps=longest + 1)
    return HumanoidEnv(cfg, motion_libs=learner.env.motion_libs, init_lib=lib, physics=learner.env.physics)


def track_rollout(learner, ts, env: HumanoidEnv) -> dict[str, np.ndarray]:
    """Every clip of ``env.init_lib`` from t = 0 with the policy's mean action, in parallel.

    Returns numpy arrays over T = longest clip - 1 steps and C clips: ``sim`` and ``ref`` body
    positions [T+1, C, nb, 3] (the start frame first), ``played`` [T+1, C] (the frame belongs to
    the clip's episode), ``failed`` [C], ``frames`` [C] (the clip's frame count at the control
    rate), and ``qpos``/``ref_qpos`` [T+1, C, nq] for rendering."""
    return _rollout_program(learner, env)(ts)


@contextlib.contextmanager
def _following(env: HumanoidEnv, lib: MotionLib):
    """``env`` reading ``lib`` (a traced argument) as its clips while a program is traced: the scene,
    its task and the reference all look the clips up in ``env.init_lib`` at trace time."""
    old, env.init_lib = env.init_lib, lib
    try:
        yield
    finally:
        env.init_lib = old


def _rollout_program(learner, env: HumanoidEnv):
    """``track_rollout`` compiled for one learner and eval scene: ``record(ts, clips=None)``.

    The clips are an argument of the compiled program (default: the scene's own), so perturbed
    copies of the same clips (every noise level and seed) reuse one compilation."""
    lib = env.init_lib
    C = lib.num_clips
    dur = np.asarray(lib.clip_duration)
    frames = np.floor(dur / env.dt + 1e-6).astype(int) + 1
    T = int(frames.max()) - 1

    @jax.jit
    def run(ts, lib):
        with _following(env, lib):
            return _run(ts)

    def _run(ts):
        state, obs = jax.vmap(env.reset_at)(
            jax.random.split(jax.random.PRNGKey(0), C), jnp.arange(C, dtype=jnp.int32), jnp.zeros(C)
        )
        ref_of = jax.vmap(lambda g: env.task.reference(g, 0.0))
        ref_qpos = jax.vmap(lambda g: _ref_qpos(env, g))

        def step(carry, _):
            state, obs, alive = carry
            action = learner.act(ts, obs, None)[0]
            state, out = jax.vmap(env.step)(state, action)
            # An episode that ended here was reset: its frame is not recorded (the failure is).
            keep = alive & ~(out.terminated | out.truncated)
            rec = (
                state.hist.pos[:, -1],
                ref_of(state.goal).pos,
                keep,
                alive & out.terminated,
                state.data.qpos,
                ref_qpos(state.goal),
            )
            return (state, out.obs, keep), rec

        alive0 = jnp.ones((C,), bool)
        ref0 = ref_of(state.goal)
        _, (sim, ref, played, failed, qpos, rq) = jax.lax.scan(step, (state, obs, alive0), None, length=T)
        first = lambda x, xs: jnp.concatenate([x[None], xs], 0)
        return (
            first(state.hist.pos[:, -1], sim),
            first(ref0.pos, ref),
            first(alive0, played),
            failed.any(0),
            first(state.data.qpos, qpos),
            first(ref_qpos(state.goal), rq),
        )

    def record(ts, clips: MotionLib | None = None):
        sim, ref, played, failed, qpos, rq = jax.device_get(run(ts, lib if clips is None else clips))
        return {
            "sim": sim,
            "ref": ref,
            "played": played,
            "failed": failed,
            "frames": frames,
            "qpos": qpos,
            "ref_qpos": rq,
        }

    return record


def _ref_qpos(env, goal):
    from jaxmotion.motion.motionlib import qpos_qvel, sample

    return qpos_qvel(sample(env.init_lib, goal.clip, goal.time))[0]


def clip_metrics(sim: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """Errors of one played clip: body positions [F, nb, 3] (m) against its reference."""
    g = np.linalg.norm(sim - ref, axis=-1)
    local = np.linalg.norm((sim - sim[:, :1]) - (ref - ref[:, :1]), axis=-1)
    vel = np.linalg.norm(np.diff(sim, 1, 0) - np.diff(ref, 1, 0), axis=-1)
    acc = np.linalg.norm(np.diff(sim, 2, 0) - np.diff(ref, 2, 0), axis=-1)
    mm = lambda x: float(1000.0 * x.mean()) if x.size else float("nan")
    return {"g_mpjpe_mm": mm(g), "mpjpe_mm": mm(local), "acc_mm": mm(acc), "vel_mm": mm(vel)}


def summarize(ro: dict[str, np.ndarray], paths: Sequence[str]) -> dict:
    """The JSON fields of the tracker evaluation from ``track_rollout``'s output."""
    clips, pooled = [], {"sim": [], "ref": []}
    ok25 = 0
    for c, path in enumerate(paths):
        n = int(ro["played"][:, c].sum())
        sim, ref = ro["sim"][:n, c], ro["ref"][:n, c]
        success = not bool(ro["failed"][c])
        mean_err = np.linalg.norm(sim - ref, axis=-1).mean(-1)
        ok25 += int(success and bool((mean_err <= 0.25).all()))
        clips.append(
            {
                "path": path,
                "frames": int(ro["frames"][c]),
                "played": n,
                "success": success,
                "max_mean_error_m": float(mean_err.max()),
                **clip_metrics(sim, ref),
            }
        )
        if success:
            pooled["sim"].append(sim)
            pooled["ref"].append(ref)
    n = len(paths)
    overall = {"g_mpjpe_mm": float("nan"), "mpjpe_mm": float("nan"), "acc_mm": float("nan"), "vel_mm": float("nan")}
    if pooled["sim"]:
        # Frame-weighted over the successful clips (differences taken within each clip).
        keys = ("g_mpjpe_mm", "mpjpe_mm", "acc_mm", "vel_mm")
        per = [clip_metrics(s, r) for s, r in zip(pooled["sim"], pooled["ref"])]
        w = {k: np.asarray([max(len(s) - d, 0) for s in pooled["sim"]], float) for k, d in zip(keys, (0, 0, 2, 1))}
        overall = {k: float(np.nansum([p[k] * wk for p, wk in zip(per, w[k])]) / max(w[k].sum(), 1.0)) for k in keys}
    succ = sum(c["success"] for c in clips)
    return {
        "clips_total": n,
        "successes": int(succ),
        "success_rate": succ / n if n else float("nan"),
        "success_rate_0.25": ok25 / n if n else float("nan"),
        **overall,
        "clips": clips,
    }


def _load(paths, character, drop_props: bool) -> list:
    from jaxmotion.motion.clip import drop_sword_shield

    if drop_props and not character.sword_shield:
        return [drop_sword_shield(c) for c in load_clips(paths, None)]
    return load_clips(paths, character)


def load_eval_clips(
    paths: Sequence[str | Path], character, drop_props: bool = False
) -> tuple[list, list[str], list[dict]]:
    """The clips at ``paths`` (files or folders) one by one: (clips, their paths, errors).
    ``drop_props``: sword-and-shield clips onto the 15-body humanoid (``clip.drop_sword_shield``)."""
    from jaxmotion.motion.loaders import find_motion_files

    good, names, errors = [], [], []
    for p in paths:
        try:
            files = find_motion_files(p)
        except (MotionFileError, FileNotFoundError) as e:
            errors.append({"path": str(p), "error": str(e)})
            continue
        for f in files:
            try:
                good.extend(_load([f], character, drop_props))
                names.append(str(f))
            except (MotionFileError, ValueError, KeyError) as e:
                errors.append({"path": str(f), "error": str(e)})
    return good, names, errors


def clean_reference(env: HumanoidEnv, lib: MotionLib, steps: int) -> np.ndarray:
    """Body positions [steps+1, C, nb, 3] of every clip of ``lib`` at the control times 0, dt, ..."""
    from jaxmotion.motion.motionlib import qpos_qvel, sample

    t = jnp.arange(steps + 1, dtype=jnp.float32)[:, None] * env.dt
    c = jnp.arange(lib.num_clips, dtype=jnp.int32)[None, :]
    ms = sample(lib, jnp.broadcast_to(c, (steps + 1, lib.num_clips)), jnp.broadcast_to(t, (steps + 1, lib.num_clips)))
    return np.asarray(jax.jit(lambda m: env.frames_of(*qpos_qvel(m)).pos)(ms))


def evaluate_clips(
    learner,
    ts,
    paths: Sequence[str | Path] | None = None,
    noise: float = 0.0,
    seed: int = 0,
    clips: Sequence | None = None,
) -> tuple[dict, dict | None]:
    """(metrics, rollout) of the tracker on ``clips``, the clips at ``paths``, or its own.

    With ``noise`` > 0 the tracker follows perturbed copies (``motion/noise.py``, one seed per
    clip from ``seed``) and is scored against the clean clips."""
    from jaxmotion.motion.noise import perturb_clip

    errors: list[dict] = []
    if paths:
        clips, names, errors = load_eval_clips(paths, learner.env.character, learner.cfg.env.drop_props)
        if not clips:
            return {"clips_total": 0, "successes": 0, "success_rate": float("nan"), "clips": [], "errors": errors}, None
    elif clips is None and noise and learner.cfg.env.init_motions:
        # Only perturbing needs the clips themselves; otherwise the scene's library already holds them
        # (no reloading of every clip at each hard-negative round).
        clips = _load(learner.cfg.env.init_motions, learner.env.character, learner.cfg.env.drop_props)
    if clips is None:
        if noise:
            raise ValueError("noise needs the tracked clips themselves (give paths or clips)")
        clean = learner.env.init_lib
        paths_ = clean.clip_paths or ("",) * clean.num_clips
        names = [p or n for p, n in zip(paths_, clean.clip_names)]  # clips built in code have no path
        tracked = clean
    else:
        names = names if paths else [c.path or c.name for c in clips]
        clean = MotionLib.from_clips(list(clips))
        rngs = [np.random.default_rng([seed, i]) for i in range(len(clips))]
        tracked = MotionLib.from_clips([perturb_clip(c, noise, r) for c, r in zip(clips, rngs)]) if noise else clean
    # One compiled program per learner and clip set: evaluating several states (seeds, checkpoints,
    # hard-negative rounds) and perturbed copies of the clips (noise levels, seeds) compiles once.
    key = (tuple(names), tuple(np.asarray(tracked.clip_len).tolist()), tuple(np.asarray(tracked.clip_fps).tolist()))

    def build():
        env = eval_env(learner, tracked)
        return env, _rollout_program(learner, env)

    env, run = program(learner, "tracking", key, build)
    ro = run(ts, tracked)
    if noise:
        ro["ref"] = clean_reference(env, clean, ro["ref"].shape[0] - 1)
        # Failure is judged against the clean clip as well: 0.5 m mean error at any played frame.
        err = np.linalg.norm(ro["sim"] - ro["ref"], axis=-1).mean(-1)
        ro["failed"] = ro["failed"] | ((err > FAIL_MEAN_M) & ro["played"]).any(0)
    return {**summarize(ro, names), "noise": float(noise), "errors": errors}, ro


def mines_after(iteration: int, cfg) -> bool:
    """Whether hard negatives are mined after the chunk that ends at ``iteration``: every
    ``hard_negatives_every`` chunks counted in iterations, not in this process's chunks, the
    run's last chunk included, and before that chunk's checkpoint, so that a run stopped at a
    mining iteration and resumed mines and samples as the uninterrupted one (skipping the last
    chunk lost the mining at the 1000th iteration of a 1000-iteration run resumed to 3000)."""
    return bool(cfg.hard_negatives_every) and (iteration // cfg.chunk) % cfg.hard_negatives_every == 0


def _mine(learner, ts, end):
    ts, hard = hard_negative_update(learner, ts, end.run_dir)
    n = learner.env.init_lib.num_clips
    end.log({"mining/success_rate": (n - len(hard)) / n, "mining/failed": float(len(hard))})
    end.say(
        f"hard negatives at iteration {int(ts.iteration)}: {len(hard)} of {learner.env.init_lib.num_clips} clips failed"
    )
    return ts


MINING = Hook(run=_mine, due=lambda cfg, end: mines_after(end.iteration, cfg), before_checkpoint=True)
"""Hard-negative mining as a training hook (``TrainConfig.hard_negatives_every``)."""


HARD_FILE = "hard_clips.json"


def hard_negative_update(learner, ts, run_dir: Path | None = None):
    """Hard-negative mining (PHC; the authors' soft rule): every training clip once from t = 0; a
    clip that fails adds to its cumulative failure count, and resets pick clip ``c`` with
    probability ∝ base weight × (1 + failures of c), so failed clips come up more often while
    none is dropped. Writes the current hard set to ``run_dir/hard_clips.json`` (with every pass's
    failures, ``passes``); returns the updated state and the failed clips' paths."""

    res, _ = evaluate_clips(learner, ts)
    failed = np.asarray([not c["success"] for c in res["clips"]])
    fails = np.asarray(jax.device_get(ts.clip_fails)) + failed.astype(np.int32)
    base = np.asarray(learner.env.init_lib.clip_weight, np.float64)
    w = base * (1.0 + fails)
    w = w / w.sum()
    put = lambda x, like: jax.device_put(jnp.asarray(x, like.dtype), like.sharding)
    ts = ts.replace(clip_fails=put(fails, ts.clip_fails), clip_weights=put(w, ts.clip_weights))
    hard = [c["path"] for c, f in zip(res["clips"], failed) if f]
    if run_dir is not None:
        path = Path(run_dir) / HARD_FILE
        try:  # every pass so far, for the progressive pipeline's hard set (a union of passes)
            passes = json.loads(path.read_text()).get("passes", []) if path.exists() else []
        except (OSError, ValueError, AttributeError):
            passes = []
        passes = [p for p in passes if p.get("iteration", 0) < int(ts.iteration)]
        passes.append({"iteration": int(ts.iteration), "failed": hard})
        doc = {
            "iteration": int(ts.iteration),
            "failed": hard,
            "passes": passes,
            "success_rate": res["success_rate"],
            "cumulative_failures": {c["path"]: int(n) for c, n in zip(res["clips"], fails)},
            "reset_probability": {c["path"]: float(p) for c, p in zip(res["clips"], w)},
        }
        tmp = Path(run_dir) / (HARD_FILE + ".tmp")
        tmp.write_text(json.dumps(doc, indent=2))
        tmp.replace(Path(run_dir) / HARD_FILE)
    return ts, hard


def write_track_html(learner, ro: dict, path, clip: int = 0):
    """The replay page of one tracked clip (the frames the tracker played): the simulated
    character solid, its reference clip as the ghost."""
    env = learner.env
    ch = env.character
    n = int(np.asarray(ro["played"])[:, clip].sum())
    sp, sq = (np.asarray(x) for x in env.poses_of(jnp.asarray(ro["qpos"][:n, clip])))
    rp, rq = (np.asarray(x) for x in env.poses_of(jnp.asarray(ro["ref_qpos"][:n, clip])))
    return write_html(
        path,
        ch.body_names,
        ch.parents,
        sp,
        sq,
        rp,
        rq,
        1.0 / env.dt,
        character_geoms(ch.sword_shield, learner_group_colors(learner)),
        title="jaxmotion tracker (ghost: the reference clip)",
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    """This evaluator's flags (its own group of ``python -m jaxmotion.eval``'s)."""
    g = p.add_argument_group("tracker runs")
    g.add_argument(
        "--clips",
        type=Path,
        nargs="+",
        default=None,
        metavar="PATH",
        help="clip files or folders to track (default: the run's own clips)",
    )
    g.add_argument(
        "--noise",
        type=float,
        default=0.0,
        metavar="LEVEL",
        help="follow clips perturbed like a video pose estimate (1: the defaults of "
        "motion/noise.PoseNoise), scored against the clean clips",
    )
    recovery.add_arguments(g)


def run(args, experiment: str, cfg, learner, ts) -> int:
    """``python -m jaxmotion.eval <tracker-run>``: every clip once from t = 0 (``--recovery``:
    the recovery trials of ``evaluation/recovery.py`` instead)."""
    if args.recovery:
        return recovery.run(args, experiment, cfg, learner, ts)
    res, ro = evaluate_clips(learner, ts, args.clips, noise=args.noise, seed=args.seed)
    res = {"experiment": experiment, "samples": int(ts.iteration) * cfg.samples_per_iteration, **res}
    noisy = f" (inputs perturbed at noise level {args.noise:g})" if args.noise else ""
    print(
        f"{experiment}: {res['samples']:,} samples, {res['successes']}/{res['clips_total']} clips tracked{noisy} "
        f"(mean body error <= 0.5 m throughout), {res.get('success_rate_0.25', float('nan')):.2f} at 0.25 m"
    )
    if res["clips"]:
        print(
            f"  on successful clips: g-MPJPE {res['g_mpjpe_mm']:.1f} mm, MPJPE {res['mpjpe_mm']:.1f} mm, "
            f"acc {res['acc_mm']:.2f} mm/frame^2, vel {res['vel_mm']:.2f} mm/frame"
        )
        print(f"  {'clip':<60} {'frames':>6} {'ok':>3} {'g-MPJPE':>8} {'MPJPE':>7}")
        for c in res["clips"]:
            print(
                f"  {Path(c['path']).name[:60]:<60} {c['frames']:>6} {'yes' if c['success'] else 'no':>3} "
                f"{c['g_mpjpe_mm']:>8.1f} {c['mpjpe_mm']:>7.1f}"
            )
    for e in res["errors"]:
        print(f"  cannot use {e['path']}: {e['error']}", file=sys.stderr)
    if args.json:
        args.json.write_text(json.dumps(res, indent=2))
    if args.video and ro is not None:
        n = int(ro["played"][:, 0].sum())
        frames = iter_frames(
            ro["qpos"][:n, 0].astype(np.float64),
            ro["ref_qpos"][:n, 0].astype(np.float64),
            learner_group_colors(learner),
        )
        print(f"video: {write_video(frames, args.video, 1.0 / learner.env.dt)} (clip 0, its reference as the ghost)")
    if args.html and ro is not None:
        print(f"html: {write_track_html(learner, ro, args.html)} (clip 0, its reference as the ghost)")
    if not args.no_plots:
        learning_curves(args.run)
    return 0
