"""Tests of jaxmotion.bench: the physics benchmark end to end, and its small helpers."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from jaxmotion import bench
from jaxmotion.physics import sim


def _positive(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


@pytest.mark.physics
def test_physics_bench_writes_complete_json(tmp_path, request):
    """``--quick`` (physics, rollout and the full training iteration on the C backend) runs compiled
    (JAX_DISABLE_JIT=0) and writes every field.

    The subprocess shares a JAX compilation cache under pytest's cache folder: the first run
    compiles MJX twice (about a minute on a 2-core CPU), later runs load the executables.
    """
    out = tmp_path / "bench.json"
    env = dict(os.environ, JAX_DISABLE_JIT="0")
    env.setdefault("JAX_COMPILATION_CACHE_DIR", str(request.config.cache.mkdir("jax_compilation_cache")))
    cmd = [
        sys.executable,
        "-m",
        "jaxmotion.bench",
        "--quick",
        "--parts",
        "physics,rollout,train",
        "--batches",
        "2",
        "--steps",
        "2",
        "--backends",
        "mujoco",
        "--out",
        str(out),
    ]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    result = json.loads(out.read_text())
    for key in ("device", "jax_version", "mujoco_version"):
        assert isinstance(result[key], str) and result[key]
    assert result["errors"] == {}
    assert [row["batch"] for row in result["physics"]] == [2]
    for part in ("rollout", "train"):
        # MJX rows differ only by the backend override; the C rows keep the suite's time down.
        assert [(r["batch"], r["backend"]) for r in result[part]] == [(2, "mujoco")], result[part]
        for row in result[part]:
            for key in ("control_steps_per_s", "physics_cost_ratio", "fraction_of_bare_c", "compile_s", "peak_mem_mb"):
                assert _positive(row[key]), (part, key, row)
    for row in result["physics"]:
        for key in (
            "mjx_control_steps_per_s",
            "mujoco_c_control_steps_per_s",
            "callback_control_steps_per_s",
            "compile_s",
        ):
            assert _positive(row[key]), (key, row)
        assert row["mujoco_c_method"].startswith("mujoco.rollout"), row
        # The characters were still standing, so the work measured is the representative one.
        assert row["mjx_root_height"] > 0.8 and row["mujoco_c_root_height"] > 0.8, row
    assert "mujoco C" in proc.stdout


def test_standing_qpos_differs_per_env():
    q = bench.standing_qpos(sim.mj_model(sim.PhysicsConfig()), 3, 0.02, seed=0)
    assert q.shape == (3, 35)
    np.testing.assert_array_equal(q[:, :7], [[0, 0, bench.ROOT_HEIGHT, 1, 0, 0, 0]] * 3)
    assert np.all(np.abs(q[0, 7:] - q[1, 7:]) > 0) and np.abs(q[:, 7:]).max() < 0.2


def test_format_table_aligns_and_marks_missing():
    rows = [{"batch": 1, "x": 12.345}, {"batch": 1024}]
    lines = bench.format_table(rows, [("batch", "batch", "d"), ("x", "x", ".1f")]).splitlines()
    assert lines == ["batch     x", "    1  12.3", " 1024     -"]


def test_cli_rejects_unknown_part():
    with pytest.raises(SystemExit):
        bench.main(["--parts", "physics,nope"])


def test_physics_ratios_pair_rows_by_batch():
    result = {
        "physics": [
            {"batch": 64, "mjx_control_steps_per_s": 1000.0},
            {
                "batch": 256,
                "mjx_control_steps_per_s": 2000.0,
                "callback_control_steps_per_s": 8000.0,
                "mujoco_c_control_steps_per_s": 10000.0,
            },
        ],
        "rollout": [
            {"batch": 256, "control_steps_per_s": 1600.0, "backend": "mjx"},
            {"batch": 256, "control_steps_per_s": 4000.0, "backend": "mujoco"},
        ],
        "train": [{"batch": 64, "control_steps_per_s": 400.0}, {"batch": 1024, "control_steps_per_s": 9.0}],
    }
    bench.add_physics_ratios(result)
    assert result["rollout"][0]["physics_cost_ratio"] == pytest.approx(1.25)
    assert result["rollout"][1]["physics_cost_ratio"] == pytest.approx(2.0)  # against its own backend
    assert result["rollout"][1]["fraction_of_bare_c"] == pytest.approx(0.4)
    assert result["train"][0]["physics_cost_ratio"] == pytest.approx(2.5)
    assert "physics_cost_ratio" not in result["train"][1]  # no physics row at that batch


def test_overrides_reach_the_benchmarked_config(data_dir):
    cfg = bench.BenchConfig(exp="smoke", overrides=("disc.gp_mode=sum_heads", "ppo.epochs=2"))
    learner, tc = bench._learner(cfg, 4)
    assert tc.disc.gp_mode == "sum_heads" and tc.ppo.epochs == 2 and tc.ppo.num_envs == 4
    assert learner.cfg is tc and tc.chunk == 1
    with pytest.raises(Exception, match="ppo.epoch"):
        bench._learner(bench.BenchConfig(exp="smoke", overrides=("ppo.epoch=2",)), 4)
