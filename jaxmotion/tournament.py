"""``python -m jaxmotion.tournament RUN [RUN ...] --bouts N [--seeds S] [--untrained] [--out DIR]``.

Plays every pair of two-player runs (boxing or fencing) with the sides swapped and writes the
antisymmetric matrix of mean per-bout results with bootstrap intervals, win/draw/loss counts and
Bradley-Terry ratings (Elo scale) to ``DIR/tournament.json`` and a heat map ``DIR/tournament.png``
(``jaxmotion.evaluation.tournament``).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from jaxmotion.config.checks import Min, show
from jaxmotion.config.errors import ConfigError, cli_errors
from jaxmotion.evaluation import tournament as T


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m jaxmotion.tournament", description=__doc__.split("\n")[0])
    p.add_argument("runs", type=Path, nargs="+", metavar="RUN", help="run folders or pretrained/<name> entries")
    p.add_argument("--bouts", type=int, required=True, help="bouts per pair and seed (even: sides swapped in pairs)")
    p.add_argument("--seeds", type=int, default=1, help="evaluation seeds 0..S-1, each N bouts (default 1)")
    p.add_argument("--steps", type=int, default=None, help="control steps per bout (default: the run's round)")
    p.add_argument(
        "--untrained", action="store_true", help="add the first run's configuration with fresh networks as a player"
    )
    p.add_argument("--stochastic", action="store_true", help="sample actions (default: deterministic, the mean)")
    p.add_argument("--out", type=Path, default=Path("tournament"), help="output folder (default ./tournament)")
    return p


NUMBERS = {"bouts": Min(2), "seeds": Min(1), "steps": Min(1)}


def check_args(args: argparse.Namespace) -> None:
    """Refuses, before anything loads, numbers out of range, odd ``--bouts``, fewer than two
    players, a run named twice and an output folder that is a file."""
    for name, mark in NUMBERS.items():
        value = getattr(args, name)
        if value is None:
            continue
        problem = "must be a finite number" if not math.isfinite(value) else mark.problem(value)
        if problem:
            raise ConfigError(f"--{name}={show(value)}: {problem}")
    if args.bouts % 2:
        raise ConfigError(f"--bouts={args.bouts}: must be even (each pair of bouts swaps the players' sides)")
    if len(args.runs) + args.untrained < 2:
        raise T.TournamentError("a tournament needs at least 2 players: give two runs, or one run and --untrained")
    if len({str(r) for r in args.runs}) < len(args.runs):
        raise T.TournamentError("a run is given twice")
    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"--out={args.out}: is a file, not a folder")


def progress(n: int, sport: str):
    """A callback printing each pair's result as it finishes."""
    total = n * (n - 1) // 2
    done = [0]
    unit = " N" if sport == "boxing" else ""

    def on_pair(i: int, j: int, pair: dict) -> None:
        done[0] += 1
        print(
            f"[{done[0]}/{total}] {pair['row']} vs {pair['column']}: {pair['mean']:+.2f}{unit} per bout, "
            f"{pair['wins']}/{pair['draws']}/{pair['losses']} win/draw/loss, bouts {pair['bout_length_s_mean']:.1f} s",
            flush=True,
        )

    return on_pair


def report(res: dict) -> None:
    """The ranking with its intervals."""
    r = res["rating"]
    print(f"ranking ({r['method']}):")
    for k, name in enumerate(r["ranking"], 1):
        lo, hi = r["elo_ci95"][name]
        print(f"  {k}. {name}: {r['elo'][name]:+.0f} Elo [{lo:+.0f}, {hi:+.0f}]")


@cli_errors
def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    check_args(args)
    sport = T.check_runs(args.runs)
    players = T.load_players(args.runs, args.untrained)
    _, notes = T.check_players(players)
    for note in notes:
        print(note)
    mode = "stochastic" if args.stochastic else "deterministic"
    print(
        f"{sport}: {len(players)} players, {args.seeds} seed(s) x {args.bouts} bouts per pair "
        f"(sides swapped in pairs), {mode} actions"
    )
    res = T.run_tournament(
        players, args.bouts, args.seeds, args.steps, not args.stochastic, progress(len(players), sport)
    )
    report(res)
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"json: {T.write_json(res, args.out / 'tournament.json')}")
    print(f"heat map: {T.heat_map(res, args.out / 'tournament.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
