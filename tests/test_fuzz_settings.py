"""Fuzz test of the settings: every bad setting on the command line is one clear line, before
anything compiles or is written.

``CASES`` are bad settings (zero, negative, NaN, inf, huge, of the wrong type, typo'd keys, unknown
choices, empty tuples, and settings that break a rule between fields) on the ``smoke`` experiment
and the two-player ``boxing/selfplay``. For each, ``python -m jaxmotion.train`` run in-process must
return non-zero with exactly one ``error:`` line on stderr that names the key, let no exception
escape, and leave the working folder empty (no ``runs/``). The learner's ``init`` and the compiled
chunk are replaced by a failure: a setting that got as far as them was accepted. The eval CLI's
flags are checked the same way, before its run folder is even loaded.
"""

from __future__ import annotations

import os

import pytest

from conftest import REPO
from jaxmotion import eval as eval_mod
from jaxmotion import train as train_mod
from jaxmotion.training import run as run_mod
from jaxmotion.training.learner import Learner

SMOKE, BOX = "smoke", "boxing/selfplay"
CASES = [
    # (experiment, settings, the key the error must name)
    (SMOKE, ["ppo.num_envs=0"], "ppo.num_envs"),
    (SMOKE, ["ppo.num_envs=-4"], "ppo.num_envs"),
    (SMOKE, ["ppo.num_envs=abc"], "ppo.num_envs"),
    (SMOKE, ["ppo.horizon=0"], "ppo.horizon"),
    (SMOKE, ["ppo.minibatch_size=0"], "ppo.minibatch_size"),
    (SMOKE, ["ppo.minibatch_size=48"], "ppo.minibatch_size"),
    (SMOKE, ["ppo.minibatch_size=256"], "ppo.minibatch_size"),
    (SMOKE, ["ppo.epochs=0"], "ppo.epochs"),
    (SMOKE, ["ppo.epochs=2.5"], "ppo.epochs"),
    (SMOKE, ["ppo.epoch=3"], "ppo.epoch"),
    (SMOKE, ["ppo.gamma=nan"], "ppo.gamma"),
    (SMOKE, ["ppo.gamma=1.5"], "ppo.gamma"),
    (SMOKE, ["ppo.gamma=1"], "ppo.gamma"),
    (SMOKE, ["ppo.gamma=-0.1"], "ppo.gamma"),
    (SMOKE, ["ppo.lam=2"], "ppo.lam"),
    (SMOKE, ["ppo.clip_eps=-0.2"], "ppo.clip_eps"),
    (SMOKE, ["ppo.clip_eps=0"], "ppo.clip_eps"),
    (SMOKE, ["ppo.actor_lr=-1"], "ppo.actor_lr"),
    (SMOKE, ["ppo.actor_lr=0"], "ppo.actor_lr"),
    (SMOKE, ["ppo.critic_lr=inf"], "ppo.critic_lr"),
    (SMOKE, ["ppo.meta_weight_lr=-1e-3"], "ppo.meta_weight_lr"),
    (SMOKE, ["ppo.max_grad_norm=0"], "ppo.max_grad_norm"),
    (SMOKE, ["ppo.value_coef=-0.5"], "ppo.value_coef"),
    (SMOKE, ["ppo.entropy_coef=nan"], "ppo.entropy_coef"),
    (SMOKE, ["ppo.popart_beta=0"], "ppo.popart_beta"),
    (SMOKE, ["ppo.popart_beta=1.5"], "ppo.popart_beta"),
    (SMOKE, ["ppo.obs_clip=-5"], "ppo.obs_clip"),
    (SMOKE, ["ppo.objective_weights=0.2,0.3,0.5"], "ppo.objective_weights"),
    (SMOKE, ["ppo.objective_weights=-1,2"], "ppo.objective_weights"),
    (SMOKE, ["ppo.objective_weights=0,0"], "ppo.objective_weights"),
    (SMOKE, ["ppo.terminate_reward=0.5"], "ppo.terminate_reward"),
    (SMOKE, ["ppo.terminate_reward=none"], "ppo.terminate_reward"),
    (SMOKE, ["ppo.terminate_reward=-inf"], "ppo.terminate_reward"),
    (SMOKE, ["ppo.multi_objective=maybe"], "ppo.multi_objective"),
    (SMOKE, ["chunk=0"], "chunk"),
    (SMOKE, ["chunk=-2"], "chunk"),
    (SMOKE, ["iterations=0"], "iterations"),
    (SMOKE, ["iterations=-10"], "iterations"),
    (SMOKE, ["iterations=5"], "iterations"),
    (SMOKE, ["iterations=1"], "iterations"),
    (SMOKE, ["iterations=1e30"], "iterations"),
    (SMOKE, ["itrations=10"], "itrations"),
    (SMOKE, ["checkpoint_every=0"], "checkpoint_every"),
    (SMOKE, ["eval_every=-1"], "eval_every"),
    (SMOKE, ["eval_episodes=0"], "eval_episodes"),
    (SMOKE, ["seed=1e30"], "seed"),
    (SMOKE, ["seed=1.5"], "seed"),
    (SMOKE, ["hard_negatives_every=-1"], "hard_negatives_every"),
    (SMOKE, ["hard_negatives_every=5"], "hard_negatives_every"),
    (SMOKE, ["player_policies=seperate"], "player_policies"),
    (SMOKE, ["player_policies=separate"], "player_policies"),
    (SMOKE, ["opponent_pool=2"], "opponent_pool"),
    (SMOKE, ["opponent_pool=-1"], "opponent_pool"),
    (SMOKE, ["net.policy_hidden=0,0"], "net.policy_hidden"),
    (SMOKE, ["net.critic_hidden=-8"], "net.critic_hidden"),
    (SMOKE, ["net.disc_hidden=0"], "net.disc_hidden"),
    (SMOKE, ["net.disc_heads=0"], "net.disc_heads"),
    (SMOKE, ["net.activation=gelu"], "net.activation"),
    (SMOKE, ["net.init_log_std=nan"], "net.init_log_std"),
    (SMOKE, ["net.disc_hidden_gain=0"], "net.disc_hidden_gain"),
    (SMOKE, ["net.critic_hidden_init=-1"], "net.critic_hidden_init"),
    (SMOKE, ["disc.loss=foo"], "disc.loss"),
    (SMOKE, ["disc.gp_mode=per_heads"], "disc.gp_mode"),
    (SMOKE, ["disc.lr=0"], "disc.lr"),
    (SMOKE, ["disc.gp_weight=-10"], "disc.gp_weight"),
    (SMOKE, ["disc.minibatch_size=0"], "disc.minibatch_size"),
    (SMOKE, ["disc.minibatch_size=100"], "disc.minibatch_size"),
    (SMOKE, ["env.physics.control_hz=0"], "env.physics.control_hz"),
    (SMOKE, ["env.physics.control_hz=inf"], "env.physics.control_hz"),
    (SMOKE, ["env.physics.sim_hz=100"], "env.physics.sim_hz"),
    (SMOKE, ["env.physics.sim_hz=-120"], "env.physics.sim_hz"),
    (SMOKE, ["env.physics.threads=-1"], "env.physics.threads"),
    (SMOKE, ["env.physics.impl=foo"], "env.physics.impl"),
    (SMOKE, ["env.physics.backend=foo"], "env.physics.backend"),
    (SMOKE, ["env.physics.solver_iterations=0"], "env.physics.solver_iterations"),
    (SMOKE, ["env.physics.servo_damping=joints"], "env.physics.servo_damping"),
    (SMOKE, ["env.physics.racket=true"], "env.physics.racket"),
    (SMOKE, ["env.episode_steps=0"], "env.episode_steps"),
    (SMOKE, ["env.max_qvel=-1"], "env.max_qvel"),
    (SMOKE, ["env.max_qvel=nan"], "env.max_qvel"),
    (SMOKE, ["env.policy_frames=0"], "env.policy_frames"),
    (SMOKE, ["env.action_scale=0"], "env.action_scale"),
    (SMOKE, ["env.fall_height=-0.1"], "env.fall_height"),
    (SMOKE, ["env.contact_grace_steps=-1"], "env.contact_grace_steps"),
    (SMOKE, ["env.init_sampling=random"], "env.init_sampling"),
    (SMOKE, ["env.groups=[]"], "env.groups"),
    (SMOKE, ['env.groups=[{"name": "upper", "frames": 0}]'], "env.groups[0].frames"),
    (SMOKE, ['env.groups=[{"name": "upper", "speed_range": [1.2, 0.8]}]'], "env.groups[0].speed_range"),
    (SMOKE, ['env.groups=[{"name": "uper"}]'], "env.groups[0].name"),
    (SMOKE, ["env.players=3"], "env.players"),
    (SMOKE, ["env.players=2"], "env.groups"),
    (SMOKE, ["env.task.name=foo"], "env.task.name"),
    (SMOKE, ["env.task.name=boxing"], "env.task.name"),
    (SMOKE, ["env.task.location.radius=-1"], "env.task.location.radius"),
    (SMOKE, ["env.task.location.timer_range=150,90"], "env.task.location.timer_range"),
    (SMOKE, ["env.task.track.goal=keypoints"], "env.task.track.goal"),
    (SMOKE, ["env.frobnicate=1"], "env.frobnicate"),
    (BOX, ["ppo.num_envs=0"], "ppo.num_envs"),
    (BOX, ["ppo.minibatch_size=100"], "ppo.minibatch_size"),
    (BOX, ["ppo.absorbing_termination=true"], "ppo.absorbing_termination"),
    (BOX, ["player_policies=separate", "opponent_pool=2"], "opponent_pool"),
    (BOX, ["opponent_pool=2", "opponent_share=0"], "opponent_share"),
    (BOX, ["opponent_pool=2", "opponent_share=1.5"], "opponent_share"),
    (BOX, ["opponent_pool=2", "opponent_every=0"], "opponent_every"),
    (BOX, ['env.groups=[{"name": "upper"}]'], "env.groups"),
    (BOX, ["env.init_motions=()"], "env.init_motions"),
    (BOX, ["env.arena.sport=fencing"], "env.arena.sport"),
    (BOX, ["env.arena.sport=tennis"], "env.arena.sport"),
    (BOX, ["env.arena.ring_size=-5"], "env.arena.ring_size"),
    (BOX, ["env.arena.pair_condim=2"], "env.arena.pair_condim"),
    (BOX, ["env.task.name=location"], "env.task.name"),
    (BOX, ["env.task.boxing.weights=1,2"], "env.task.boxing.weights"),
    (BOX, ["env.task.boxing.damage_clip=-1"], "env.task.boxing.damage_clip"),
    (BOX, ["env.task.boxing.start_distance=3,0.7"], "env.task.boxing.start_distance"),
    (BOX, ["env.physics.sim_hz=250"], "env.physics.sim_hz"),
    (BOX, ["env.episode_steps=-300"], "env.episode_steps"),
]
"""(experiment, settings, the key its error line must name). ``ppo.num_envs=1e9`` (it needs the
environment built, so the clips) is ``test_too_many_environments_is_one_line``."""


