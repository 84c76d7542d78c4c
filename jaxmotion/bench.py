"""Throughput benchmarks: physics only, policy rollout, and the full training loop.

``python -m jaxmotion.bench [--quick] [--batches 64,256,1024] [--parts physics,rollout,train]
[--exp composite/chest_open+squat] [--out bench.json]`` prints a table and writes JSON;
``--time-to-result RUN [--targets upper=0.10,lower=0.09]`` instead reads a training run's log:
the samples and wall time it took to reach the targets (``evaluation/time_to_result.py``). ``make
bench`` runs all three parts at batches 64, 256 and 1024 (and 4096, 16384 on a GPU).

* **physics**: one jitted ``lax.scan`` over ``--steps`` control steps of ``vmap(pd_step)`` on a
  batch of standing characters (PD targets 0, small random joint offsets so the batch elements
  differ), state donated. Beside it, MuJoCo C steps the same model (``sim.mj_model``) from the
  same initial states on the same cores with ``mujoco.rollout`` (native thread pool), falling back
  to a Python loop over ``mj_step`` when that is unavailable (``mujoco_c_method`` says which).
  Both are reported in control steps per second (one control step = ``substeps`` physics steps).
  ``callback_control_steps_per_s`` is the MuJoCo C backend as the env calls it (``jax.pure_callback``
  into ``mujoco.rollout`` from a jitted scan).
* **rollout**: ``Learner.rollout`` (``horizon`` control steps of policy + env), jitted, donated;
  one row per physics backend (``--backends``, default ``mjx,mujoco``; each row's ``backend``).
  Two-player experiments (``--exp boxing/selfplay --parts rollout,train``) count player-steps:
  each bout step is two samples.
* **train**: ``make_train_chunk`` (``--iters`` whole iterations in one jitted scan, default 1:
  the scan adds nothing per iteration, and one iteration at batch 1024 already takes seconds).

Both report ``physics_cost_ratio``, the time per control step relative to physics alone at the
same batch: the full training iteration's is the "learning overhead" (1.0 = no cost beyond
physics). ``peak_mem_mb`` is the device's peak bytes in use where it reports them, else the
process's peak resident memory, which only grows over a run (batches go smallest first).

Compilation is timed separately (``compile_s``: lowering plus XLA compile) and followed by one
untimed warm-up call. All parts at one batch size are then timed in ``--rounds`` alternating
rounds that together last at least ``--seconds`` per part (the physics calls each from the same
initial states), so that a slow spell of the host slows physics and training alike. Batch 256
stays in the default list because jax 0.10.2 hung there (DESIGN.md); ``--timeout`` turns a hang
into an exit with a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import faulthandler
import functools
import json
import math
import os
import resource
import sys
import time
from typing import Annotated, Any, Literal
from collections.abc import Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from jaxmotion.physics import sim
from jaxmotion.physics.backends import cpu_count
from jaxmotion.config.checks import Count, Min, NonEmpty, NonNegative, validate
from jaxmotion.config.errors import cli_errors
from jaxmotion.evaluation import time_to_result

ROOT_HEIGHT = 0.89
"""Standing root height (m) of the humanoid with all joint angles 0."""
DEFAULT_BATCHES = (64, 256, 1024)
GPU_EXTRA_BATCHES = (4096, 16384)


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    """What to measure and for how long."""

    batches: Annotated[tuple[int, ...], Min(1), NonEmpty()] = DEFAULT_BATCHES
    steps: Count = 8
    """Control steps per physics call (the length of the jitted scan)."""
    seconds: NonNegative = 3.0
    """Minimum measuring time per number (calls repeat until it has passed)."""
    rounds: Count = 3
    """The parts at one batch size are timed in this many alternating rounds."""
    noise: NonNegative = 0.02
    """Standard deviation (rad) of the random joint-angle offsets of the initial states."""
    seed: int = 0
    exp: Annotated[str, NonEmpty()] = "composite/chest_open+squat"
    """Experiment whose config the rollout and train parts use (num_envs = batch)."""
    iters: Annotated[int, Min(0)] = 1
    """Train: iterations per compiled chunk; 0 keeps the experiment's ``chunk``."""
    overrides: tuple[str, ...] = ()
    """``key=value`` overrides of the experiment's config, as ``make train ARGS=...`` takes."""
    physics: sim.PhysicsConfig = sim.PhysicsConfig()
    backends: Annotated[tuple[Literal["mjx", "mujoco"], ...], NonEmpty()] = ("mjx", "mujoco")
    """Physics backends of the rollout and train rows (each row says its ``backend``)."""


