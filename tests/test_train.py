"""The training driver: exact resume, two devices in step, config errors, objective weights.

The two heavy tests share one tiny configuration and, in this process, one compiled training
chunk: ``jaxmotion.train.make_train_chunk`` is memoised for the module, so the uninterrupted run,
the interrupted run and its resumption all execute the same program (compiling a chunk takes
about a minute on a 2-core CPU). Sharing is only for speed: with three separate compilations, as
in real separate processes, the resumed run was bit-identical too (checked once, 200 s). The
two-device run needs its own process, because the number of host devices is fixed when JAX
starts; it compiles the second program and reuses the one-device run's first iteration.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import jax
import numpy as np
import pytest

from conftest import REPO, jit_enabled
from jaxmotion.training import checkpoint as ckpt
from jaxmotion import config as C
from jaxmotion import train as train_mod
from jaxmotion.training import run as run_mod
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.training.learner import DiscConfig, Learner, PPOConfig, TrainConfig

EXPERIMENT = "smoke"
TIMING_FIELDS = ("steps_per_s", "wall_s")


def tiny_config() -> TrainConfig:
    """The smoke experiment shrunk until compilation dominates: 4 envs x horizon 4, chunk 1.

    Episodes last 6 control steps, so the 12 steps of a 3-iteration run cross automatic resets
    (and the resumed part of a run starts mid-episode).
    """
    base = C.load_experiment(EXPERIMENT)
    return dataclasses.replace(
        base,
        env=dataclasses.replace(base.env, episode_steps=6),
        net=dataclasses.replace(
            base.net, policy_hidden=(16, 16), critic_hidden=(16, 16), disc_hidden=(16, 16), disc_heads=2
        ),
        ppo=dataclasses.replace(base.ppo, num_envs=4, horizon=4, minibatch_size=8, epochs=1),
        disc=dataclasses.replace(base.disc, minibatch_size=8),
        seed=0,
        iterations=3,
        chunk=1,
        checkpoint_every=1,
        resume="",
    )


def _leaves(tree) -> list[tuple[str, np.ndarray]]:
    return [(jax.tree_util.keystr(p), np.asarray(x)) for p, x in jax.tree_util.tree_flatten_with_path(tree)[0]]


def _rows(run_dir: Path) -> list[dict]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines() if line.strip()]


def _untimed(row: dict) -> dict:
    return {k: v for k, v in row.items() if k not in TIMING_FIELDS}


@pytest.fixture(scope="module")
def motion_data(data_dir):
    """Points ``$JAXMOTION_DATA`` at the shared motions for this module."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("JAXMOTION_DATA", str(data_dir))
        yield data_dir


@pytest.fixture(scope="module")
def shared_chunk():
    """Memoises ``make_train_chunk`` by (config minus run bookkeeping, chunk, devices).

    Yields the list of programs actually built, so a test can check how many were compiled.
    """
    built: dict = {}
    real = run_mod.make_train_chunk

    def memo(learner, mesh, chunk, example):
        key = (
            dataclasses.replace(learner.cfg, resume="", init_from="", iterations=0, checkpoint_every=0),
            chunk,
            tuple(d.id for d in mesh.devices.flat),
        )
        if key not in built:
            built[key] = real(learner, mesh, chunk, example)
        return built[key]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(run_mod, "make_train_chunk", memo)
        yield built


@pytest.fixture(scope="module")
def runs(motion_data, shared_chunk, tmp_path_factory):
    """Run A: 3 chunks uninterrupted. Run B: stopped after chunk 1 (its checkpoint written), then
    resumed to the end. Also keeps B's state after chunk 1 (one iteration on one device)."""
    cfg = tiny_config()
    root = tmp_path_factory.mktemp("runs")
    times = {}
    with jit_enabled():
        t = time.perf_counter()
        a = train_mod.train(EXPERIMENT, cfg, run_dir=root / "A", progress=False, tensorboard=True)
        times["A (compile + 3 chunks)"] = time.perf_counter() - t
        t = time.perf_counter()
        b1 = train_mod.train(
            EXPERIMENT, cfg, run_dir=root / "B", progress=False, tensorboard=False, stop_after_chunks=1
        )
        b1_leaves = _leaves(b1.state)  # host copies: the state must outlive later runs.
        b1_rows = _rows(root / "B")
        # A row logged after the last checkpoint by the "killed" process: resume must drop it.
        with open(root / "B" / "metrics.jsonl", "a") as f:
            f.write(json.dumps({**b1_rows[-1], "iteration": 2, "samples": -1.0}) + "\n")
        b = train_mod.train(
            EXPERIMENT, dataclasses.replace(cfg, resume=str(root / "B")), progress=False, tensorboard=False
        )
        times["B (1 chunk, then resume for 2)"] = time.perf_counter() - t
    print("\nrun times:", {k: f"{v:.1f}s" for k, v in times.items()})
    return dict(cfg=cfg, a=a, b1=b1, b1_leaves=b1_leaves, b1_rows=b1_rows, b=b, programs=len(shared_chunk))


