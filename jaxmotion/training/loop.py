"""Sharding and the compiled chunk: ``chunk`` learner iterations in one ``lax.scan`` under one
``jax.jit``, the state donated, the environment batch split over a 1-D ``data`` mesh and
everything else replicated (XLA inserts the gradient all-reduce: synchronous data parallelism).
The learner's pure iteration is ``learner.Learner.iteration``. Across processes (``hosts``) the
mesh spans every process's devices and the arrays are global: each process holds its devices'
parts."""

from __future__ import annotations

from typing import TYPE_CHECKING

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

from jaxmotion.training import hosts

if TYPE_CHECKING:
    from jaxmotion.training.learner import Learner, TrainState


def make_mesh(devices=None) -> Mesh:
    """A 1-D mesh over ``devices`` (default: all, of every process) with axis name ``data``."""
    devices = jax.devices() if devices is None else devices
    return Mesh(np.asarray(devices), ("data",))


def state_shardings(ts: TrainState, mesh: Mesh):
    """Env states and observations split along the batch axis; everything else replicated."""
    batch = NamedSharding(mesh, P("data"))
    rep = NamedSharding(mesh, P())
    sh = jax.tree.map(lambda _: rep, ts)
    return sh.replace(env_state=jax.tree.map(lambda _: batch, ts.env_state), obs=batch)


def shard_state(ts: TrainState, mesh: Mesh) -> TrainState:
    """``ts`` (whole on this process, as ``Learner.init`` makes it) placed on the mesh; across
    processes every process makes the same ``ts`` and keeps its own devices' parts."""
    return hosts.to_global(ts, state_shardings(ts, mesh))


def make_train_chunk(learner: Learner, mesh: Mesh, chunk: int, example: TrainState):
    """``chunk`` iterations in one ``lax.scan`` under one ``jax.jit`` (state donated).

    Returns ``f(ts) -> (ts, metrics)`` with metrics stacked over the chunk, replicated (every
    process can read them).
    """
    sh = state_shardings(example, mesh)
    rep = NamedSharding(mesh, P())

    def run(ts):
        def body(ts, _):
            ts, m = learner.iteration(ts, mesh)
            ts = jax.lax.with_sharding_constraint(ts, sh)
            return ts, m

        return jax.lax.scan(body, ts, None, length=chunk)

    return jax.jit(run, in_shardings=(sh,), out_shardings=(sh, rep), donate_argnums=0)