# ---- helpers ------------------------------------------------------------------------------
def device_description() -> str:
    """The first JAX device and the host's CPU model and count, in one line."""
    d = jax.devices()[0]
    cpu = ""
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), "")
    except OSError:
        pass
    kind = f"{d.platform}:{d.device_kind}" if d.device_kind.lower() != d.platform else d.platform
    return f"{kind} x{jax.device_count()}; host {cpu or 'cpu'}, {cpu_count()} CPUs"


def peak_memory_mb() -> float:
    """Peak device memory (MB) where the device reports it, else this process's max RSS (MB)."""
    try:
        stats = jax.devices()[0].memory_stats() or {}
    except Exception:  # noqa: BLE001 - backends without memory stats raise various errors
        stats = {}
    if stats.get("peak_bytes_in_use"):
        return stats["peak_bytes_in_use"] / 2**20
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux, bytes on macOS
    return rss / (2**20 if sys.platform == "darwin" else 2**10)


def time_calls(
    fn: Callable[[Any], Any], state: Any, seconds: float, fresh: Callable[[], Any] | None = None
) -> tuple[Any, int, float]:
    """Calls ``state = fn(state)`` (blocking on the result) until ``seconds`` have passed.

    Args:
        fn: the function to time.
        state: its first input; later calls get the previous output.
        seconds: minimum total time of the calls (at least one call is made).
        fresh: if given, every call starts from ``fresh()`` instead (made outside the timing).

    Returns:
        The last output, the number of calls and the seconds spent inside ``fn``.
    """
    n, elapsed = 0, 0.0
    while n == 0 or elapsed < seconds:
        if fresh is not None:
            state = jax.block_until_ready(fresh())
        t0 = time.perf_counter()
        state = jax.block_until_ready(fn(state))
        elapsed += time.perf_counter() - t0
        n += 1
    return state, n, elapsed


def standing_qpos(m: mujoco.MjModel, batch: int, noise: float, seed: int) -> np.ndarray:
    """[batch, nq] standing poses (identity root at 0.89 m) with random joint offsets."""
    q = np.zeros((batch, m.nq))
    q[:, 2], q[:, 3] = ROOT_HEIGHT, 1.0
    q[:, 7:] = np.random.default_rng(seed).normal(0.0, noise, (batch, m.nq - 7))
    return q


# ---- timed programs -----------------------------------------------------------------------
@dataclasses.dataclass
class Timed:
    """A compiled program timed in rounds: ``state = fn(state)`` (from ``fresh()`` if given)."""

    fn: Callable[[Any], Any]
    state: Any
    steps_per_call: int
    """Control steps one call advances (batch x steps)."""
    fresh: Callable[[], Any] | None = None
    calls: int = 0
    elapsed: float = 0.0

    def measure(self, seconds: float) -> None:
        self.state, n, e = time_calls(self.fn, self.state, seconds, self.fresh)
        self.calls += n
        self.elapsed += e

    @property
    def rate(self) -> float:
        """Control steps per second over every timed call so far."""
        return self.steps_per_call * self.calls / self.elapsed


def _compile(fn, *args, **jit_kwargs):
    """``(compiled, seconds)``: lowering plus XLA compilation of ``jax.jit(fn)`` for ``args``."""
    t0 = time.perf_counter()
    compiled = jax.jit(fn, **jit_kwargs).lower(*args).compile()
    return compiled, time.perf_counter() - t0


