"""Training across processes (several machines, or several processes on one): JAX's distributed
runtime, started before anything touches a device, and the few conversions the driver needs
between process-local and global arrays.

``python -m jaxmotion.train EXP --processes N --process-id i --coordinator host:port`` (or
``JAXMOTION_DISTRIBUTED=1``, which leaves the settings to ``jax.distributed.initialize()``: on a
SLURM cluster it reads them from ``srun``'s environment) runs one synchronous training over every
process's devices: the mesh of ``loop.make_mesh`` spans them all, each process steps its shard of
the environment batch, and the gradient all-reduce crosses processes (gloo on CPU, JAX's default).
Process 0 alone writes the run folder; every process reads it (a shared filesystem).
"""

from __future__ import annotations

import dataclasses
import os
import re

import jax
import numpy as np
from jax.experimental import multihost_utils

from jaxmotion.config.errors import JaxmotionError

ENV_FLAG = "JAXMOTION_DISTRIBUTED"
"""``=1``: call ``jax.distributed.initialize()`` with no arguments (SLURM, Open MPI, or
``JAX_COORDINATOR_ADDRESS`` plus a cluster JAX detects)."""
FLAGS = {"--processes": "processes", "--process-id": "process_id", "--coordinator": "coordinator"}


class DistributedError(JaxmotionError):
    """Bad multi-process settings, or a distributed runtime that cannot start."""


@dataclasses.dataclass(frozen=True)
class Cluster:
    """The processes of one training, as the command line gives them."""

    processes: int
    """How many processes train together (one per machine, usually)."""
    process_id: int
    """This process's index, 0 to ``processes - 1``; process 0 writes the run folder."""
    coordinator: str
    """``host:port`` of process 0, which every process can reach."""


def _int_flag(flag: str, value: str) -> int:
    try:
        return int(value)
    except ValueError:
        raise DistributedError(f"{flag} {value!r}: not an integer") from None


def check_coordinator(value: str) -> str:
    """``value`` if it is ``host:port`` (port 1-65535; ``[ipv6]:port`` too), else a ``DistributedError``."""
    m = re.fullmatch(r"(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d+)", value)
    if m is None or not 0 < int(m.group(2)) < 65536:
        raise DistributedError(f"--coordinator {value!r}: expected host:port (e.g. node0:12355), port 1-65535")
    return value


def split_flags(argv: list[str]) -> tuple[Cluster | None, list[str]]:
    """(the ``Cluster`` the flags ``--processes N --process-id i --coordinator host:port`` give,
    or None without them; the other arguments). ``--flag=value`` works too. All three or none."""
    values: dict[str, str] = {}
    rest: list[str] = []
    i = 0
    while i < len(argv):
        arg = argv[i]
        flag, eq, value = arg.partition("=")
        if flag not in FLAGS:
            rest.append(arg)
            i += 1
            continue
        if not eq:
            if i + 1 >= len(argv):
                raise DistributedError(f"{flag} needs a value")
            value, i = argv[i + 1], i + 1
        values[flag] = value
        i += 1
    if not values:
        return None, rest
    missing = [f for f in FLAGS if f not in values]
    if missing:
        raise DistributedError(f"{', '.join(values)} also needs {', '.join(missing)} (all three flags, or none)")
    n = _int_flag("--processes", values["--processes"])
    i = _int_flag("--process-id", values["--process-id"])
    if n < 1:
        raise DistributedError(f"--processes {n}: at least 1")
    if not 0 <= i < n:
        raise DistributedError(f"--process-id {i} is out of range for --processes {n} (0 to {n - 1})")
    return Cluster(n, i, check_coordinator(values["--coordinator"])), rest


def initialize(cluster: Cluster | None, environ=os.environ) -> bool:
    """Starts JAX's distributed runtime for ``cluster`` (or, with ``JAXMOTION_DISTRIBUTED=1``,
    as ``jax.distributed.initialize()`` finds it); returns whether it did. Must come before
    anything touches a device. Waits up to 5 minutes for the other processes."""
    if cluster is None and environ.get(ENV_FLAG) != "1":
        return False
    try:
        if cluster is None:
            jax.distributed.initialize()
        else:
            jax.distributed.initialize(cluster.coordinator, cluster.processes, cluster.process_id)
    except (RuntimeError, ValueError, TypeError) as e:
        where = f"at {cluster.coordinator}" if cluster else f"({ENV_FLAG}=1)"
        line = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise DistributedError(f"the distributed runtime {where} did not start: {line[:300]}") from None
    return True


def primary() -> bool:
    """Whether this process writes the run folder, logs and prints (process 0)."""
    return jax.process_index() == 0


def to_global(tree, shardings):
    """``tree`` (host-local arrays every process holds in full, with the same values: made from
    the same key by the same program) as global arrays of ``shardings``; each process keeps only
    its devices' parts. One process: ``jax.device_put``."""
    if jax.process_count() == 1:
        return jax.device_put(tree, shardings)

    def one(x, sh):
        host = np.asarray(x)
        return jax.make_array_from_callback(host.shape, sh, lambda idx: host[idx])

    return jax.tree.map(one, tree, shardings)


def to_local(tree):
    """Every leaf of ``tree`` as a whole array on this process (replicated leaves: this
    process's copy; split ones gathered from all processes, so every process must call this at
    the same point). For work between chunks that runs outside the mesh (evaluation, mining)."""
    if jax.process_count() == 1:
        return tree

    def one(x):
        if not isinstance(x, jax.Array) or x.is_fully_addressable:
            return x
        if x.is_fully_replicated:
            return x.addressable_data(0)
        return jax.device_put(multihost_utils.process_allgather(x, tiled=True), jax.local_devices()[0])

    return jax.tree.map(one, tree)


def from_primary(tree, shardings):
    """``tree`` (host-local, as ``to_local`` gives) as global arrays holding process 0's values,
    so that processes whose work between chunks came out differently agree again."""
    if jax.process_count() == 1:
        return jax.device_put(tree, shardings)
    return to_global(multihost_utils.broadcast_one_to_all(tree), shardings)


def broadcast_text(text: str) -> str:
    """Process 0's ``text`` (e.g. the run folder it named) on every process."""
    if jax.process_count() == 1:
        return text
    data = np.frombuffer(text.encode(), np.uint8)
    size = int(multihost_utils.broadcast_one_to_all(np.int32(data.size)))
    buf = np.zeros(size, np.uint8)
    buf[: min(size, data.size)] = data[:size]
    return bytes(multihost_utils.broadcast_one_to_all(buf)).decode()


def total(count: int) -> int:
    """``count`` summed over processes (every process must call this at the same point)."""
    if jax.process_count() == 1:
        return count
    return int(np.sum(multihost_utils.process_allgather(np.int64(count))))


def barrier(name: str) -> None:
    """Waits until every process has come here (no-op in one process)."""
    if jax.process_count() > 1:
        multihost_utils.sync_global_devices(name)
