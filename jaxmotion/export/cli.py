"""``python -m jaxmotion.export RUN [--out FILE] [--format onnx|stablehlo] [--check [FILE.onnx]]``.

Exports a run's policy (a run folder or ``pretrained/<name>``) as one function from the last F
MuJoCo states (and a tracker's reference frame) to PD targets (``export/policy.py``), with a JSON
sidecar and the scene's MJCF beside it; ``--check`` replays one episode of it in plain MuJoCo with
onnxruntime, in a process without JAX (``export/check_policy.py``), and compares it with the same
episode in jaxmotion step by step (``export/episode.py``). See ``docs/export.md``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from jaxmotion.config.errors import ConfigError, cli_errors
from jaxmotion.config.checks import check_output
from jaxmotion.export import formats
from jaxmotion.export import policy as P
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.training.learner import TrainConfig
from jaxmotion.training.runs import final_stage, load_run

CHECKER = Path(__file__).with_name("check_policy.py")
SUFFIX = {"onnx": ".onnx", "stablehlo": ".stablehlo"}


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m jaxmotion.export", description=__doc__.split("\n")[0])
    p.add_argument("run", type=Path, help="run folder (runs/<experiment>/<timestamp>) or pretrained/<name>")
    p.add_argument("--out", type=Path, default=None, help="the policy file (default: policy.onnx / policy.stablehlo)")
    p.add_argument("--format", choices=formats.FORMATS, default="onnx")
    p.add_argument(
        "--check",
        nargs="?",
        const="",
        default=None,
        type=str,
        metavar="FILE.onnx",
        help="replay one episode in plain MuJoCo with onnxruntime (no JAX) against jaxmotion's: "
        "of FILE.onnx, or of the policy exported now",
    )
    p.add_argument("--steps", type=int, default=None, help="control steps of the checked episode (default: the run's)")
    p.add_argument("--seed", type=int, default=0, help="which reset the checked episode starts from")
    p.add_argument("--tolerance", type=float, default=1e-3, help="largest PD-target difference that passes (rad)")
    p.add_argument("--min-height", type=float, default=0.4, help="lowest root height (m) that counts as up")
    p.add_argument(
        "--agree-steps",
        type=int,
        default=90,
        help="control steps over which the closed loop must agree to the tolerance (see docs/export.md)",
    )
    return p


def sidecar_paths(out: Path) -> dict[str, Path]:
    """The files written with a policy ``out``: its sidecar and the scene."""
    return {"sidecar": out.with_suffix(".json"), "scene": out.with_suffix(".xml")}


def check_args(args: argparse.Namespace) -> None:
    """Refuses what would fail only after the run is loaded: outputs that cannot be written,
    numbers out of range."""
    if args.steps is not None and args.steps < 1:
        raise ConfigError(f"--steps={args.steps}: must be at least 1")
    if args.agree_steps < 0:
        raise ConfigError(f"--agree-steps={args.agree_steps}: must be at least 0")
    if not args.tolerance > 0:
        raise ConfigError(f"--tolerance={args.tolerance}: must be above 0")
    if args.check:
        if not Path(args.check).is_file():
            raise ConfigError(f"--check {args.check}: no such file")
        if not sidecar_paths(Path(args.check))["sidecar"].is_file():
            raise ConfigError(f"--check {args.check}: no sidecar {Path(args.check).with_suffix('.json')} beside it")
        return
    if args.check is not None and args.format != "onnx":
        raise ConfigError("--check runs ONNX policies: leave out --format stablehlo")
    if args.out is None and args.check is None:
        args.out = Path("policy" + SUFFIX[args.format])
    if args.out is not None:
        for path in (args.out, *sidecar_paths(args.out).values()):
            check_output("--out", path)


def export(learner, ts, fmt: str, out: Path) -> dict[str, Path]:
    """Writes the policy, its sidecar and its scene; returns their paths."""
    fn, layout = P.policy_function(learner, ts)
    paths = sidecar_paths(out)
    formats.write(fmt, fn, layout, out)
    paths["scene"].write_text(P.scene_xml(learner.cfg.env.physics))
    files = {"policy": out.name, "format": fmt, "scene": paths["scene"].name}
    paths["sidecar"].write_text(json.dumps(P.sidecar(learner, layout, files), indent=1) + "\n")
    return {"policy": out, **paths}


def run_checker(policy: Path, episode, work: Path) -> dict[str, np.ndarray]:
    """The standalone checker's results on ``episode``, run in a fresh Python process by path (so
    that it imports neither jaxmotion nor JAX)."""
    ep, out = work / "episode.npz", work / "checked.npz"
    np.savez(ep, **episode.arrays())
    cmd = [sys.executable, str(CHECKER), str(policy), str(ep), str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"the checker failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return dict(np.load(out))


def compare(episode, checked: dict[str, np.ndarray], args) -> tuple[bool, list[str]]:
    """(passed, report lines) of the checker's episode against jaxmotion's.

    The function must agree on jaxmotion's own states at every step; the two closed-loop
    simulations, over the first ``--agree-steps`` steps (after that a contact event amplifies the
    float32 differences of two runtimes and the episodes part, see docs/export.md); the character
    must stay up in both for the whole episode."""
    n, tol = len(episode.targets), args.tolerance
    diff = np.abs(checked["targets"] - episode.targets).max(-1) if n else np.zeros(1)
    opened = float(np.abs(checked["open_loop"] - episode.targets).max()) if n else 0.0
    parted = int(np.argmax(diff > tol)) if (diff > tol).any() else n
    agree = min(args.agree_steps, n)
    low, low_jm = float(checked["root_height"].min()), float(episode.root_height.min())
    up = low > args.min_height and not episode.ended
    no_jax = not bool(checked["jax_imported"])
    lines = [
        f"  PD targets, onnxruntime on jaxmotion's states:  max |diff| {opened:.2e} rad over {n} steps",
        f"  PD targets, closed loop in plain MuJoCo:        max |diff| {float(diff[:agree].max()):.2e} rad over the "
        f"first {agree} steps; within {tol:g} for {parted} steps, max {float(diff.max()):.2e} over the episode",
        f"  root height: min {low:.3f} m (jaxmotion {low_jm:.3f} m, threshold {args.min_height:g} m): "
        + ("stayed up" if up else "FELL" if low <= args.min_height else "jaxmotion's episode was terminated"),
        f"  checker process: {'jax not imported' if no_jax else 'JAX WAS IMPORTED'}",
    ]
    return opened <= tol and parted >= agree and up and no_jax and n > 0, lines


def check(learner, ts, policy: Path, args) -> int:
    from jaxmotion.export.episode import reference_episode

    steps = args.steps or learner.cfg.env.episode_steps
    episode = reference_episode(learner, ts, steps, args.seed)
    with tempfile.TemporaryDirectory() as work:
        checked = run_checker(policy, episode, Path(work))
    ok, lines = compare(episode, checked, args)
    print(f"check of {policy} against {args.run}: {len(episode.targets)} of {steps} control steps from seed")
    print(f"{args.seed} (MuJoCo C in jaxmotion and plain MuJoCo + onnxruntime, mean actions)")
    print("\n".join(lines))
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


@cli_errors
def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    check_args(args)
    _, cfg = ckpt.read_config(final_stage(args.run), TrainConfig)
    why = P.unsupported(cfg)
    if why:  # decided from the config, before any clip or checkpoint is loaded
        raise P.ExportError(f"{args.run}: {why}")
    _, cfg, learner, ts = load_run(args.run)
    if args.check:
        return check(learner, ts, Path(args.check), args)
    with tempfile.TemporaryDirectory() as work:
        out = args.out if args.out is not None else Path(work) / "policy.onnx"
        written = export(learner, ts, args.format, out)
        if args.out is not None:
            size = written["policy"].stat().st_size
            print(f"{written['policy']} ({size / 1e6:.2f} MB, {args.format}), {written['sidecar']}, {written['scene']}")
        return check(learner, ts, out, args) if args.check is not None else 0