@pytest.mark.slow
def test_resume_reproduces_uninterrupted_run(runs):
    cfg, a, b1, b = runs["cfg"], runs["a"], runs["b1"], runs["b"]
    assert runs["programs"] == 1, "all three runs should share one compiled chunk"
    assert int(b1.state.iteration) == 1 and [r["iteration"] for r in runs["b1_rows"]] == [1]
    assert b.run_dir == b1.run_dir
    assert int(a.state.iteration) == int(b.state.iteration) == cfg.iterations

    # Every leaf of the final state, bit for bit: networks, optimisers, normalisers, PopArt,
    # environment states (physics, history, step counters, per-env keys) and the loop's key.
    la, lb = _leaves(a.state), _leaves(b.state)
    assert [k for k, _ in la] == [k for k, _ in lb]
    for (k, x), (_, y) in zip(la, lb):
        assert x.dtype == y.dtype and x.shape == y.shape, k
        np.testing.assert_array_equal(x, y, err_msg=k)
    # The resumed iterations did change the parameters after the checkpoint.
    moved = dict(runs["b1_leaves"])
    assert any(not np.array_equal(moved[k], x) for k, x in la if "policy_params" in k)

    # The logs: the same iterations with the same values, except wall-clock timings.
    rows_a, rows_b = _rows(a.run_dir), _rows(b.run_dir)
    assert [r["iteration"] for r in rows_a] == [r["iteration"] for r in rows_b] == [1, 2, 3]
    assert [_untimed(r) for r in rows_a] == [_untimed(r) for r in rows_b]
    assert [_untimed(r) for r in a.metrics] == [_untimed(r) for r in rows_a]
    assert [r["iteration"] for r in b.metrics] == [2, 3]
    assert rows_a[-1]["samples"] == cfg.iterations * cfg.samples_per_iteration
    for r in rows_a:
        assert all(np.isfinite(v) for v in r.values()), r
    # Episodes of 6 steps: the 12 steps crossed automatic resets.
    assert sum(r["env/episodes_done"] for r in rows_a) > 0

    # The run folder.
    for name in ("metrics.jsonl", "config.json", "checkpoints", "tb"):
        assert (a.run_dir / name).exists(), name
    assert any((a.run_dir / "tb").iterdir())
    steps = sorted(int(p.name) for p in (a.run_dir / "checkpoints").iterdir() if p.name.isdigit())
    assert steps == [1, 2, 3]
    assert 3 in [int(p.name) for p in (b.run_dir / "checkpoints").iterdir() if p.name.isdigit()]
    experiment, saved = ckpt.read_config(a.run_dir, TrainConfig)
    assert experiment == EXPERIMENT and saved == cfg
    # The resumed run kept its folder's config (resume is not written into it).
    assert ckpt.read_config(b.run_dir, TrainConfig) == (EXPERIMENT, cfg)


