"""Run folders that were killed, damaged or pointed at wrongly: resume past a damaged newest
checkpoint or a half-written log line, resume without repeating settings, stopping a training
that went non-finite, one-line errors for folders that are no run, no orphan folders, and the
data folder a run remembers.

One module-scoped pair of tiny runs (``test_train.tiny_config``, 4 iterations of one chunk, a
checkpoint after each) is trained once with one compiled chunk (``shared_chunk``) and one learner
(``shared_learner``: its compiled ``init`` took 15-40 s per learner on the shared 2-core CPU):
``full`` runs uninterrupted, ``part`` stops after 3 chunks. Each test copies ``part`` into its own
folder, damages it and resumes it (one or two more chunks), comparing with ``full`` bit for bit.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import DATA, jit_enabled
from jaxmotion import config as C
from jaxmotion import eval as eval_mod
from jaxmotion import train as train_mod
from jaxmotion.config.errors import JaxmotionError
from jaxmotion.motion import data as motion_data_mod
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.training import run as run_mod
from jaxmotion.training import runs as runs_mod
from jaxmotion.training.learner import TrainConfig
from jaxmotion.training.runs import load_run
from test_train import EXPERIMENT, _leaves, _rows, _untimed, motion_data, shared_chunk, tiny_config  # noqa: F401

pytestmark = pytest.mark.filterwarnings(
    # tensorstore's threads finishing the other reads of a damaged checkpoint after orbax closed
    # its event loop; outside pytest, checkpoint._DropClosedLoopCallbacks drops these
    "ignore:Exception ignored in. None:pytest.PytestUnraisableExceptionWarning"
)

ITERATIONS = 4
TINY_OVERRIDES = [
    "env.episode_steps=6",
    "net.policy_hidden=16,16",
    "net.critic_hidden=16,16",
    "net.disc_hidden=16,16",
    "net.disc_heads=2",
    "ppo.num_envs=4",
    "ppo.horizon=4",
    "ppo.minibatch_size=8",
    "ppo.epochs=1",
    "disc.minibatch_size=8",
    "seed=0",
    f"iterations={ITERATIONS}",
    "chunk=1",
    "checkpoint_every=1",
]
"""``tiny_config`` with 4 iterations on the command line (the same compiled chunk)."""


def _config() -> TrainConfig:
    return dataclasses.replace(tiny_config(), iterations=ITERATIONS)


@pytest.fixture(autouse=True)
def _forget_recorded_data(monkeypatch):
    """Loading a run sets the process-wide data fallback (``motion.data.use_recorded``): undone
    after each test, so no other test inherits it."""
    monkeypatch.setattr(motion_data_mod, "_recorded", None)


@pytest.fixture(scope="module")
def shared_learner():
    """Memoises ``make_learner`` (in the driver and in ``load_run``) by config minus run
    bookkeeping, so every run and load of the module compiles ``Learner.init`` once."""
    built: dict = {}
    real = runs_mod.make_learner

    def memo(cfg, env=None):
        if env is not None:
            return real(cfg, env)
        key = dataclasses.replace(cfg, resume="", init_from="", iterations=0, checkpoint_every=0)
        if key not in built:
            built[key] = real(cfg)
        return built[key]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(run_mod, "make_learner", memo)
        mp.setattr(runs_mod, "make_learner", memo)
        yield real


@pytest.fixture(scope="module")
def base(motion_data, shared_chunk, shared_learner, tmp_path_factory):  # noqa: F811
    """``full``: 4 chunks uninterrupted; ``part``: the same stopped after 3 (checkpoints 1-3)."""
    cfg = _config()
    root = tmp_path_factory.mktemp("run_folders")
    with jit_enabled():
        full = train_mod.train(EXPERIMENT, cfg, run_dir=root / "full", progress=False, tensorboard=False)
        train_mod.train(EXPERIMENT, cfg, run_dir=root / "part", progress=False, tensorboard=False, stop_after_chunks=3)
    return dict(
        cfg=cfg,
        full=dict(_leaves(full.state)),
        full_rows=_rows(root / "full"),
        part=root / "part",
        make_learner=shared_learner,
    )


def _copy(base: dict, dest: Path) -> Path:
    shutil.copytree(base["part"], dest)
    return dest


def _resume(cfg: TrainConfig, run: Path, **kwargs) -> run_mod.RunResult:
    with jit_enabled():
        return train_mod.train(
            EXPERIMENT, dataclasses.replace(cfg, resume=str(run)), progress=False, tensorboard=False, **kwargs
        )


def _steps(run: Path) -> list[int]:
    return sorted(int(p.name) for p in (run / "checkpoints").iterdir() if p.name.isdigit())


def _damage(run: Path, step: int, how: str) -> None:
    """Cuts the largest array file of checkpoint ``step`` in half, or deletes it."""
    files = [f for f in (run / "checkpoints" / str(step) / "default" / "d").iterdir() if f.is_file()]
    f = max(files, key=lambda f: f.stat().st_size)
    if how == "truncate":
        f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    else:
        f.unlink()


def _same_as_full(base: dict, result: run_mod.RunResult) -> None:
    """The resumed run ends bit for bit where the uninterrupted one did, with the same log."""
    assert int(result.state.iteration) == ITERATIONS
    for k, x in _leaves(result.state):
        np.testing.assert_array_equal(x, base["full"][k], err_msg=k)
    assert [_untimed(r) for r in _rows(result.run_dir)] == [_untimed(r) for r in base["full_rows"]]


def _one_line_error(err: str) -> None:
    lines = err.strip().splitlines()
    assert lines and lines[-1].startswith("error: ") and "Traceback" not in err, err


@pytest.mark.slow
@pytest.mark.parametrize("how", ["truncate", "delete"])
def test_resume_falls_back_past_a_damaged_newest_checkpoint(base, tmp_path, capsys, how):
    run = _copy(base, tmp_path / "run")
    _damage(run, 3, how)
    result = _resume(base["cfg"], run)
    err = capsys.readouterr().err
    assert "checkpoint 3 is damaged (" in err and "resuming from 2" in err, err
    _same_as_full(base, result)
    assert (run / ckpt.DAMAGED_DIR / "3").is_dir()  # set aside, so step 3 could be written again
    assert _steps(run)[-1] == ITERATIONS


@pytest.mark.slow
def test_load_run_falls_back_and_a_run_with_no_intact_checkpoint_is_one_line(base, tmp_path, capsys, monkeypatch):
    run = _copy(base, tmp_path / "run")
    _damage(run, 3, "truncate")
    with jit_enabled():
        _, _, _, ts = load_run(run)
    assert int(ts.iteration) == 2
    assert "checkpoint 3 is damaged (" in capsys.readouterr().err
    for step in (1, 2):
        _damage(run, step, "delete")
    with jit_enabled(), pytest.raises(ckpt.RunFolderError, match="no checkpoint .* can be read"):
        load_run(run)
    monkeypatch.chdir(tmp_path)
    capsys.readouterr()
    with jit_enabled():
        assert train_mod.main([EXPERIMENT, f"resume={run}"]) == 2
    err = capsys.readouterr().err
    _one_line_error(err)
    assert "can be read" in err
    with jit_enabled():
        assert eval_mod.main([str(run), "--no-plots"]) == 2
    _one_line_error(capsys.readouterr().err)


def test_a_run_loads_after_its_scene_state_gained_a_field(base, tmp_path, monkeypatch):
    """``load_run`` (eval, composers, meta policies) restores networks and statistics, not the
    environments' state: a task whose goal state gained a timer (boxing's hit interval did) still
    loads the runs trained before it, with the checkpoint's parameters."""
    run = _copy(base, tmp_path / "run")
    real = runs_mod.make_learner

    def grown(cfg, env=None):
        learner = real(cfg, env) if env is not None else real(cfg)
        init = learner.init

        def init_with_timer(rng):
            ts = init(rng)
            return ts.replace(env_state=ts.env_state.replace(goal={"timer": jnp.zeros((4,), jnp.int32)}))

        monkeypatch.setattr(learner, "init", init_with_timer)
        return learner

    monkeypatch.setattr(runs_mod, "make_learner", grown)
    with jit_enabled():
        _, _, _, ts = load_run(run)
    assert int(ts.iteration) == 3
    assert set(ts.env_state.goal) == {"timer"}


