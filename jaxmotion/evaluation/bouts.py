"""Evaluation of two-player runs: vmapped bouts of one policy against another (or itself).

``play(learner, ts, opponent, bouts)`` plays ``bouts`` bouts in parallel, each to its end (a
penalty, a result or the round's time limit). Bouts come in pairs from the same start state with
the sides swapped (the evaluated policy is player 0 in one, player 1 in the other), so that the
result of A against B is exactly the negative of B against A with deterministic actions: an
evaluation matrix is antisymmetric by construction of the schedule, not by luck.

Outcome of a bout, for the evaluated policy: boxing, the sum over the bout of the clipped damage
it dealt minus what it received (Fig. 10b's entry), a win when that is positive, a draw at 0;
fencing, the touch rules' result, or a loss for the player whose fall or exit from the piste
ended the bout (a timeout is a draw). Intervals are bootstrap 95% (2000 resamples of bouts).
Falls are also reported per minute of play, per side.

A bout's time limit is the run's round, ``env.episode_steps`` (the limit it was trained with;
``--steps`` overrides it): 1800 steps = 60 s at 30 Hz for boxing, 600 = 20 s for fencing.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.evaluation.rollout import act, program
from jaxmotion.physics.arena import PLAYER_RGBA, scenery
from jaxmotion.training.runs import load_run
from jaxmotion.viz.plot import learning_curves
from jaxmotion.viz.render import iter_frames, write_video
from jaxmotion.viz.replay_html import character_geoms, write_html


def _play_fn(learner, opponent_learner, bouts: int, steps: int, deterministic: bool):
    sig = (id(opponent_learner), bouts, steps, deterministic)
    return program(learner, "bouts", sig, lambda: _play_program(learner, opponent_learner, bouts, steps, deterministic))


def _play_program(learner, opponent_learner, bouts: int, steps: int, deterministic: bool):
    env = learner.env
    side = jnp.arange(bouts) % 2  # the evaluated policy's side in each bout

    @jax.jit
    def run(ts, ts_op, key):
        k_reset, k_act = jax.random.split(key)
        keys = jax.random.split(k_reset, bouts // 2)
        state, obs = jax.vmap(env.reset)(jnp.repeat(keys, 2, axis=0))  # pairs share a start state
        state0, obs0 = state, obs
        mine = jnp.arange(2)[None, :] == side[:, None]  # [E, 2]: which player is the evaluated one

        def step(carry, k):
            state, obs, alive, ca, cb = carry
            k1, k2 = jax.random.split(k)
            a, ca = act(learner, ts, obs, None if deterministic else k1, ca)
            b, cb = act(opponent_learner, ts_op, obs, None if deterministic else k2, cb)
            action = jnp.where(mine[..., None], a, b)
            # A bout that ends is not played on: restarting it from its start state (instead of a
            # fresh reset on every step for every bout) costs nothing.
            new, out = jax.vmap(env.step)(state, action, (state0, obs0))
            ended = out.terminated | out.truncated
            done = jnp.any(ended, -1)
            ca, cb = learner.reset_carry(ca, ended), opponent_learner.reset_carry(cb, ended)
            rec = (state.data.qpos, alive, out.info, out.terminated, out.truncated)
            return (new, out.obs, alive & ~done, ca, cb), rec

        alive0 = jnp.ones((bouts,), bool)
        carry0 = (state, obs, alive0, learner.initial_carry(obs), opponent_learner.initial_carry(obs))
        (last, *_), (qpos, alive, info, term, trunc) = jax.lax.scan(step, carry0, jax.random.split(k_act, steps))
        return qpos, alive, info, term, trunc, mine

    return run


def _ci(x: np.ndarray, stat=np.mean, n: int = 2000, seed: int = 0) -> list[float]:
    """Bootstrap 95% interval of ``stat`` over the first axis."""
    x = np.asarray(x, np.float64)
    if len(x) == 0:
        return [float("nan"), float("nan")]
    rng = np.random.default_rng(seed)
    s = np.array([stat(x[rng.integers(0, len(x), len(x))]) for _ in range(n)])
    return [float(np.percentile(s, 2.5)), float(np.percentile(s, 97.5))]


def outcomes(sport: str, ro: dict, dt: float) -> dict:
    """Per-bout results for the evaluated policy from a ``play`` recording (numpy)."""
    alive, info, mine = ro["alive"], ro["info"], ro["mine"]  # [T, E], {k: [T, E, 2]}, [E, 2]
    live = alive[..., None]
    me = lambda x: np.where(mine[None], x, 0).sum(-1)  # [T, E] the evaluated player's value
    op = lambda x: np.where(mine[None], 0, x).sum(-1)
    length = alive.sum(0) * dt
    out = {
        "length_s": length,
        "fall_me": (me(info["fall"]) * alive).any(0),
        "fall_op": (op(info["fall"]) * alive).any(0),
    }
    if sport == "boxing":
        dealt = np.where(live, info["damage_dealt"], 0.0)
        diff = me(dealt).sum(0) - op(dealt).sum(0)
        out.update(
            score=np.sign(diff),
            damage_diff=diff,
            hits_me=(me(info["hit"]) * alive).sum(0),
            hits_op=(op(info["hit"]) * alive).sum(0),
            penalty_me=(me(info["fall"] | info["stuck"] | info["ropes"]) * alive).any(0),
            penalty_op=(op(info["fall"] | info["stuck"] | info["ropes"]) * alive).any(0),
        )
    else:
        win = (me(info["win"]) * alive).any(0)
        loss = (me(info["loss"]) * alive).any(0)
        pen_me = (me(info["fall"] | info["out"]) * alive).any(0)
        pen_op = (op(info["fall"] | info["out"]) * alive).any(0)
        score = np.where(win, 1, np.where(loss, -1, 0))
        score = np.where((score == 0) & pen_me & ~pen_op, -1, np.where((score == 0) & pen_op & ~pen_me, 1, score))
        out.update(
            score=score,
            touches_me=(me(info["touch"]) * alive).sum(0),
            touches_op=(op(info["touch"]) * alive).sum(0),
            penalty_me=pen_me,
            penalty_op=pen_op,
        )
    return out


def summarize(sport: str, oc: dict) -> dict:
    """Win/draw/loss counts with intervals, and the sport's means (the JSON of ``eval``).

    Falls per minute are each side's falls over the minutes played by all bouts together (a
    fall ends a bout, so a bout has at most one a side): a rate that stays comparable when the
    round length changes, where the count of falls per bout does not."""
    s = np.asarray(oc["score"])
    n = len(s)
    minutes = float(np.sum(oc["length_s"]) / 60.0)  # the time played, all bouts together
    res = {
        "bouts": n,
        "wins": int((s > 0).sum()),
        "draws": int((s == 0).sum()),
        "losses": int((s < 0).sum()),
        "win_rate": float((s > 0).mean()),
        "win_rate_ci95": _ci(s > 0),
        "bout_length_s_mean": float(np.mean(oc["length_s"])),
        "minutes_played": minutes,
        "falls": {"self": int(oc["fall_me"].sum()), "opponent": int(oc["fall_op"].sum())},
        "falls_per_minute": {
            "self": float(oc["fall_me"].sum() / minutes) if minutes > 0 else float("nan"),
            "opponent": float(oc["fall_op"].sum() / minutes) if minutes > 0 else float("nan"),
        },
        "penalties": {"self": int(oc["penalty_me"].sum()), "opponent": int(oc["penalty_op"].sum())},
    }
    if sport == "boxing":
        res.update(
            damage_diff_mean=float(np.mean(oc["damage_diff"])),
            damage_diff_ci95=_ci(oc["damage_diff"]),
            hits={"self": int(oc["hits_me"].sum()), "opponent": int(oc["hits_op"].sum())},
            bouts_with_damage=int(((oc["hits_me"] + oc["hits_op"]) > 0).sum()),
        )
    else:
        res.update(
            touches={"self": int(oc["touches_me"].sum()), "opponent": int(oc["touches_op"].sum())},
            bout_lengths_s=[float(x) for x in oc["length_s"]],
        )
    return res


def play(
    learner, ts, opponent=None, bouts: int = 32, steps: int | None = None, seed: int = 0, deterministic: bool = True
) -> tuple[dict, dict]:
    """Plays ``bouts`` (even) bouts of ``ts``'s policy against ``opponent`` = (learner, state)
    (default: itself); returns (summary, recording). The recording holds ``qpos`` [T, E, nq],
    ``alive`` [T, E], ``info`` {k: [T, E, 2]}, ``mine`` [E, 2] (the evaluated player)."""
    if bouts < 2 or bouts % 2:
        raise ValueError(f"bouts must be an even number >= 2 (pairs with the sides swapped), got {bouts}")
    op_learner, op_ts = opponent if opponent is not None else (learner, ts)
    if (op_learner.env.obs_size, op_learner.env.action_size) != (learner.env.obs_size, learner.env.action_size):
        raise ValueError(
            f"the opponent's observation/action sizes {op_learner.env.obs_size}/"
            f"{op_learner.env.action_size} differ from {learner.env.obs_size}/{learner.env.action_size}"
        )
    steps = steps or learner.cfg.env.episode_steps
    run = _play_fn(learner, op_learner, bouts, steps, deterministic)
    qpos, alive, info, term, trunc, mine = jax.device_get(run(ts, op_ts, jax.random.PRNGKey(seed)))
    ro = {
        "qpos": np.asarray(qpos),
        "alive": np.asarray(alive),
        "info": {k: np.asarray(v) for k, v in info.items()},
        "mine": np.asarray(mine),
    }
    sport = learner.cfg.env.arena.sport
    res = summarize(sport, outcomes(sport, ro, learner.env.dt))
    return {**res, "round_s": steps * learner.env.dt}, ro


def touch_markers(learner, ro: dict, bout: int = 0, hold: int = 6) -> dict[str, np.ndarray]:
    """Video markers: a sphere over the head of a player for ``hold`` frames after each of its
    scoring touches (``render`` draws a zero-length segment as a sphere)."""
    info, qpos = ro["info"], ro["qpos"][:, bout]
    key = "hit" if "hit" in info else "touch"
    nq = qpos.shape[-1] // 2
    out = {}
    for k in range(2):
        hit = info[key][:, bout, k].astype(bool)
        held = np.convolve(hit.astype(float), np.ones(hold), mode="full")[: len(hit)] > 0
        p = qpos[:, k * nq : k * nq + 3] + np.array([0.0, 0.0, 0.85])
        p = np.where(held[:, None], p, np.array([0.0, 0.0, -100.0]))
        out[f"touch_p{k}"] = np.repeat(p[:, None], 2, axis=1)
    return out


def write_bout_video(learner, ro: dict, path: Path, bout: int = 0) -> Path:
    """Renders one bout: player 0 as the character, player 1 as the second (opaque) figure, the
    ropes, and a sphere over a player's head when it scores."""
    n = int(ro["alive"][:, bout].sum())
    q = ro["qpos"][:n, bout].astype(np.float64)
    nq = q.shape[-1] // 2
    rgba = [float(x) for x in PLAYER_RGBA[1].split()]
    colors = {b: tuple(float(x) for x in PLAYER_RGBA[0].split()) for b in range(learner.env.layout.nb)}
    mk = {k: v[:n] for k, v in touch_markers(learner, ro, bout).items()}
    frames = iter_frames(
        q[:, :nq],
        q[:, nq:],
        colors,
        ghost_rgba=rgba,
        markers=mk,
        camera_distance=6.0,
        camera_elevation=-20.0,
        scenery=scenery(learner.cfg.env.arena, _piste(learner)),
    )
    return write_video(frames, path, 1.0 / learner.env.dt)


