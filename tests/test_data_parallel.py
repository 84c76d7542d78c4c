"""The per-device iteration's reductions (``axis_name``) against one device on the whole batch.

Over several devices each device runs the iteration on its own share of the batch
(``training/loop.py``); its batch statistics must still be those of the whole batch. Here two host
devices each hold half of a batch, and the observation normaliser, PopArt and the advantage
standardisation computed per device with the reduction must equal (to float rounding) the plain
functions on the whole batch; without the reduction each device would have its own half's
statistics, apart at O(1). Two devices need their own process (the host's device count is fixed
when JAX starts); nothing here steps physics, so it takes seconds.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

from conftest import REPO

SCRIPT = textwrap.dedent("""
    import jax, jax.numpy as jnp, numpy as np
    from jax.sharding import Mesh, PartitionSpec as P
    from jaxmotion.algos import normalizer as N, popart as PA, ppo as PPO

    assert len(jax.devices()) == 2
    mesh = Mesh(np.asarray(jax.devices()), ("d",))
    rng = np.random.default_rng(0)
    # Halves with different moments, so a per-device statistic is far from the whole batch's.
    x = np.concatenate([rng.normal(0, 1, (64, 5)), rng.normal(3, 2, (64, 5))]).astype(np.float32)
    mask = rng.random(128) > 0.3
    adv = np.concatenate([rng.normal(0, 1, (64, 3)), rng.normal(2, 5, (64, 3))]).astype(np.float32)
    w = jnp.asarray([0.2, 0.3, 0.5])
    norm0 = N.normalizer_update(N.normalizer_init(5), rng.normal(1, 1, (32, 5)).astype(np.float32))
    pa0 = PA.popart_init(3)

    def local(x, mask, adv):
        n = N.normalizer_update(norm0, x, mask, axis_name="d")
        p = PA.popart_update(pa0, adv, 0.1, axis_name="d")
        comb, std = PPO.combine_advantages(adv, w, axis_name="d")
        return n, p, comb, std

    f = jax.jit(jax.shard_map(local, mesh=mesh, in_specs=(P("d"), P("d"), P("d")),
                              out_specs=(P(), P(), P("d"), P("d")), check_vma=False))
    n2, p2, comb2, std2 = f(x, mask, adv)
    n1 = N.normalizer_update(norm0, x, mask)
    p1 = PA.popart_update(pa0, adv, 0.1)
    comb1, std1 = PPO.combine_advantages(adv, w)
    close = lambda a, b: np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-5)
    for a, b in zip(jax.tree.leaves((n2, p2, comb2, std2)), jax.tree.leaves((n1, p1, comb1, std1))):
        close(a, b)
    # Each device's copy of the replicated statistics is the same.
    for leaf in jax.tree.leaves((n2, p2)):
        shards = [np.asarray(s.data) for s in leaf.addressable_shards]
        assert all(np.array_equal(shards[0], s) for s in shards)
    # The halves' own statistics are far apart: the check above can tell.
    half = N.normalizer_update(norm0, x[:64], mask[:64])
    assert np.abs(np.asarray(half.mean) - np.asarray(n1.mean)).max() > 0.5
    print("ok")
""")


def test_reductions_over_two_devices_equal_one_device(tmp_path):
    script = tmp_path / "reductions.py"
    script.write_text(SCRIPT)
    env = dict(
        os.environ, JAX_DISABLE_JIT="0", XLA_FLAGS="--xla_force_host_platform_device_count=2", JAX_PLATFORMS="cpu"
    )
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=300, cwd=REPO)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok"), proc.stdout + proc.stderr