# ---- physics ------------------------------------------------------------------------------
def prepare_mjx(cfg: BenchConfig, qpos: np.ndarray) -> tuple[Timed, dict[str, float]]:
    """MJX stepping the initial poses ``qpos`` [B, nq] for ``cfg.steps`` control steps per call."""
    model = sim.mjx_model(cfg.physics)
    step = jax.vmap(functools.partial(sim.pd_step, substeps=cfg.physics.substeps), in_axes=(None, 0, None))

    def run(model, data, target):
        data, _ = jax.lax.scan(lambda d, _: (step(model, d, target), None), data, None, length=cfg.steps)
        return data

    d0 = mjx.make_data(model)
    data = jax.vmap(lambda q: d0.replace(qpos=q))(jnp.asarray(qpos, d0.qpos.dtype))
    target = jnp.zeros((model.nu,), d0.ctrl.dtype)
    compiled, compile_s = _compile(run, model, data, target, donate_argnums=1)
    # Every call starts from the initial poses, as the MuJoCo C rollouts do: held at zero targets
    # with no balance control, the characters would fall over some tens of seconds in.
    fresh = lambda: jax.tree.map(jnp.copy, data)
    timed = Timed(lambda d: compiled(model, d, target), None, qpos.shape[0] * cfg.steps, fresh)
    jax.block_until_ready(timed.fn(fresh()))  # warm-up
    return timed, {"compile_s": compile_s}


def prepare_callback(cfg: BenchConfig, qpos: np.ndarray) -> tuple[Timed, dict[str, float]]:
    """The MuJoCo C backend as the env uses it: ``jax.pure_callback`` into ``mujoco.rollout``
    from a jitted ``lax.scan``, the same calls and initial poses as ``prepare_mjx``."""
    from jaxmotion.physics import backends

    pc = cfg.physics
    phys = backends.MujocoPhysics(sim.scene_xml(pc), sim.mj_model(pc), sim.mjx_model(pc), pc.substeps, cpu_count())
    step = jax.vmap(phys.step, in_axes=(0, None))

    def run(data, target):
        return jax.lax.scan(lambda d, _: (step(d, target)[0], None), data, None, length=cfg.steps)[0]

    d0 = mjx.make_data(sim.mjx_model(pc))
    data = jax.vmap(lambda q: d0.replace(qpos=q))(jnp.asarray(qpos, d0.qpos.dtype))
    target = jnp.zeros((phys.mj.nu,), jnp.float32)
    compiled, _ = _compile(run, data, target, donate_argnums=0)
    fresh = lambda: jax.tree.map(jnp.copy, data)
    timed = Timed(lambda d: compiled(d, target), None, qpos.shape[0] * cfg.steps, fresh)
    jax.block_until_ready(timed.fn(fresh()))  # warm-up
    return timed, {}


def prepare_mujoco_c(cfg: BenchConfig, qpos: np.ndarray, stack: contextlib.ExitStack) -> tuple[Timed, dict[str, Any]]:
    """MuJoCo C from the same initial poses, ctrl held at 0, on all usable CPUs.

    ``mujoco.rollout``'s native thread pool (kept open on ``stack``) where available, else a
    Python loop over ``mj_step``. The timed state is the final root heights ``[B]``.
    """
    m = sim.mj_model(cfg.physics)
    nstep = cfg.steps * cfg.physics.substeps
    batch = qpos.shape[0]
    d = mujoco.MjData(m)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    init = np.empty((batch, mujoco.mj_stateSize(m, spec)))
    for i in range(batch):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = qpos[i]
        mujoco.mj_getState(m, d, init[i], spec)
    try:
        from mujoco import rollout
    except ImportError:
        rollout = None
    if rollout is not None and hasattr(rollout, "Rollout"):
        nthread = cpu_count()
        datas = [mujoco.MjData(m) for _ in range(nthread)]
        ctrl = np.zeros((1, 1, m.nu))
        out = np.empty((batch, nstep, init.shape[1]))
        pool = stack.enter_context(rollout.Rollout(nthread=nthread))

        def fn(_):
            pool.rollout(m, datas, init, ctrl, nstep=nstep, state=out)
            return out[:, -1, 1 + 2].copy()

        method = f"mujoco.rollout nthread={nthread}"
    else:
        datas = [mujoco.MjData(m) for _ in range(batch)]

        def fn(_):
            for dd, st in zip(datas, init):
                mujoco.mj_setState(m, dd, st, spec)
                dd.ctrl[:] = 0.0
                mujoco.mj_step(m, dd, nstep)
            return np.array([dd.qpos[2] for dd in datas])

        method = "python loop over mj_step (1 thread)"
    timed = Timed(fn, fn(None), batch * cfg.steps)  # the first call is the warm-up
    return timed, {"mujoco_c_method": method}