def _refuse(*args, **kwargs):
    raise AssertionError("the settings were accepted: the learner's init or the compiled chunk was reached")


@pytest.fixture
def nothing_compiles(monkeypatch, tmp_path):
    """In an empty working folder, with the learner's ``init`` and the compiled chunk refused."""
    monkeypatch.setattr(Learner, "init", _refuse)
    monkeypatch.setattr(run_mod, "make_train_chunk", _refuse)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def assert_one_clear_line(rc, capsys, key: str, folder) -> str:
    """One ``error:`` line naming ``key``, a non-zero status, no traceback, nothing written."""
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert rc != 0, (rc, out, err)
    assert len(lines) == 1, err
    assert key in lines[0], lines[0]
    assert "Traceback" not in err + out
    assert sorted(p.name for p in folder.iterdir()) == [], "something was written"
    return lines[0]


@pytest.mark.parametrize("experiment, settings, key", CASES, ids=[f"{e}:{' '.join(s)}" for e, s, _ in CASES])
def test_bad_setting_is_one_clear_line(experiment, settings, key, nothing_compiles, capsys):
    rc = train_mod.main([experiment, *settings])
    assert_one_clear_line(rc, capsys, key, nothing_compiles)
    assert not (nothing_compiles / "runs").exists()


def test_case_list_is_broad():
    assert len(CASES) >= 80
    assert len({k for _, _, k in CASES}) >= 60
    assert {e for e, _, _ in CASES} == {SMOKE, BOX}


