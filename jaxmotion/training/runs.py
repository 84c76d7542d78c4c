"""Run folders: where a run is written, and rebuilding a learner and its state from one.

A run folder holds ``config.json`` (the experiment's name and its full config) and orbax
checkpoints; ``load_run`` needs nothing else, so run folders written by earlier versions of the
code load as long as their config's fields still exist. A run records the absolute folder its
clips came from (``config.json``, ``resolved.data``); loading it without ``$JAXMOTION_DATA`` set
reads the clips from there (``use_recorded_data``).
"""

from __future__ import annotations

import sys
import time
import json
from pathlib import Path

import jax
import jax.numpy as jnp

from jaxmotion.config.checks import validate
from jaxmotion.config.errors import JaxmotionError, cli_errors
from jaxmotion.envs.bout import make_env
from jaxmotion.envs.humanoid import HumanoidEnv
from jaxmotion.motion import data
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.nets.moe import DECODER
from jaxmotion.training.learner import Learner, TrainConfig, TrainState
from jaxmotion.training.meta import Meta, MetaError, resolve_run
from jaxmotion.training.primitives import Primitives


def new_run_dir(experiment: str, root: Path = Path("runs")) -> Path:
    """``runs/<experiment>/<timestamp>`` (with a suffix when that exists already)."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    d = root / experiment / stamp
    n = 1
    while d.exists():
        d = root / experiment / f"{stamp}-{n}"
        n += 1
    return d


def recorded_data_dir(run_dir: Path) -> Path | None:
    """The data folder a run recorded (``config.json``: ``resolved.data``) if it still exists,
    else None (pretrained entries and runs of earlier versions record none)."""
    rec = ckpt.read_resolved(run_dir).get("data")
    return Path(rec) if isinstance(rec, str) and rec and Path(rec).is_dir() else None


def use_recorded_data(run_dir: Path) -> None:
    """Makes the data folder ``run_dir`` recorded the fallback for clips when ``$JAXMOTION_DATA``
    is not set (``motion.data.use_recorded``); a run that recorded none changes nothing."""
    rec = recorded_data_dir(run_dir)
    if rec is not None:
        data.use_recorded(rec)


def make_learner(cfg: TrainConfig, env: HumanoidEnv | None = None) -> Learner:
    """The learner of ``cfg``, with the frozen part its policy builds on loaded from its runs: the
    meta policy ``meta`` names (incremental learning; a meta run may itself be incremental) or the
    primitives a composer weights (``primitives``). Settings are checked before
    anything is loaded."""
    validate(cfg, rules=env is None)
    if cfg.primitives:
        dirs = [resolve_run(p) for p in cfg.primitives]  # missing runs fail before any clip is loaded
        for d in dirs:
            use_recorded_data(d)
        env = env if env is not None else make_env(cfg.env)
        loaded = [(d, *load_run(d)[2:]) for d in dirs]
        return Learner(cfg, env, meta=Primitives(loaded, env))
    if not cfg.meta:
        return Learner(cfg, env)
    meta_dir = resolve_run(cfg.meta)  # a missing meta run fails before any clip is loaded
    use_recorded_data(meta_dir)
    env = env if env is not None else make_env(cfg.env)
    experiment, _, meta_learner, meta_ts = load_run(meta_dir)
    return Learner(cfg, env, meta=Meta(meta_dir, experiment, meta_learner, meta_ts, env))


PIPELINE_FILE = "pipeline.json"
"""A progressive pipeline's record of its stages (``training/progressive.py``)."""


def final_stage(run_dir: Path) -> Path:
    """The run folder a folder stands for: itself, or a progressive pipeline's last finished
    stage (its ``composer/`` once trained)."""
    path = Path(run_dir) / PIPELINE_FILE
    if not path.is_file():
        return Path(run_dir)
    try:
        final = json.loads(path.read_text()).get("final")
    except (OSError, ValueError, AttributeError):
        raise ckpt.RunFolderError(f"{path} is damaged") from None
    if not final:
        raise ckpt.RunFolderError(f"{run_dir}: a progressive pipeline with no finished stage yet")
    return Path(run_dir) / final


def load_run(run_dir: Path) -> tuple[str, TrainConfig, Learner, TrainState]:
    """(experiment, config, learner, restored state) of a run folder (a progressive pipeline's:
    its last finished stage): its newest checkpoint that can be read (a line on stderr per
    damaged newer one), the environments' state left as initialised; clips from
    ``$JAXMOTION_DATA``, else the data folder the run recorded. A ``RunFolderError`` if the
    folder is no usable run."""
    run_dir = final_stage(Path(run_dir))
    experiment, cfg = ckpt.read_config(run_dir, TrainConfig)
    use_recorded_data(run_dir)
    learner = make_learner(cfg)
    like = learner.init(jax.random.PRNGKey(cfg.seed))
    # What an evaluation, a composer or a meta policy uses is the networks and their statistics:
    # the environments' state is left as initialised, so a scene whose state gained a field (a
    # task's timer) still loads the runs it trained before.
    ts, _ = ckpt.restore_run(run_dir, like, skip=ckpt.PER_ENV)
    return experiment, cfg, learner, ts