# ---- rollout and train --------------------------------------------------------------------
def _learner(cfg: BenchConfig, batch: int, backend: str = "auto"):
    """A ``Learner`` for ``cfg.exp`` with ``num_envs = batch`` (minibatches shrunk to fit) on
    physics ``backend``."""
    from jaxmotion import config as C
    from jaxmotion.training.learner import Learner

    tc = C.apply_overrides(C.load_experiment(cfg.exp), cfg.overrides + (f"env.physics.backend={backend}",))
    n = batch * tc.ppo.horizon * tc.env.players
    fit = lambda mb: math.gcd(n, mb)  # the largest size <= mb that divides the sample count
    tc = dataclasses.replace(
        tc,
        ppo=dataclasses.replace(tc.ppo, num_envs=batch, minibatch_size=fit(tc.ppo.minibatch_size)),
        disc=dataclasses.replace(tc.disc, minibatch_size=fit(tc.disc.minibatch_size)),
    )
    if cfg.iters:
        tc = dataclasses.replace(tc, chunk=cfg.iters, iterations=cfg.iters)  # a run of one chunk
    return Learner(tc), tc


def check_clips(cfg: BenchConfig) -> None:
    """Loads every clip of the benchmarked experiment (raises ``MotionFileError`` if one is bad)."""
    from jaxmotion import config as C
    from jaxmotion.motion.loaders import load_clips

    env = C.apply_overrides(C.load_experiment(cfg.exp), cfg.overrides).env
    for paths in [env.init_motions] + [g.motions for g in env.groups]:
        if paths:
            load_clips(paths)


def prepare_rollout(cfg: BenchConfig, batch: int, backend: str) -> tuple[Timed, dict[str, float]]:
    """``Learner.rollout`` (policy + env, ``horizon`` control steps per call), state donated."""
    learner, tc = _learner(cfg, batch, backend)
    ts = learner.init(jax.random.PRNGKey(cfg.seed))
    compiled, compile_s = _compile(learner.rollout, ts, donate_argnums=0)
    fn = lambda s: compiled(s[0])
    state = jax.block_until_ready(fn((ts,)))  # warm-up
    return Timed(fn, state, batch * tc.ppo.horizon * tc.env.players), {"compile_s": compile_s}


def prepare_train(cfg: BenchConfig, batch: int, backend: str) -> tuple[Timed, dict[str, float]]:
    """Whole training iterations (``make_train_chunk``, ``chunk`` of them per call), donated."""
    from jaxmotion.training.loop import make_mesh, make_train_chunk, shard_state

    learner, tc = _learner(cfg, batch, backend)
    mesh = make_mesh()
    ts = shard_state(learner.init(jax.random.PRNGKey(cfg.seed)), mesh)
    t0 = time.perf_counter()
    compiled = make_train_chunk(learner, mesh, tc.chunk, ts).lower(ts).compile()
    compile_s = time.perf_counter() - t0
    fn = lambda s: compiled(s[0])
    state = jax.block_until_ready(fn((ts,)))  # warm-up
    return Timed(fn, state, batch * tc.ppo.horizon * tc.chunk * tc.env.players), {"compile_s": compile_s}


PARTS = ("physics", "rollout", "train")


