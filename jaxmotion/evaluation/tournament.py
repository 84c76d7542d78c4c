"""A tournament of two-player policies: every pair plays, sides swapped, and the players are rated.

Each unordered pair (i, j) plays ``bouts`` bouts per evaluation seed with ``bouts.play``: pairs of
bouts from one start with the sides swapped, so with deterministic actions i vs j is exactly
-(j vs i) and one play fills both M[i, j] and M[j, i] = -M[i, j]. A bout's score for the row
player: boxing, the summed damage dealt minus received (N); fencing, the touch result (+1 win,
0 draw, -1 loss). The diagonal (self-play) is 0 by definition.

Intervals are bootstrap 95%: evaluation seeds resampled, then within each the start states (a
pair of bouts with the sides swapped is one unit: its two bouts share a start, so they are not
independent). The rating is Bradley-Terry, fitted by maximum likelihood on the win/loss counts
(a draw is half a win each way) with one virtual draw per pair as the prior, so that a player
that wins everything gets a finite rating; ratings are Elo-scaled (400·log10, mean 0).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import jax
import numpy as np

from jaxmotion.config.errors import JaxmotionError
from jaxmotion.evaluation.bouts import outcomes, play
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.training.hparams import TrainConfig
from jaxmotion.training.runs import final_stage, load_run

ELO = 400.0 / np.log(10.0)
"""Natural-log strength to Elo points: a difference of 400 is odds of 10 to 1."""
PRIOR_GAMES = 1.0
"""Virtual games per pair added to the Bradley-Terry counts, as draws (half a win each way)."""
RESAMPLES = 2000
UNTRAINED = "untrained"
_BOOKKEEPING = ("seed", "iterations", "chunk", "checkpoint_every", "resume", "init_from", "eval_episodes", "eval_every")


class TournamentError(JaxmotionError):
    """Players that cannot meet in a tournament (not two-player runs, mixed sports, too few)."""


# --------------------------------------------------------------------------- statistics


def units(values: np.ndarray) -> np.ndarray:
    """Per-bout values [S, N] (seeds x bouts, bouts in side-swapped pairs) as the mean of each
    start's pair of bouts [S, N/2]: the bootstrap's unit (the two bouts of a start are not
    independent; with deterministic actions and one policy they cancel exactly)."""
    v = np.asarray(values, np.float64)
    if v.ndim != 2 or v.shape[1] % 2:
        raise ValueError(f"values must be [seeds, bouts] with an even number of bouts, got {v.shape}")
    return v.reshape(v.shape[0], -1, 2).mean(-1)


def resample(shape: tuple[int, int], n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Indices of ``n`` two-level bootstrap resamples of [S, U] units: seeds with replacement
    [n, S], then units within each drawn seed with replacement [n, S, U]."""
    s, u = shape
    return rng.integers(0, s, (n, s)), rng.integers(0, u, (n, s, u))


def bootstrap_means(values: np.ndarray, n: int = RESAMPLES, seed: int = 0) -> np.ndarray:
    """Means of ``n`` two-level bootstrap resamples (``resample``) of per-bout values [S, N]."""
    u = units(values)
    si, ui = resample(u.shape, n, np.random.default_rng(seed))
    return u[si[..., None], ui].mean((1, 2))


def interval(samples: np.ndarray) -> list[float]:
    """The central 95% of bootstrap samples."""
    return [float(np.percentile(samples, 2.5)), float(np.percentile(samples, 97.5))]


def payoff_matrix(pairs: dict, n: int, resamples: int = RESAMPLES, seed: int = 0) -> dict[str, np.ndarray]:
    """The antisymmetric matrix of mean per-bout values of row vs column, and its 95% interval.

    ``pairs`` maps (i, j), i < j, to i's per-bout values [S, N] against j. M[j, i] = -M[i, j] and
    j's interval is i's negated, from the same bouts; the diagonal is 0 (self-play)."""
    mean, lo, hi = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    for k, ((i, j), v) in enumerate(sorted(pairs.items())):
        m = float(np.mean(v))
        a, b = interval(bootstrap_means(v, resamples, seed + k))
        mean[i, j], lo[i, j], hi[i, j] = m, a, b
        mean[j, i], lo[j, i], hi[j, i] = 0.0 - m, 0.0 - b, 0.0 - a  # 0.0 - x: no -0.0
    return {"mean": mean, "low": lo, "high": hi}