@pytest.mark.slow
def test_slim_copy_restores_everything_but_the_environments(runs, tmp_path):
    """``checkpoint slim``: the copy's checkpoint holds no per-environment leaves; restored into a
    fresh template it equals the run's final state everywhere else (networks, optimisers,
    normalisers, PopArt, RNG, counters) and keeps the template's freshly reset environments."""
    cfg, a = runs["cfg"], runs["a"]
    with jit_enabled():
        like = Learner(cfg).init(jax.random.PRNGKey(cfg.seed + 1))
        step = ckpt.slim(a.run_dir, tmp_path / "slim", like)
        assert step == cfg.iterations
        mgr = ckpt.manager(tmp_path / "slim")
        restored, got = ckpt.restore(mgr, like)
        mgr.close()
    assert got == step
    assert (tmp_path / "slim" / "config.json").read_text() == (a.run_dir / "config.json").read_text()
    assert (tmp_path / "slim" / "metrics.jsonl").exists()
    final, template = dict(_leaves(a.state)), dict(_leaves(like))
    for k, x in _leaves(restored):
        want = template[k] if ckpt.field_of(k) in ckpt.PER_ENV else final[k]
        np.testing.assert_array_equal(x, want, err_msg=k)
    assert any(k.startswith(".env_state") for k in final)
    # The observation statistics travel (".obs" names the observations, not ".obs_norm"): a
    # trained policy acts on normalised observations and is garbage without them.
    norm = [k for k in final if ckpt.field_of(k) == "obs_norm"]
    assert norm and any(not np.array_equal(final[k], template[k]) for k in norm)
    assert any(not np.array_equal(final[k], template[k]) for k in final if k.startswith(".env_state"))
    size = lambda d: sum(f.stat().st_size for f in d.rglob("*") if f.is_file())
    assert size(tmp_path / "slim" / "checkpoints") < size(a.run_dir / "checkpoints" / str(step))


TWO_DEVICE_SCRIPT = textwrap.dedent("""
    import json, sys
    from pathlib import Path
    import jax, numpy as np
    from jaxmotion.training import checkpoint as ckpt
    from jaxmotion.train import train
    from jaxmotion.training.learner import TrainConfig

    src, out = Path(sys.argv[1]), Path(sys.argv[2])
    assert len(jax.devices()) == 2, jax.devices()
    experiment, cfg = ckpt.read_config(src, TrainConfig)
    # train() puts the env batch on make_mesh() over all devices: 2 envs per device here.
    res = train(experiment, cfg, run_dir=out / "run", progress=False, tensorboard=False,
                stop_after_chunks=1)
    ts = res.state
    paths = jax.tree_util.tree_flatten_with_path(ts)[0]
    np.savez(out / "state.npz", *[np.asarray(x) for _, x in paths])
    sharded = [len(x.sharding.device_set) for x in jax.tree.leaves((ts.env_state, ts.obs)) if x.size]
    replicated = [len(x.sharding.device_set) for x in jax.tree.leaves(ts.policy_params)]
    specs = sorted({str(x.sharding.spec) for x in jax.tree.leaves((ts.env_state, ts.obs)) if x.size})
    # Each device holds its own copy of a replicated leaf: the copies must be the same.
    rest = ts.replace(env_state=None, obs=None)
    apart = [jax.tree_util.keystr(p) for p, x in jax.tree_util.tree_flatten_with_path(rest)[0]
             if not all(np.array_equal(np.asarray(s.data), np.asarray(x.addressable_shards[0].data))
                        for s in x.addressable_shards)]
    json.dump({"keys": [jax.tree_util.keystr(p) for p, _ in paths], "env_device_counts": sharded,
               "param_device_counts": replicated, "env_specs": specs, "metrics": res.metrics,
               "copies_apart": apart},
              open(out / "info.json", "w"))
""")