@pytest.mark.parametrize("experiment, n", [(SMOKE, "1e9"), (BOX, "1e8")])
def test_too_many_environments_is_one_line(experiment, n, nothing_compiles, capsys, data_dir, monkeypatch):
    """Environments whose states cannot fit in memory: a ``ppo.num_envs`` error with the estimate,
    after the environment is built (its clips loaded) and before anything is allocated for them."""
    monkeypatch.setenv("JAXMOTION_DATA", str(data_dir))
    rc = train_mod.main([experiment, f"ppo.num_envs={n}"])
    line = assert_one_clear_line(rc, capsys, "ppo.num_envs", nothing_compiles)
    assert "memory" in line and "B each" in line


# ---- python -m jaxmotion.eval ----------------------------------------------------------------

RUN = REPO / "pretrained" / "chest_open+squat_cpu"
"""A real run folder; the flags below are refused before it is loaded."""


@pytest.fixture
def no_rollout(monkeypatch, tmp_path):
    """In an empty working folder, with loading the run (the first step of every rollout) refused."""
    monkeypatch.setattr(eval_mod, "load_run", _refuse)
    monkeypatch.chdir(tmp_path)
    return tmp_path


EVAL_CASES = [
    (["--episodes", "0"], "--episodes"),
    (["--episodes", "-3"], "--episodes"),
    (["--steps", "0"], "--steps"),
    (["--bouts", "0"], "--bouts"),
    (["--bouts", "7"], "--bouts"),
    (["--switch-every", "0"], "--switch-every"),
    (["--switch-every", "nan"], "--switch-every"),
    (["--noise", "-1"], "--noise"),
    (["--noise", "inf"], "--noise"),
]