def win_counts(pairs: dict, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(wins, draws) [n, n] from per-bout scores (sign of the row player's result): wins[i, j]
    counts i's wins over j; draws is symmetric."""
    wins, draws = np.zeros((n, n), int), np.zeros((n, n), int)
    for (i, j), s in pairs.items():
        s = np.sign(np.asarray(s))
        wins[i, j], wins[j, i] = int((s > 0).sum()), int((s < 0).sum())
        draws[i, j] = draws[j, i] = int((s == 0).sum())
    return wins, draws


def bradley_terry(
    wins: np.ndarray, draws: np.ndarray, prior_games: float = PRIOR_GAMES, tol: float = 1e-10, max_iter: int = 100000
) -> np.ndarray:
    """Bradley-Terry log-strengths θ (mean 0), P(i beats j) = 1 / (1 + exp(θ_j - θ_i)), fitted by
    maximum likelihood with Hunter's (2004) minorise-maximise updates, which raise the
    likelihood every step. A draw is half a win each way; ``prior_games`` virtual draws per pair
    keep the fit finite when a player wins every bout. Batched over leading axes ([..., n, n])."""
    n = wins.shape[-1]
    off = 1.0 - np.eye(n)
    w = (np.asarray(wins, np.float64) + 0.5 * np.asarray(draws, np.float64) + 0.5 * prior_games) * off
    games = w + np.swapaxes(w, -1, -2)
    total = w.sum(-1)
    theta = np.zeros(w.shape[:-1])
    for _ in range(max_iter):
        p = np.exp(theta)
        new = np.log(total / (games / (p[..., :, None] + p[..., None, :])).sum(-1))
        new -= new.mean(-1, keepdims=True)
        done = np.max(np.abs(new - theta)) < tol
        theta = new
        if done:
            break
    return theta


def ratings(scores: dict, n: int, resamples: int = RESAMPLES, seed: int = 0) -> dict:
    """Elo-scaled Bradley-Terry ratings (mean 0) of the win/draw/loss counts of per-bout scores
    {(i, j): [S, N]}, with bootstrap 95% intervals (each pair's bouts resampled as in
    ``bootstrap_means``, all resamples fitted at once)."""
    wins, draws = win_counts(scores, n)
    elo = ELO * bradley_terry(wins, draws)
    rng = np.random.default_rng(seed)
    bw, bd = np.zeros((resamples, n, n)), np.zeros((resamples, n, n))
    for (i, j), s in sorted(scores.items()):
        s = np.sign(np.asarray(s, np.float64))
        pair = s.reshape(s.shape[0], -1, 2)  # [S, U, 2]: a start's two bouts stay together
        si, ui = resample(pair.shape[:2], resamples, rng)
        picked = pair[si[..., None], ui]  # [B, S, U, 2]
        bw[:, i, j], bw[:, j, i] = (picked > 0).sum((1, 2, 3)), (picked < 0).sum((1, 2, 3))
        bd[:, i, j] = bd[:, j, i] = (picked == 0).sum((1, 2, 3))
    boot = ELO * bradley_terry(bw, bd)
    lo, hi = np.percentile(boot, 2.5, axis=0), np.percentile(boot, 97.5, axis=0)
    return {"elo": elo, "low": lo, "high": hi, "wins": wins, "draws": draws}


def summarize(names: list[str], sport: str, values: dict, scores: dict, resamples: int = RESAMPLES) -> dict:
    """The tournament's result (JSON-ready) from per-bout outcomes: ``values`` {(i, j): [S, N]}
    the row player's damage difference (boxing) or touch result (fencing), ``scores`` the
    sign of its result per bout (for win/draw/loss counts)."""
    n = len(names)
    m = payoff_matrix(values, n, resamples)
    r = ratings(scores, n, resamples)
    order = [int(k) for k in np.argsort(-r["elo"], kind="stable")]
    return {
        "players": list(names),
        "sport": sport,
        "value": "damage difference (N) per bout" if sport == "boxing" else "touch result per bout (+1/0/-1)",
        "matrix": m["mean"].tolist(),
        "matrix_ci95": [m["low"].tolist(), m["high"].tolist()],
        "wins": r["wins"].tolist(),
        "draws": r["draws"].tolist(),
        "losses": r["wins"].T.tolist(),
        "rating": {
            "method": f"Bradley-Terry MLE on wins + draws/2 with {PRIOR_GAMES:g} virtual draw per pair, Elo scale",
            "elo": {names[k]: float(r["elo"][k]) for k in range(n)},
            "elo_ci95": {names[k]: [float(r["low"][k]), float(r["high"][k])] for k in range(n)},
            "ranking": [names[k] for k in order],
        },
    }


# --------------------------------------------------------------------------- outputs


def heat_map(result: dict, path: Path) -> Path:
    """The matrix as a heat map (red: the row player wins), each cell annotated with its value,
    its interval and the row player's wins/draws/losses; the ranking in the title."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    m = np.asarray(result["matrix"])
    lo, hi = (np.asarray(x) for x in result["matrix_ci95"])
    n = len(m)
    labels = [Path(p).name if p != UNTRAINED else p for p in result["players"]]
    if len(set(labels)) < n:
        labels = list(result["players"])
    vmax = float(np.max(np.abs(m))) or 1.0
    fig, ax = plt.subplots(figsize=(2.0 + 1.6 * n, 1.5 + 1.3 * n))
    im = ax.imshow(m, cmap="RdBu_r", vmin=-vmax, vmax=vmax)
    fmt = "{:+.1f}" if result["sport"] == "boxing" else "{:+.2f}"
    for i in range(n):
        for j in range(n):
            text = fmt.format(m[i, j])
            if i != j:
                w, d, l_ = result["wins"][i][j], result["draws"][i][j], result["losses"][i][j]
                text += f"\n[{fmt.format(lo[i, j])}, {fmt.format(hi[i, j])}]\n{w}/{d}/{l_}"
            dark = abs(m[i, j]) > 0.6 * vmax
            ax.text(j, i, text, ha="center", va="center", fontsize=8, color="white" if dark else "black")
    ax.set_xticks(range(n), labels, rotation=30, ha="right")
    ax.set_yticks(range(n), labels)
    ax.set_xlabel("column player")
    ax.set_ylabel("row player")
    fig.colorbar(im, ax=ax, label=f"row vs column: {result['value']}")
    elo = result["rating"]["elo"]
    order = " > ".join(f"{Path(p).name} ({elo[p]:+.0f})" for p in result["rating"]["ranking"])
    ax.set_title(f"{result['sport']}, {result.get('mode', '')}: cells mean [95%] w/d/l\nElo: {order}", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_json(result: dict, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2))
    return path


# --------------------------------------------------------------------------- players and play


def check_runs(paths: list[Path]) -> str:
    """The sport of the runs at ``paths`` from their configs alone (nothing loaded yet); a
    ``TournamentError`` for a single-player run or runs of different sports, a
    ``RunFolderError`` for a folder that is no run."""
    sports = {}
    for p in paths:
        _, cfg = ckpt.read_config(final_stage(Path(p)), TrainConfig)
        if cfg.env.players != 2:
            raise TournamentError(f"{p} is a single-player run; a tournament needs boxing or fencing runs")
        sports[str(p)] = cfg.env.arena.sport
    if len(set(sports.values())) > 1:
        raise TournamentError(f"mixed sports: {', '.join(f'{p} ({s})' for p, s in sports.items())}")
    return next(iter(sports.values()))


def _acting_config(cfg: TrainConfig) -> TrainConfig:
    """``cfg`` without the fields that only steer training (seed, length, checkpoints)."""
    return dataclasses.replace(cfg, **{k: getattr(TrainConfig(), k) for k in _BOOKKEEPING})


def _shapes(ts) -> tuple:
    """The tree structure and leaf shapes of a state."""
    return jax.tree.structure(ts), tuple(np.shape(x) for x in jax.tree.leaves(ts))


def load_players(paths: list[Path], untrained: bool = False) -> list[tuple[str, object, object]]:
    """(name, learner, state) per run, and with ``untrained`` the first run's configuration with
    freshly initialised networks (its seed), named ``untrained``. Runs whose configurations differ
    only in bookkeeping (seed, iterations, ...) share one learner, so their bouts compile once."""
    players = []
    for p in paths:
        _, cfg, learner, ts = load_run(Path(p))
        for _, other, other_ts in players:
            if _acting_config(other.cfg) == _acting_config(cfg) and _shapes(other_ts) == _shapes(ts):
                learner = other
                break
        players.append((str(p), learner, ts))
    if untrained:
        _, learner, _ = players[0]
        players.append((UNTRAINED, learner, learner.init(jax.random.PRNGKey(learner.cfg.seed))))
    return players


def check_players(players: list) -> tuple[str, list[str]]:
    """(sport, notes) of the players: at least two, distinct names, all two-player runs of one
    sport (else a ``TournamentError``); a note for each whose scene or rules differ from the
    first's (a pair plays in its row player's scene, as ``bouts.run`` does)."""
    if len(players) < 2:
        raise TournamentError(f"a tournament needs at least 2 players, got {len(players)}")
    names = [p[0] for p in players]
    if len(set(names)) < len(names):
        raise TournamentError(f"a player is named twice: {', '.join(names)}")
    for name, learner, _ in players:
        if learner.players != 2:
            raise TournamentError(f"{name} is a single-player run; a tournament needs boxing or fencing runs")
    sports = {name: learner.cfg.env.arena.sport for name, learner, _ in players}
    if len(set(sports.values())) > 1:
        raise TournamentError(f"mixed sports: {', '.join(f'{n} ({s})' for n, s in sports.items())}")
    first = players[0][1].cfg.env
    notes = [
        f"note: {name} was trained in another scene or with other rules; its bouts against later players use "
        f"its scene, so a pair is antisymmetric only within one scene"
        for name, learner, _ in players[1:]
        if learner.cfg.env != first
    ]
    return sports[names[0]], notes


def play_pair(row, column, bouts: int, seeds: int, steps: int | None, deterministic: bool) -> dict:
    """``seeds`` x ``bouts`` bouts of ``row`` = (learner, state) against ``column`` in the row's
    scene, seed s = ``play(..., seed=s)``: the row player's per-bout outcomes [S, N] each."""
    learner, ts = row
    sport = learner.cfg.env.arena.sport
    out = []
    for s in range(seeds):
        _, ro = play(learner, ts, column, bouts=bouts, steps=steps, seed=s, deterministic=deterministic)
        out.append(outcomes(sport, ro, learner.env.dt))
    oc = {k: np.stack([o[k] for o in out]) for k in out[0]}
    oc["value"] = oc["damage_diff"] if sport == "boxing" else oc["score"].astype(np.float64)
    return oc


def run_tournament(
    players: list,
    bouts: int,
    seeds: int = 1,
    steps: int | None = None,
    deterministic: bool = True,
    on_pair=None,
    resamples: int = RESAMPLES,
) -> dict:
    """Plays every unordered pair of ``players`` [(name, learner, state)] once (``play_pair``)
    and returns ``summarize``'s result with the settings, notes and per-pair figures;
    ``on_pair(i, j, pair)`` is called after each pair (progress)."""
    if bouts < 2 or bouts % 2:
        raise TournamentError(f"--bouts={bouts}: must be an even number >= 2 (pairs with the sides swapped)")
    sport, notes = check_players(players)
    names = [p[0] for p in players]
    values, scores, detail = {}, {}, []
    for i in range(len(players)):
        for j in range(i + 1, len(players)):
            oc = play_pair(players[i][1:], players[j][1:], bouts, seeds, steps, deterministic)
            values[i, j], scores[i, j] = oc["value"], oc["score"]
            pair = {
                "row": names[i],
                "column": names[j],
                "mean": float(np.mean(oc["value"])),
                "per_seed_mean": [float(x) for x in oc["value"].mean(1)],
                "wins": int((oc["score"] > 0).sum()),
                "draws": int((oc["score"] == 0).sum()),
                "losses": int((oc["score"] < 0).sum()),
                "bout_length_s_mean": float(np.mean(oc["length_s"])),
                "falls": {"row": int(oc["fall_me"].sum()), "column": int(oc["fall_op"].sum())},
            }
            detail.append(pair)
            if on_pair is not None:
                on_pair(i, j, pair)
    res = summarize(names, sport, values, scores, resamples)
    learner = players[0][1]
    res.update(
        mode="deterministic" if deterministic else "stochastic",
        bouts=bouts,
        seeds=seeds,
        steps=steps or learner.cfg.env.episode_steps,
        round_s=(steps or learner.cfg.env.episode_steps) * learner.env.dt,
        notes=notes,
        pairs=detail,
    )
    return res