def _piste(learner):
    cfg = learner.cfg.env
    return cfg.task.fencing.piste if cfg.arena.sport == "fencing" else None


def add_arguments(p: argparse.ArgumentParser) -> None:
    """This evaluator's flags (its own group of ``python -m jaxmotion.eval``'s)."""
    g = p.add_argument_group("two-player runs")
    g.add_argument(
        "--against",
        type=Path,
        nargs="+",
        default=(),
        metavar="RUN",
        help="opponent run folders (default: the run plays itself)",
    )
    g.add_argument("--bouts", type=int, default=32, help="bouts per opponent (even; default 32)")


def run(args, experiment: str, cfg, learner, ts) -> int:
    """``python -m jaxmotion.eval <bout-run> [--against RUN ...] [--bouts N]``: this policy
    against each opponent run (default: itself), deterministic and stochastic."""
    sport = cfg.env.arena.sport
    opponents = [(str(args.run), None)]
    if args.against:
        opponents = []
        for r in args.against:
            _, ocfg, olearner, ots = load_run(r)
            if ocfg.env.arena.sport != sport:
                print(f"error: {r} is a {ocfg.env.arena.sport} run, {args.run} a {sport} run", file=sys.stderr)
                return 2
            if ocfg.env != cfg.env:
                print(
                    f"note: {r} was trained in another scene or with other rules; these bouts use "
                    f"{args.run}'s, so A vs B and B vs A are antisymmetric only within one scene"
                )
            opponents.append((str(r), (olearner, ots)))
    samples = int(ts.iteration) * cfg.samples_per_iteration
    print(f"{experiment}: {samples:,} samples, {sport}, {args.bouts} bouts per opponent (sides swapped in pairs)")
    results, first = [], None
    for name, op in opponents:
        entry = {"experiment": experiment, "samples": samples, "opponent": name}
        for mode, det in (("deterministic", True), ("stochastic", False)):
            res, ro = play(learner, ts, op, args.bouts, steps=args.steps, seed=args.seed, deterministic=det)
            print_summary(f"vs {Path(name).name} ({mode})", res, sport)
            if det:
                entry.update(res)
                first = ro if first is None else first
            else:
                entry["stochastic"] = res
        results.append(entry)
    if args.json:
        args.json.write_text(json.dumps(results[0] if len(results) == 1 else results, indent=2))
    if args.video:
        print(f"video: {write_bout_video(learner, first, args.video)} (bout 0)")
    if args.html:
        print(f"html: {write_bout_html(learner, first, args.html)} (bout 0)")
    if not args.no_plots:
        learning_curves(args.run)
    return 0