@pytest.mark.slow
def test_resume_past_a_half_written_metrics_line(base, tmp_path):
    run = _copy(base, tmp_path / "run")
    with open(run / "metrics.jsonl", "a") as f:
        f.write('{"iteration": 4, "samples": 6')  # killed mid-write
    result = _resume(base["cfg"], run)
    assert [r["iteration"] for r in _rows(run)] == list(range(1, ITERATIONS + 1))  # the cut line is gone
    _same_as_full(base, result)


@pytest.mark.slow
def test_a_kill_before_the_first_checkpoint_leaves_no_repeated_rows(base, tmp_path):
    """Metrics logged, then killed before any checkpoint: the resumed run starts at 0 and its log
    holds each iteration once (the same as an uninterrupted run's)."""
    run = _copy(base, tmp_path / "run")
    shutil.rmtree(run / "checkpoints")
    assert [r["iteration"] for r in _rows(run)] == [1, 2, 3]
    _same_as_full(base, _resume(base["cfg"], run))


@pytest.mark.slow
def test_resume_keeps_the_saved_settings_unless_length_is_given(base, tmp_path, capsys, monkeypatch):
    run = _copy(base, tmp_path / "run")
    monkeypatch.chdir(tmp_path)
    with jit_enabled():
        assert train_mod.main([EXPERIMENT, f"resume={run}"]) == 0  # the smoke default would say 6
    assert [r["iteration"] for r in _rows(run)] == [1, 2, 3, 4] and _steps(run)[-1] == 4
    with jit_enabled():
        assert train_mod.main([EXPERIMENT, f"resume={run}", "iterations=5"]) == 0
    assert [r["iteration"] for r in _rows(run)] == [1, 2, 3, 4, 5] and _steps(run)[-1] == 5
    assert ckpt.read_config(run, TrainConfig)[1] == dataclasses.replace(base["cfg"], iterations=5)
    capsys.readouterr()
    assert train_mod.main([EXPERIMENT, f"resume={run}", "ppo.gamma=0.9", "iterations=6"]) == 2
    err = capsys.readouterr().err
    _one_line_error(err)
    assert "ppo.gamma" in err and "iterations" not in err.split("cannot change")[0], err
    assert _steps(run)[-1] == 5


