"""``python -m jaxmotion.eval <run-folder> [--episodes N] [--json FILE] [--video FILE] [--html FILE]``.

Rebuilds the learner from the run folder alone (``config.json`` + the latest checkpoint; a
``pretrained/<name>`` entry is a run folder too), then hands it to its task's evaluator
(``jaxmotion.evaluation``): imitation runs get DTW errors per body group, tracker runs clip-by-clip
success and MPJPE, two-player runs bout results. Each evaluator owns its flags.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax

from jaxmotion.config.errors import cli_errors
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


@cli_errors
def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    for out in (args.json, args.video, args.html):
        if out is not None:
            out.parent.mkdir(parents=True, exist_ok=True)
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