@pytest.mark.slow
def test_two_devices_train_in_step(runs, tmp_path, request):
    """The same global batch (4 envs) split 2+2 over two host devices: each device runs the
        iteration on its own environments (``loop.per_device``) and the two stay one synchronous
        update, compared with run B's state after its first iteration (same config, seed, chunk).

        Each device draws its own action noise, resets, reference windows and minibatches, so the
        numbers are not one device's; what must hold: the batch really is split, every replicated
        leaf (parameters, optimiser moments, the normalisers, PopArt) is the same on both devices
        (an unsynchronised gradient or statistic would tell them apart), the normalisers counted
        every sample of both devices, each parameter is within Adam's bound of the one-device update
        (Adam moves an element by at most ~lr per step whatever the data; the critic's value head is
    also rescaled by PopArt with the data's returns), and the logged metrics have
        the same keys and are finite. The reductions themselves are checked exactly against one device
        in ``test_data_parallel.py``.
    """
    script = tmp_path / "two_devices.py"
    script.write_text(TWO_DEVICE_SCRIPT)
    env = dict(
        os.environ, JAX_DISABLE_JIT="0", XLA_FLAGS="--xla_force_host_platform_device_count=2", JAX_PLATFORMS="cpu"
    )
    env.setdefault("JAX_COMPILATION_CACHE_DIR", str(request.config.cache.mkdir("jax_compilation_cache")))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    t = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, str(script), str(runs["b1"].run_dir), str(tmp_path)],
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
        cwd=REPO,
    )
    print(f"\ntwo-device subprocess: {time.perf_counter() - t:.1f}s")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    info = json.loads((tmp_path / "info.json").read_text())

    # The environment batch really was split over both devices; parameters were replicated.
    assert info["env_device_counts"] and set(info["env_device_counts"]) == {2}
    assert all("data" in s for s in info["env_specs"]), info["env_specs"]
    assert set(info["param_device_counts"]) == {2}
    assert info["copies_apart"] == []

    cfg = runs["cfg"]
    n = cfg.samples_per_iteration
    ppo_steps = cfg.ppo.epochs * n // cfg.ppo.minibatch_size
    disc_steps = n // cfg.disc.minibatch_size
    adam_bound = {
        ".policy_params": 2 * cfg.ppo.actor_lr * ppo_steps,
        ".critic_params": 2 * cfg.ppo.critic_lr * ppo_steps,
        ".disc_params": 2 * cfg.disc.lr * disc_steps,
    }
    one = runs["b1_leaves"]
    two = np.load(tmp_path / "state.npz")
    assert info["keys"] == [k for k, _ in one]
    for i, (k, x) in enumerate(one):
        y = two[f"arr_{i}"]
        assert x.shape == y.shape and x.dtype == y.dtype, k
        if k.startswith(tuple(adam_bound)) and "value_head" not in k:  # PopArt rescales the head by the data
            bound = adam_bound[k.split("[")[0]] + 1e-4 * max(1.0, float(np.abs(x).max()))
            assert float(np.abs(x.astype(np.float64) - y).max()) <= bound, k
        elif k.endswith(".count") and k.startswith((".obs_norm", ".disc_norm")):
            assert y == x, k  # every sample of both devices, once
        elif k == ".iteration":
            assert y == x

    row1, row2 = _untimed(runs["b1_rows"][0]), _untimed(info["metrics"][0])
    assert row1.keys() == row2.keys()
    assert all(np.isfinite(v) for v in row2.values())


