"""``python -m jaxmotion.eval <run-folder> [--episodes N] [--json FILE] [--video FILE] [--html FILE]``.

Rebuilds the learner from the run folder alone (``config.json`` + the latest checkpoint; a
``pretrained/<name>`` entry is a run folder too), then hands it to its task's evaluator
(``jaxmotion.evaluation``): imitation runs get DTW errors per body group, tracker runs clip-by-clip
success and MPJPE, two-player runs bout results. Each evaluator owns its flags.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import jax

from jaxmotion.config.checks import Min, check_output, show
from jaxmotion.config.errors import ConfigError, cli_errors
from jaxmotion.evaluation import EVALUATORS, evaluator_of
from jaxmotion.training.runs import load_run


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m jaxmotion.eval", description=__doc__.split("\n")[0])
    p.add_argument("run", type=Path, help="run folder (runs/<experiment>/<timestamp>) or pretrained/<name>")
    p.add_argument("--episodes", type=int, default=None, help="episodes (default: the config's eval_episodes)")
    p.add_argument(
        "--steps",
        type=int,
        default=None,
        help="control steps per episode or bout (default: the config's episode length)",
    )
    p.add_argument("--json", type=Path, default=None, help="also write the metrics here")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--untrained",
        action="store_true",
        help="evaluate the run's configuration with freshly initialised networks (its seed): the baseline",
    )
    p.add_argument(
        "--video", type=Path, default=None, help="render episode 0 with its reference as a ghost (.mp4, or .gif)"
    )
    p.add_argument("--html", type=Path, default=None, help="write episode 0 as a self-contained 3D replay page (.html)")
    p.add_argument(
        "--no-plots", action="store_true", help="do not write learning-curve PNGs (plot_*.png) into the run folder"
    )
    for ev in EVALUATORS.values():
        ev.add_arguments(p)
    return p


NUMBERS = {
    "episodes": Min(1),
    "steps": Min(1),
    "bouts": Min(1),
    "switch_every": Min(0, open=True),
    "noise": Min(0),
    "trials": Min(1),
}
"""The numeric flags (the evaluators' included) and their ranges, checked before the run loads."""
OUTPUTS = ("json", "video", "html")


def check_args(args: argparse.Namespace) -> None:
    """Refuses, before the run is loaded or rolled out, a number out of its range and an output
    that cannot be written (its folder is made here; an output may go into a new folder)."""
    for name, mark in NUMBERS.items():
        value = getattr(args, name, None)
        if value is None:
            continue
        problem = "must be a finite number" if not math.isfinite(value) else mark.problem(value)
        if problem:
            raise ConfigError(f"--{name.replace('_', '-')}={show(value)}: {problem}")
    if getattr(args, "bouts", None) is not None and args.bouts % 2:
        raise ConfigError(f"--bouts={args.bouts}: must be even (each pair of bouts swaps the players' sides)")
    for name in OUTPUTS:
        if getattr(args, name) is not None:
            check_output(f"--{name}", getattr(args, name))


@cli_errors
def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    check_args(args)
    try:
        experiment, cfg, learner, ts = load_run(args.run)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if args.untrained:
        ts = learner.init(jax.random.PRNGKey(cfg.seed))
        experiment += " (untrained)"
    return evaluator_of(learner).run(args, experiment, cfg, learner, ts)


if __name__ == "__main__":
    sys.exit(main())