def bench_batch(
    cfg: BenchConfig, batch: int, parts: list[str], errors: dict[str, str], log: Callable[[str], None] = print
) -> dict[str, dict[str, Any]]:
    """Compiles every part at one batch size, then times them in ``cfg.rounds`` alternating rounds.

    Alternating makes a slow spell of the host (other processes, a noisy neighbour) hit physics
    and training alike, so their ratio holds even when the absolute numbers wander. A part that
    fails to build is recorded in ``errors`` (physics failures are raised).

    Returns:
        ``{part: [rows]}`` for the parts that ran (rollout and train: one row per backend).
    """
    rows: dict[str, dict[str, Any]] = {}
    timers: dict[str, Timed] = {}
    with contextlib.ExitStack() as stack:
        for part in parts:
            log(f"{part}: batch {batch} (compiling) ...")
            try:
                if part == "physics":
                    qpos = standing_qpos(sim.mj_model(cfg.physics), batch, cfg.noise, cfg.seed)
                    timers["physics"], rows["physics"] = prepare_mjx(cfg, qpos)
                    timers["mujoco_c"], info = prepare_mujoco_c(cfg, qpos, stack)
                    rows["physics"].update(info)
                    timers["callback"], _ = prepare_callback(cfg, qpos)
                else:
                    for be in cfg.backends:
                        key = f"{part}:{be}"
                        try:
                            prep = prepare_rollout if part == "rollout" else prepare_train
                            timers[key], rows[key] = prep(cfg, batch, be)
                            rows[key]["backend"] = be
                        except Exception as err:  # noqa: BLE001 - later parts and the JSON still get written
                            errors[key] = f"{type(err).__name__}: {err}"
                            log(f"{key}: FAILED: {errors[key]}")
            except Exception as err:  # noqa: BLE001
                if part == "physics":
                    raise
                errors[part] = f"{type(err).__name__}: {err}"
                log(f"{part}: FAILED: {errors[part]}")
        rounds = max(1, cfg.rounds)
        for r in range(rounds):
            log(f"  timing round {r + 1}/{rounds}")
            for t in timers.values():
                t.measure(cfg.seconds / rounds)
    mem = peak_memory_mb()
    if "physics" in rows:
        rows["physics"].update(
            {
                "batch": batch,
                "mjx_control_steps_per_s": timers["physics"].rate,
                "mjx_root_height": float(jnp.mean(timers["physics"].state.qpos[:, 2])),
                "mujoco_c_control_steps_per_s": timers["mujoco_c"].rate,
                "mujoco_c_root_height": float(np.mean(timers["mujoco_c"].state)),
                "callback_control_steps_per_s": timers["callback"].rate,
            }
        )
    out: dict[str, list[dict[str, Any]]] = {}
    for key, row in rows.items():
        if key == "physics":
            out["physics"] = [row]
            continue
        row.update({"batch": batch, "control_steps_per_s": timers[key].rate, "peak_mem_mb": mem})
        out.setdefault(key.split(":")[0], []).append(row)
    summary = ", ".join(f"{k} {t.rate:.0f}/s" for k, t in timers.items())
    log(f"  batch {batch}: {summary}")
    return out


# ---- report -------------------------------------------------------------------------------
def add_physics_ratios(result: dict[str, Any]) -> None:
    """On rollout and train rows whose batch also has a physics row: ``physics_cost_ratio``, the
    cost of a control step relative to the same backend's physics alone (MJX, or the C backend
    through its callback), and ``fraction_of_bare_c``, this rate over MuJoCo C's bare rollout."""
    by_batch = {r["batch"]: r for r in result.get("physics", [])}
    for part in ("rollout", "train"):
        for row in result.get(part, []):
            phys = by_batch.get(row["batch"])
            if phys is None or not row.get("control_steps_per_s"):
                continue
            key = "callback_control_steps_per_s" if row.get("backend") == "mujoco" else "mjx_control_steps_per_s"
            if phys.get(key):
                row["physics_cost_ratio"] = phys[key] / row["control_steps_per_s"]
            if phys.get("mujoco_c_control_steps_per_s"):
                row["fraction_of_bare_c"] = row["control_steps_per_s"] / phys["mujoco_c_control_steps_per_s"]