def _poisoned(monkeypatch, at: int, what: str) -> None:
    """Makes the chunk ending at iteration ``at`` go non-finite: its ``ppo/policy_loss``
    (``what='metrics'``), its policy parameters (``'state'``), or raise ``KeyboardInterrupt``
    (``'interrupt'``). Wraps the module's memoised ``make_train_chunk`` (not an earlier
    poisoned one): nothing is compiled."""
    real = getattr(run_mod.make_train_chunk, "unpoisoned", run_mod.make_train_chunk)

    def make(learner, mesh, chunk, example):
        fn = real(learner, mesh, chunk, example)

        def run(ts):
            ts, m = fn(ts)
            if int(ts.iteration) == at:
                if what == "metrics":
                    m = {**m, "ppo/policy_loss": m["ppo/policy_loss"] * jnp.nan}
                elif what == "state":
                    ts = ts.replace(policy_params=jax.tree.map(lambda x: x * jnp.nan, ts.policy_params))
                else:
                    raise KeyboardInterrupt
            return ts, m

        return run

    make.unpoisoned = real
    monkeypatch.setattr(run_mod, "make_train_chunk", make)


@pytest.mark.slow
def test_a_training_that_goes_non_finite_stops_and_keeps_its_last_good_checkpoint(base, tmp_path, capsys, monkeypatch):
    _poisoned(monkeypatch, 3, "metrics")
    with jit_enabled(), pytest.raises(run_mod.TrainingDiverged) as e:
        train_mod.train(EXPERIMENT, base["cfg"], run_dir=tmp_path / "A", progress=False, tensorboard=False)
    msg = str(e.value)
    assert "non-finite at iteration 3 (ppo/policy_loss = nan)" in msg, msg
    assert f"last good checkpoint is 2 in {tmp_path / 'A' / 'checkpoints'}" in msg and "learning rates" in msg
    assert _steps(tmp_path / "A") == [1, 2]
    with jit_enabled():
        _, _, _, ts = load_run(tmp_path / "A")
    assert int(ts.iteration) == 2
    assert all(np.isfinite(x).all() for _, x in _leaves(ts.policy_params))

    # The command line: one line, a non-zero exit, the last good checkpoint kept.
    _poisoned(monkeypatch, 2, "state")
    monkeypatch.chdir(tmp_path)
    with jit_enabled():
        assert train_mod.main([EXPERIMENT, *TINY_OVERRIDES]) == 2
    err = capsys.readouterr().err
    _one_line_error(err)
    assert "non-finite at iteration 2 (non-finite policy_params)" in err, err
    (run,) = list((tmp_path / "runs" / EXPERIMENT).iterdir())
    assert _steps(run) == [1]