def init_from(learner: Learner, ts: TrainState, path: str | Path) -> TrainState:
    """``ts`` with everything but the environments taken from the latest checkpoint of the run
    (or ``pretrained/<name>`` entry) at ``path``: parameters, optimiser states, observation,
    discriminator and PopArt statistics, and the iteration count, so a long training goes on
    where that run stopped. The networks must have the same shapes (same experiment settings);
    the mining counts (``PER_CLIP``) come along only when the clip sets are the same size."""
    path = check_init_from(path)
    skip = ckpt.PER_ENV + ("rng",)
    try:
        try:
            src, _ = ckpt.restore_run(path, ts, skip=skip, doing="starting from")
        except ValueError as e:
            if "clip_" not in str(e):
                raise
            # Another clip set (a progressive stage on its predecessor's failed clips): the mining
            # counts are per clip of that set, so this run starts its own.
            src, _ = ckpt.restore_run(path, ts, skip=skip + PER_CLIP, doing="starting from")
    except ckpt.RunFolderError as e:  # no checkpoint, or none that can be read
        raise InitFromError(f"init_from={path}: {e}") from None
    except ValueError as e:  # a leaf of another shape or a missing leaf
        raise InitFromError(
            f"init_from={path} does not fit this experiment's networks or objectives ({str(e).splitlines()[0][:200]})"
        ) from None
    return src


def transfer_decoder(learner: Learner, ts: TrainState, path: str | Path) -> TrainState:
    """``ts`` with its mixture of experts' motor decoder (``nets.moe.DECODER``: the experts and
    sigma) and its body-state statistics taken from the 'moe' run (or pretrained entry) at
    ``path``, the encoder left new: Won et al. §4.3's transfer from imitation pretraining to a
    sport (``decoder_from``). With separate player policies every player gets a copy."""
    try:
        path = check_init_from(resolve_run(path, "decoder_from"))
    except MetaError as e:
        raise InitFromError(str(e)) from None
    try:
        _, scfg, src, sts = load_run(path)
    except ckpt.RunFolderError as e:
        raise InitFromError(f"decoder_from={path}: {e}") from None
    if scfg.net.policy != "moe":
        raise InitFromError(
            f"decoder_from={path}: its policy is net.policy={scfg.net.policy}, not a mixture of experts"
        )
    if src.norm_size != learner.norm_size or src.env.body_obs_size != learner.env.body_obs_size:
        raise InitFromError(
            f"decoder_from={path}: its body state has {src.env.body_obs_size} features (normalised: {src.norm_size}), "
            f"this run's {learner.env.body_obs_size} ({learner.norm_size})"
        )
    mine = ts.policy_params["params"]
    theirs = {k: sts.policy_params["params"][k] for k in DECODER}
    if learner.separate:  # one copy per player
        theirs = jax.tree.map(lambda x: jnp.broadcast_to(x, (learner.players,) + x.shape), theirs)
    shapes = lambda t: jax.tree.map(lambda x: x.shape, t)
    if shapes(theirs) != shapes({k: mine[k] for k in DECODER}):
        raise InitFromError(
            f"decoder_from={path}: its experts (net.experts={scfg.net.experts}, net.expert_hidden="
            f"{scfg.net.expert_hidden}) do not fit this run's "
            f"({learner.cfg.net.experts}, {learner.cfg.net.expert_hidden})"
        )
    norm = sts.obs_norm
    if learner.separate:
        norm = jax.tree.map(lambda x: jnp.broadcast_to(x, (learner.players,) + x.shape), norm)
    put = lambda new, old: jax.device_put(jnp.asarray(new, old.dtype), old.sharding)
    params = {"params": {**mine, **jax.tree.map(put, theirs, {k: mine[k] for k in DECODER})}}
    return ts.replace(
        policy_params=params,
        opt_state=learner.optimizer.init({"actor": params, "critic": ts.critic_params}),
        obs_norm=jax.tree.map(put, norm, ts.obs_norm),
    )


PER_CLIP = ("clip_fails", "clip_weights")
"""The ``TrainState`` fields sized by the run's clip set (hard-negative mining)."""


class InitFromError(JaxmotionError):
    """``init_from`` names something that cannot start this run."""


def check_init_from(path: str | Path) -> Path:
    """``path`` if it is a run folder or pretrained entry, else an ``InitFromError``; the data
    folder it recorded becomes the clips' fallback (``use_recorded_data``)."""
    path = Path(path)
    if not (path / ckpt.CONFIG_FILE).exists():
        raise InitFromError(f"init_from={path}: not a run folder or pretrained entry (no {ckpt.CONFIG_FILE})")
    use_recorded_data(path)
    return path


def spaces_mismatch(runs: list[tuple[Path, Learner]]) -> str | None:
    """Why the policies of these runs cannot take turns on one character (their observation or
    action sizes differ from the first run's), or None."""
    (first, l0), sizes = runs[0], lambda lr: (lr.env.obs_size, lr.env.action_size)
    for r, lr in runs[1:]:
        if sizes(lr) != sizes(l0):
            return (
                f"{r} has observation/action sizes {lr.env.obs_size}/{lr.env.action_size}, "
                f"{first} has {l0.env.obs_size}/{l0.env.action_size}: they cannot take turns"
            )
    return None


@cli_errors
def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 3 or argv[0] != "slim":
        print("usage: python -m jaxmotion.training.runs slim <run-folder> <out-folder>", file=sys.stderr)
        return 2
    _, cfg = ckpt.read_config(Path(argv[1]), TrainConfig)
    use_recorded_data(Path(argv[1]))
    learner = make_learner(cfg)
    step = ckpt.slim(Path(argv[1]), Path(argv[2]), learner.init(jax.random.PRNGKey(cfg.seed)))
    print(f"{argv[2]}: checkpoint {step} without {', '.join(ckpt.PER_ENV)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