def test_cli_rejects_config_typo():
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    proc = subprocess.run(
        [sys.executable, "-m", "jaxmotion.train", EXPERIMENT, "ppo.num_env=4"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        cwd=REPO,
    )
    assert proc.returncode != 0
    assert "ppo.num_env" in proc.stderr and "num_envs" in proc.stderr, proc.stderr
    assert "minibatch_size" in proc.stderr  # the other valid keys are listed too
    assert "run folder" not in proc.stdout


def test_cli_rejects_unknown_experiment(capsys):
    assert train_mod.main(["no_such_experiment"]) != 0
    err = capsys.readouterr().err
    assert "no_such_experiment" in err and "Available" in err, err
    assert all(name in err for name in C.list_experiments()), err


def test_override_value_of_wrong_type_is_rejected():
    cfg = C.load_experiment(EXPERIMENT)
    with pytest.raises(C.ConfigError, match="ppo.clip_eps"):
        C.apply_overrides(cfg, ["ppo.clip_eps=abc"])
    with pytest.raises(C.ConfigError, match="num_envs"):
        C.apply_overrides(cfg, ["ppo.num_env=4"])
    assert C.apply_overrides(cfg, ["ppo.clip_eps=0.1"]).ppo.clip_eps == 0.1


@pytest.fixture(scope="module")
def synthetic_env():
    """A two-group environment on synthetic clips (no motion files needed)."""
    clip = make_test_clip(30, 30.0, root_vel=(0.0, 0.0, 0.0), root_height=0.87, name="stand")
    lib = MotionLib.from_clips([clip])
    env_cfg = EnvConfig(groups=(GroupConfig(name="upper"), GroupConfig(name="lower")), episode_steps=20)
    return HumanoidEnv(env_cfg, motion_libs=(lib, lib), init_lib=lib)


@pytest.mark.parametrize("weights", [(0.2, 0.3, 0.5), (1.0,), (1.0, -0.5), (0.0, 0.0)])
def test_bad_objective_weights_rejected(synthetic_env, weights):
    cfg = TrainConfig(
        env=synthetic_env.cfg,
        ppo=PPOConfig(num_envs=4, horizon=4, minibatch_size=8, objective_weights=weights),
        disc=DiscConfig(minibatch_size=8),
    )
    with pytest.raises(ValueError, match=r"objective_weights must be 2 non-negative"):
        Learner(cfg, env=synthetic_env)


def test_good_objective_weights_are_normalised(synthetic_env):
    cfg = TrainConfig(
        env=synthetic_env.cfg,
        ppo=PPOConfig(num_envs=4, horizon=4, minibatch_size=8, objective_weights=(1.0, 3.0)),
        disc=DiscConfig(minibatch_size=8),
    )
    learner = Learner(cfg, env=synthetic_env)
    np.testing.assert_allclose(np.asarray(learner.objective_weights), [0.25, 0.75])


@pytest.mark.slow
def test_eval_cli_reports_and_writes_everything_from_one_rollout(runs, tmp_path, monkeypatch, capsys):
    """``python -m jaxmotion.eval <run> --json --html [--video]`` on run A: metrics, the replay
    page, the learning-curve PNGs, and the video where headless GL works; one rollout for all."""
    from jaxmotion import eval as E
    from jaxmotion.evaluation import imitation as EI
    from jaxmotion.viz import render as RD

    calls = []
    real = EI.rollout
    monkeypatch.setattr(EI, "rollout", lambda *a, **k: calls.append(a[2:4]) or real(*a, **k))
    run_dir = runs["a"].run_dir
    args = [str(run_dir), "--episodes", "2", "--json", str(tmp_path / "m.json"), "--html", str(tmp_path / "r.html")]
    video = RD.gl_backend() is not None
    if video:
        args += ["--video", str(tmp_path / "v.gif")]
    with jit_enabled():
        assert E.main(args) == 0
    assert calls == [(2, runs["cfg"].env.episode_steps)]
    res = json.loads((tmp_path / "m.json").read_text())
    assert res["episodes"] == 2 and res["samples"] == 3 * runs["cfg"].samples_per_iteration
    for g in runs["cfg"].env.groups:
        m = res["groups"][g.name]
        assert 0.0 < m["dtw_error_m_mean"] < 2.0 and np.isfinite(m["dtw_error_world_m_mean"])
    assert 0.0 < res["episode_length_s"] <= runs["cfg"].env.episode_steps * runs["cfg"].env.physics.control_dt + 1e-6
    assert "jaxmotion replay" in (tmp_path / "r.html").read_text()  # self-containment: test_render
    assert list(run_dir.glob("plot_*.png"))
    if video:
        assert (tmp_path / "v.gif").stat().st_size > 0
    out = capsys.readouterr().out
    assert "DTW error" in out and "html:" in out
    # The same seeds without training: the baseline a trained run must beat.
    with jit_enabled():
        assert (
            E.main([str(run_dir), "--episodes", "2", "--untrained", "--no-plots", "--json", str(tmp_path / "u.json")])
            == 0
        )
    base = json.loads((tmp_path / "u.json").read_text())
    assert base["experiment"].endswith("(untrained)") and base["samples"] == 0


@pytest.mark.parametrize("cli", ["train", "eval", "bench"])
def test_cli_without_clips_prints_one_clear_line(cli, tmp_path, monkeypatch, capsys):
    """No clips at $JAXMOTION_DATA: one error line naming the file, how to point JAXMOTION_DATA at
    the clips, a non-zero exit, and no traceback (nor a run folder left behind)."""
    from jaxmotion import bench, eval as E, train as T
    from jaxmotion.training import checkpoint as ckpt
    from jaxmotion import config as C

    monkeypatch.setenv("JAXMOTION_DATA", str(tmp_path / "nowhere"))
    monkeypatch.chdir(tmp_path)
    if cli == "train":
        rc = T.main(["composite/chest_open+squat_cpu"])
    elif cli == "bench":
        rc = bench.main(["--parts", "train", "--exp", "composite/chest_open+squat_cpu"])
    else:
        run = tmp_path / "run"
        ckpt.write_config(run, "composite/chest_open+squat_cpu", C.load_experiment("composite/chest_open+squat_cpu"))
        rc = E.main([str(run)])
    err = capsys.readouterr().err
    assert rc == 2
    assert "nowhere/compositemotion/gym/" in err and "no such file" in err and "JAXMOTION_DATA" in err
    assert "Traceback" not in err
    assert not (tmp_path / "runs").exists()


@pytest.mark.slow
def test_init_from_continues_a_run_in_a_new_folder(runs, tmp_path):
    """``init_from=<run>``: a new run starts from run A's parameters, optimiser, statistics and
    iteration count (freshly reset environments), so its first chunk continues A's training;
    a run whose networks do not fit is one clear error and leaves no folder behind."""
    from jaxmotion.training.runs import InitFromError

    cfg, a = runs["cfg"], runs["a"]
    more = dataclasses.replace(cfg, init_from=str(a.run_dir), iterations=cfg.iterations + cfg.chunk)
    with jit_enabled():
        c = train_mod.train(EXPERIMENT, more, run_dir=tmp_path / "C", progress=False, tensorboard=False)
    assert int(c.state.iteration) == cfg.iterations + cfg.chunk
    assert [r["iteration"] for r in c.metrics] == list(range(cfg.iterations + 1, cfg.iterations + cfg.chunk + 1))
    assert c.metrics[0]["samples"] == (cfg.iterations + 1) * cfg.samples_per_iteration
    final = dict(_leaves(a.state))
    # The new run trained on from A's state: its parameters moved away from A's final ones, but
    # its first log row's statistics continue A's (PopArt moved from A's, not from scratch).
    assert any(not np.array_equal(final[k], x) for k, x in _leaves(c.state) if "policy_params" in k)
    assert ckpt.read_config(tmp_path / "C", TrainConfig)[1].init_from == str(a.run_dir)

    wide = dataclasses.replace(more, net=dataclasses.replace(cfg.net, policy_hidden=(8,)))
    with jit_enabled(), pytest.raises(InitFromError, match="does not fit"):
        train_mod.train(EXPERIMENT, wide, run_dir=tmp_path / "D", progress=False, tensorboard=False)
    assert not (tmp_path / "D").exists()


def test_init_from_a_folder_that_is_no_run_is_one_line(tmp_path, capsys, motion_data):
    rc = train_mod.main([EXPERIMENT, f"init_from={tmp_path / 'nothing'}", "iterations=1", "chunk=1"])
    err = capsys.readouterr().err
    assert rc == 2 and "init_from=" in err and "not a run folder" in err and "Traceback" not in err


def test_restore_can_leave_leaves_out_but_finds_every_leaf_it_asks_for(tmp_path):
    """``checkpoint.restore(skip=...)`` (what ``init_from`` uses): skipped leaves keep the
    template's values whatever their shape on disk; a leaf of another shape, or one the
    checkpoint lacks, is an error rather than a silently fresh value."""
    import jax.numpy as jnp

    mgr = ckpt.manager(tmp_path)
    ckpt.save(mgr, 3, {"a": jnp.arange(3.0), "env": jnp.ones(5)})
    mgr.close()
    for like, problem in (
        ({"a": jnp.zeros(4), "env": jnp.zeros(7)}, "shape"),
        ({"a": jnp.zeros(3), "b": jnp.zeros(2), "env": jnp.zeros(7)}, "has no"),
    ):
        mgr = ckpt.manager(tmp_path)
        with pytest.raises(ValueError, match=problem):
            ckpt.restore(mgr, like, skip=("env",))
        mgr.close()
    mgr = ckpt.manager(tmp_path)
    got, step = ckpt.restore(mgr, {"a": jnp.zeros(3), "env": jnp.zeros(7)}, skip=("env",))
    mgr.close()
    assert step == 3
    np.testing.assert_array_equal(got["a"], [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(got["env"], np.zeros(7))