def test_the_command_line_overrides_give_the_tiny_config():
    """The compiled chunk the command-line tests reuse is the module's (same config)."""
    assert C.apply_overrides(C.load_experiment(EXPERIMENT), TINY_OVERRIDES) == _config()


@pytest.mark.slow
@pytest.mark.parametrize("what", ["interrupt", "state"])
def test_a_new_run_that_fails_before_its_first_checkpoint_leaves_no_folder(base, tmp_path, monkeypatch, what):
    _poisoned(monkeypatch, 1, what)
    with jit_enabled(), pytest.raises((KeyboardInterrupt, run_mod.TrainingDiverged)) as e:
        train_mod.train(EXPERIMENT, base["cfg"], run_dir=tmp_path / "new", progress=False, tensorboard=False)
    assert not (tmp_path / "new").exists()
    if what == "state":
        assert "no checkpoint was written" in str(e.value) and "is removed" in str(e.value)
    # A run with a checkpoint, or a resumed one, keeps its folder.
    _poisoned(monkeypatch, 2, what)
    with jit_enabled(), pytest.raises((KeyboardInterrupt, run_mod.TrainingDiverged)):
        train_mod.train(EXPERIMENT, base["cfg"], run_dir=tmp_path / "kept", progress=False, tensorboard=False)
    assert _steps(tmp_path / "kept") == [1]
    run = _copy(base, tmp_path / "resumed")
    shutil.rmtree(run / "checkpoints")
    _poisoned(monkeypatch, 1, what)
    with pytest.raises((KeyboardInterrupt, run_mod.TrainingDiverged)):
        _resume(base["cfg"], run)
    assert (run / ckpt.CONFIG_FILE).exists()


def _bad_folders(root: Path) -> dict[str, Path]:
    """Folders that are no usable run, by what is wrong with them."""
    good = {"experiment": EXPERIMENT, "config": C.to_dict(_config())}
    docs = {
        "not JSON": '{"experiment": "smoke", "conf',
        "not an object": "[1, 2]",
        "no experiment": json.dumps({"config": good["config"]}),
        "no config": json.dumps({"experiment": EXPERIMENT}),
        "experiment not a string": json.dumps({**good, "experiment": 3}),
        "field of the wrong type": json.dumps({**good, "config": {**good["config"], "iterations": "many"}}),
        "unknown field": json.dumps({**good, "config": {**good["config"], "no_such_field": 1}}),
    }
    out = {"missing": root / "missing", "no config.json": root / "empty"}
    out["no config.json"].mkdir()
    for name, text in docs.items():
        out[name] = root / name.replace(" ", "_")
        out[name].mkdir()
        (out[name] / ckpt.CONFIG_FILE).write_text(text)
    return out