def write_bout_html(learner, ro: dict, path: Path, bout: int = 0) -> Path:
    """The replay page of one bout: player 0 solid, player 1 as the second (ghost) figure."""
    env = learner.env
    ch = env.character
    n = int(ro["alive"][:, bout].sum())
    pos, quat = (np.asarray(x) for x in env.poses_of(jnp.asarray(ro["qpos"][:n, bout])))
    col = {b: tuple(float(x) for x in PLAYER_RGBA[0].split()) for b in range(ch.num_bodies)}
    legend = {"player 0": PLAYER_RGBA[0].split(), "player 1": PLAYER_RGBA[1].split()}
    return write_html(
        path,
        ch.body_names,
        ch.parents,
        pos[:, 0],
        quat[:, 0],
        pos[:, 1],
        quat[:, 1],
        1.0 / env.dt,
        character_geoms(ch.sword_shield, col),
        title=f"jaxmotion bout ({learner.cfg.env.arena.sport})",
        legend={k: [float(x) for x in v] for k, v in legend.items()},
    )


def print_summary(name: str, res: dict, sport: str) -> None:
    lo, hi = res["win_rate_ci95"]
    line = (
        f"  {name}: {res['wins']}/{res['draws']}/{res['losses']} win/draw/loss of {res['bouts']} "
        f"(win rate {res['win_rate']:.2f}, 95% [{lo:.2f}, {hi:.2f}]), bouts {res['bout_length_s_mean']:.1f} s"
        + (f" (round {res['round_s']:.0f} s)" if "round_s" in res else "")
    )
    if sport == "boxing":
        a, b = res["damage_diff_ci95"]
        line += (
            f", damage diff {res['damage_diff_mean']:+.1f} N [{a:+.1f}, {b:+.1f}], hits {res['hits']['self']}"
            f"/{res['hits']['opponent']}, {res['bouts_with_damage']} bouts with damage"
        )
    else:
        line += f", touches {res['touches']['self']}/{res['touches']['opponent']}"
    line += (
        f", falls {res['falls']['self']}/{res['falls']['opponent']} "
        f"({res['falls_per_minute']['self']:.2f}/{res['falls_per_minute']['opponent']:.2f} a minute), penalties "
        f"{res['penalties']['self']}/{res['penalties']['opponent']} (self/opponent)"
    )
    print(line)
