"""Sharding and the compiled chunk: ``chunk`` learner iterations in one ``lax.scan`` under one
``jax.jit``, the state donated, the environment batch split over a 1-D ``data`` mesh and
everything else replicated. Over several devices each runs the iteration on its own share under
``shard_map``, gradients and batch statistics averaged over the mesh (synchronous data
parallelism, as DD-PPO). The learner's pure iteration is ``learner.Learner.iteration``."""

from __future__ import annotations

from typing import TYPE_CHECKING

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

if TYPE_CHECKING:
    from jaxmotion.training.learner import Learner, TrainState


def make_mesh(devices=None) -> Mesh:
    """A 1-D mesh over ``devices`` (default: all) with axis name ``data``."""
    devices = jax.devices() if devices is None else devices
    return Mesh(np.asarray(devices), ("data",))


def state_shardings(ts: TrainState, mesh: Mesh):
    """Env states, observations and a recurrent policy's carry split along the batch axis;
    everything else replicated."""
    batch = NamedSharding(mesh, P("data"))
    rep = NamedSharding(mesh, P())
    sh = jax.tree.map(lambda _: rep, ts)
    return sh.replace(
        env_state=jax.tree.map(lambda _: batch, ts.env_state),
        obs=batch,
        policy_carry=None if ts.policy_carry is None else batch,
    )


def shard_state(ts: TrainState, mesh: Mesh) -> TrainState:
    return jax.device_put(ts, state_shardings(ts, mesh))


def per_device(learner: Learner, mesh: Mesh) -> bool:
    """Whether the iteration runs per device (``shard_map``, explicit reductions) over ``mesh``:
    with several devices, unless an opponent pool indexes the whole batch (its bouts are the
    batch's first environments); that case stays one program that XLA partitions."""
    return mesh.size > 1 and learner.pool is None


def make_train_chunk(learner: Learner, mesh: Mesh, chunk: int, example: TrainState):
    """``chunk`` iterations in one ``lax.scan`` under one ``jax.jit`` (state donated).

    Over several devices each runs the iteration on its own environments (``per_device``): one
    program per device that meets the others only in the reductions, so on a CPU whose devices
    are its cores both cores work on the networks as well as the physics. (Left to XLA's
    partitioner, the minibatch gathers across the batch made two CPU devices 2.4x slower than one.)

    Returns ``f(ts) -> (ts, metrics)`` with metrics stacked over the chunk.
    """
    sh = state_shardings(example, mesh)

    if per_device(learner, mesh):
        specs = jax.tree.map(lambda s: s.spec, sh)

        def local(ts):
            return jax.lax.scan(lambda ts, _: learner.iteration(ts, axis="data"), ts, None, length=chunk)

        run = jax.shard_map(local, mesh=mesh, in_specs=(specs,), out_specs=(specs, P()), check_vma=False)
        return jax.jit(run, in_shardings=(sh,), out_shardings=(sh, None), donate_argnums=0)

    def run(ts):
        def body(ts, _):
            ts, m = learner.iteration(ts, mesh)
            ts = jax.lax.with_sharding_constraint(ts, sh)
            return ts, m

        return jax.lax.scan(body, ts, None, length=chunk)

    return jax.jit(run, in_shardings=(sh,), out_shardings=(sh, None), donate_argnums=0)