def format_table(rows: list[dict[str, Any]], columns: list[tuple[str, str, str]]) -> str:
    """An aligned text table of ``rows``; ``columns`` are (header, key, format) triples."""
    cells = [[h for h, _, _ in columns]]
    cells += [[format(r[k], f) if k in r else "-" for _, k, f in columns] for r in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(columns))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in cells)


def report(result: dict[str, Any]) -> str:
    """The tables of every part that has rows."""
    out = [f"device: {result['device']}  (jax {result['jax_version']}, mujoco {result['mujoco_version']})"]
    if result["physics"]:
        rows = [
            dict(r, ratio=r["mujoco_c_control_steps_per_s"] / r["mjx_control_steps_per_s"]) for r in result["physics"]
        ]
        out += [
            "",
            f"physics (control steps/s; 1 control step = {result['settings']['substeps']} physics steps; "
            f"C: {rows[0]['mujoco_c_method']})",
            format_table(
                rows,
                [
                    ("batch", "batch", "d"),
                    ("mjx", "mjx_control_steps_per_s", ".0f"),
                    ("mujoco C", "mujoco_c_control_steps_per_s", ".0f"),
                    ("C/mjx", "ratio", ".1f"),
                    ("C callback", "callback_control_steps_per_s", ".0f"),
                    ("compile s", "compile_s", ".1f"),
                    ("mjx root z", "mjx_root_height", ".3f"),
                ],
            ),
        ]
    for part in ("rollout", "train"):
        if result[part]:
            out += [
                "",
                f"{part} (control steps/s; cost/physics = time per control step over physics alone;"
                f" exp {result['settings']['exp']})",
                format_table(
                    result[part],
                    [
                        ("batch", "batch", "d"),
                        ("backend", "backend", "s"),
                        ("steps/s", "control_steps_per_s", ".0f"),
                        ("cost/physics", "physics_cost_ratio", ".2f"),
                        ("of bare C", "fraction_of_bare_c", ".2f"),
                        ("compile s", "compile_s", ".1f"),
                        ("peak MB", "peak_mem_mb", ".0f"),
                    ],
                ),
            ]
    for part, msg in result.get("errors", {}).items():
        out += ["", f"{part}: FAILED: {msg}"]
    return "\n".join(out)


def run(cfg: BenchConfig, parts: list[str], timeout: float = 0.0) -> dict[str, Any]:
    """Runs ``parts`` at every batch size and returns the JSON-ready result.

    Args:
        cfg: what to measure.
        parts: a subset of ``PARTS``.
        timeout: seconds after which a batch size that has not finished aborts the process with
            a traceback (a hung compile or execution, as with jax 0.10.2); 0 disables.
    """
    result = {
        "device": device_description(),
        "jax_version": jax.__version__,
        "mujoco_version": mujoco.__version__,
        "settings": {
            "control_steps_per_call": cfg.steps,
            "substeps": cfg.physics.substeps,
            "sim_hz": cfg.physics.sim_hz,
            "min_seconds": cfg.seconds,
            "rounds": cfg.rounds,
            "exp": cfg.exp,
            "overrides": list(cfg.overrides),
            "train_iterations_per_call": cfg.iters or "experiment chunk",
            # With a persistent cache, compile_s of a cache hit is the load time.
            "compilation_cache": jax.config.jax_compilation_cache_dir or None,
        },
        "physics": [],
        "rollout": [],
        "train": [],
        "errors": {},
    }
    log = lambda s: print(s, file=sys.stderr, flush=True)
    for batch in cfg.batches:
        if timeout > 0:
            faulthandler.dump_traceback_later(timeout, exit=True)
        try:
            todo = [p for p in PARTS if p in parts and p not in result["errors"]]
            for part, rows in bench_batch(cfg, batch, todo, result["errors"], log).items():
                result[part].extend(rows)
        finally:
            faulthandler.cancel_dump_traceback_later()
    add_physics_ratios(result)
    if hasattr(os, "getloadavg"):  # other processes on the host make the numbers noisy
        result["settings"]["host_load_avg_1_5_15min"] = [round(x, 2) for x in os.getloadavg()]
    return result