@pytest.mark.parametrize("flags, key", EVAL_CASES, ids=[" ".join(f) for f, _ in EVAL_CASES])
def test_bad_eval_number_is_one_line(flags, key, no_rollout, capsys):
    rc = eval_mod.main([str(RUN), *flags])
    assert_one_clear_line(rc, capsys, key, no_rollout)


@pytest.mark.parametrize("flag", ["--json", "--video", "--html"])
def test_unwritable_eval_output_is_one_line_before_the_rollout(flag, no_rollout, capsys):
    (no_rollout / "a_file").write_text("x")
    for target in (no_rollout / "a_file" / "out.json", no_rollout):  # under a file; a folder
        rc = eval_mod.main([str(RUN), flag, str(target)])
        out, err = capsys.readouterr()
        lines = [line for line in err.splitlines() if line.startswith("error:")]
        assert rc == 2 and len(lines) == 1 and flag in lines[0], err
        assert sorted(p.name for p in no_rollout.iterdir()) == ["a_file"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only folder")
def test_read_only_eval_folder_is_one_line(no_rollout, capsys):
    ro = no_rollout / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        rc = eval_mod.main([str(RUN), "--json", str(ro / "m.json")])
    finally:
        ro.chmod(0o700)
    _, err = capsys.readouterr()
    assert rc == 2 and err.count("error:") == 1 and "--json" in err


def test_eval_output_in_a_new_folder_is_made_before_the_run_loads(no_rollout):
    target = no_rollout / "new" / "deeper" / "metrics.json"
    with pytest.raises(AssertionError, match="accepted"):  # got as far as loading the run
        eval_mod.main([str(RUN), "--json", str(target), "--episodes", "2"])
    assert target.parent.is_dir() and not target.exists()


def test_bench_batches_that_are_no_numbers_are_one_line(capsys):
    from jaxmotion import bench

    with pytest.raises(SystemExit) as e:
        bench.main(["--batches", "abc"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "--batches abc" in err and "Traceback" not in err