def test_folders_that_are_no_run_are_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for why, folder in _bad_folders(tmp_path).items():
        with pytest.raises(ckpt.RunFolderError) as e:
            ckpt.read_config(folder, TrainConfig)
        assert str(folder) in str(e.value) and "\n" not in str(e.value), (why, str(e.value))
        with pytest.raises(ckpt.RunFolderError):
            load_run(folder)
        assert train_mod.main([EXPERIMENT, f"resume={folder}"]) == 2, why
        _one_line_error(capsys.readouterr().err)
        assert eval_mod.main([str(folder), "--no-plots"]) == 2, why
        _one_line_error(capsys.readouterr().err)
    assert not (tmp_path / "runs").exists()
    # A config.json without checkpoints: nothing to restore either (load_run gets there after
    # loading the clips, so that missing clips are named first).
    run = tmp_path / "no_checkpoint"
    ckpt.write_config(run, EXPERIMENT, _config())
    with pytest.raises(ckpt.RunFolderError, match="no checkpoint"):
        ckpt.restore_run(run, {})


@pytest.mark.slow
def test_a_run_remembers_its_data_folder(base, tmp_path, monkeypatch):
    """``resolved.data`` in config.json: used by ``load_run`` when ``$JAXMOTION_DATA`` is unset,
    ignored when it is set."""
    assert ckpt.read_resolved(base["part"])["data"] == str(DATA.absolute())
    monkeypatch.chdir(tmp_path)  # no ./data here
    monkeypatch.setattr(runs_mod, "make_learner", base["make_learner"])  # really load the clips
    monkeypatch.setattr(motion_data_mod, "_recorded", None)
    monkeypatch.delenv("JAXMOTION_DATA")
    with jit_enabled():
        _, _, _, ts = load_run(base["part"])
    assert int(ts.iteration) == 3 and motion_data_mod.data_dir() == DATA.absolute()

    monkeypatch.setattr(motion_data_mod, "_recorded", None)
    monkeypatch.setenv("JAXMOTION_DATA", str(tmp_path / "nowhere"))
    with jit_enabled(), pytest.raises(JaxmotionError, match="nowhere"):
        load_run(base["part"])


def test_mujoco_warnings_are_counted_into_the_run_folder(tmp_path):
    """MuJoCo's warnings of a chunk go to ``physics.log`` (iteration, count, message) and their
    total is returned for the chunk's metrics row; a chunk without warnings writes nothing."""
    from jaxmotion.physics import backends

    backends.WARNINGS.take()
    assert run_mod.log_physics_warnings(tmp_path, 10) == 0
    assert not (tmp_path / run_mod.PHYSICS_LOG).exists()
    unstable = "Nan, Inf or huge value in QACC at DOF 7. The simulation is unstable."
    for _ in range(3):
        backends.WARNINGS._on_warning(unstable + " Time = 0.25.")
    backends.WARNINGS._on_warning("Too many contacts. Time = 1.0.")
    assert run_mod.log_physics_warnings(tmp_path, 20) == 4
    lines = (tmp_path / run_mod.PHYSICS_LOG).read_text().splitlines()
    assert lines == [
        f"iteration 20: 3 x {unstable}",
        "iteration 20: 1 x Too many contacts.",
    ]
    assert run_mod.log_physics_warnings(tmp_path, 30) == 0


def test_every_chunk_logs_its_physics_warning_count(base):
    """The last row of every chunk carries ``physics/warnings`` (a stable tiny run: 0)."""
    rows = base["full_rows"]
    assert [r.get("physics/warnings") for r in rows] == [0.0] * ITERATIONS