@cli_errors
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m jaxmotion.bench", description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="tiny run for tests: batches 1,4, 2 steps, no timing floor")
    p.add_argument("--batches", help="comma-separated batch sizes (default 64,256,1024; on GPU also 4096,16384)")
    p.add_argument(
        "--parts", default="physics,rollout,train", help="physics,rollout,train (default) or a comma-separated subset"
    )
    p.add_argument("--steps", type=int, help="control steps per physics call (default 8, quick 2)")
    p.add_argument("--seconds", type=float, help="minimum measuring time per number (default 3, quick 0)")
    p.add_argument(
        "--exp",
        default=None,
        help="experiment for rollout/train (default composite/chest_open+squat; smoke with --quick)",
    )
    p.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="KEY=VALUE",
        help="config overrides for rollout/train, e.g. --set disc.gp_mode=sum_heads",
    )
    p.add_argument(
        "--backends", default="mjx,mujoco", help="physics backends of the rollout and train rows (default: both)"
    )
    p.add_argument(
        "--iters", type=int, default=1, help="train iterations per compiled call (0: the experiment's chunk)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--rounds", type=int, help="alternating timing rounds per batch size (default 3, quick 1)")
    p.add_argument("--timeout", type=float, default=1800.0, help="abort a batch size that runs longer (s; 0: never)")
    p.add_argument("--out", default="bench.json", help="JSON output file")
    p.add_argument("--time-to-result", metavar="RUN", help="instead: samples and wall time RUN took to --targets")
    p.add_argument("--targets", default="upper=0.10,lower=0.09", help="group=DTW error (m), default paper Table 1")
    a = p.parse_args(argv)
    if a.time_to_result:
        return time_to_result.report(a.time_to_result, a.targets, a.out)
    parts = [s.strip() for s in a.parts.split(",") if s.strip()]
    if bad := [s for s in parts if s not in PARTS]:
        p.error(f"unknown part(s) {bad}; choose from {list(PARTS)}")
    if a.batches:
        try:
            batches = tuple(int(s) for s in a.batches.split(",") if s.strip())
        except ValueError:
            p.error(f"--batches {a.batches}: comma-separated whole numbers, e.g. 64,256")
    elif a.quick:
        batches = (1, 4)
    else:
        batches = DEFAULT_BATCHES + (GPU_EXTRA_BATCHES if jax.default_backend() == "gpu" else ())
    cfg = BenchConfig(
        batches=batches,
        steps=(2 if a.quick else 8) if a.steps is None else a.steps,
        seconds=a.seconds if a.seconds is not None else (0.0 if a.quick else 3.0),
        exp=a.exp or ("smoke" if a.quick else "composite/chest_open+squat"),
        iters=a.iters,
        seed=a.seed,
        rounds=(1 if a.quick else 3) if a.rounds is None else a.rounds,
        overrides=tuple(a.set),
        backends=tuple(b.strip() for b in a.backends.split(",") if b.strip()),
    )
    validate(cfg)  # every number in its range, known backends: one line before anything compiles
    # A benchmark without compilation measures nothing useful (and un-jitted MJX takes seconds
    # per step), so JAX_DISABLE_JIT=1, which the test suite sets, is overridden here.
    jax.config.update("jax_disable_jit", False)
    if {"rollout", "train"} & set(parts):
        check_clips(cfg)  # a missing clip is one clear line before anything compiles
    result = run(cfg, parts, a.timeout)
    print(report(result))
    with open(a.out, "w") as f:
        json.dump(result, f, indent=2)
    print(f"\nwrote {a.out}")
    return 1 if result["errors"] else 0


if __name__ == "__main__":
    sys.exit(main())
