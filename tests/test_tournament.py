"""``python -m jaxmotion.tournament``: the Bradley-Terry fit on payoffs whose strengths are known,
the matrix's antisymmetry, the bootstrap intervals, a real tiny boxing tournament (untrained
players, a few steps) whose matrix equals the reverse-order play, and bad input on the CLI."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import jax
import numpy as np
import pytest

from conftest import REPO, jit_enabled
from jaxmotion import tournament as cli
from jaxmotion.evaluation import tournament as T

STRENGTH = np.array([-1.0, 0.0, 0.5, 1.5])  # true log-strengths of four synthetic players


def _synthetic(bouts: int, seeds: int = 1, seed: int = 0):
    """Per-bout values of every pair i < j [seeds, bouts]: normal around θ_i - θ_j (a damage
    difference), and its sign as the score."""
    rng = np.random.default_rng(seed)
    n = len(STRENGTH)
    values = {
        (i, j): rng.normal(STRENGTH[i] - STRENGTH[j], 1.0, (seeds, bouts)) for i in range(n) for j in range(i + 1, n)
    }
    return values, {k: np.sign(v) for k, v in values.items()}


def test_bradley_terry_recovers_known_strengths_and_stays_finite_when_one_player_wins_everything():
    n = len(STRENGTH)
    p = 1.0 / (1.0 + np.exp(STRENGTH[None, :] - STRENGTH[:, None]))  # P(i beats j)
    wins = 100.0 * p * (1 - np.eye(n))  # the expected counts: their MLE is the truth itself
    theta = T.bradley_terry(wins, np.zeros((n, n)), prior_games=0.0)
    np.testing.assert_allclose(theta, STRENGTH - STRENGTH.mean(), atol=1e-6)
    # The prior shrinks towards 0 but keeps the order; draws count half a win each way.
    shrunk = T.bradley_terry(wins, np.zeros((n, n)))
    assert list(np.argsort(shrunk)) == [0, 1, 2, 3] and np.all(np.abs(shrunk) < np.abs(theta))
    np.testing.assert_allclose(T.bradley_terry(np.zeros((2, 2)), np.array([[0, 8], [8, 0]])), 0.0, atol=1e-12)
    # One player wins all its bouts: finite, first, and more bouts make it stronger.
    allwin = np.array([[0, 10, 10], [0, 0, 5], [0, 5, 0]])
    t10 = T.bradley_terry(allwin, np.zeros((3, 3)))
    t100 = T.bradley_terry(10 * allwin, np.zeros((3, 3)))
    assert np.all(np.isfinite(t10)) and t10[0] > t10[1] == pytest.approx(t10[2])
    assert t10[0] < t100[0] < 20


def test_tournament_of_synthetic_payoffs_ranks_the_players_and_its_matrix_is_antisymmetric():
    values, scores = _synthetic(bouts=64, seeds=2)
    names = ["weak", "mid", "good", "best"]
    res = T.summarize(names, "boxing", values, scores, resamples=400)
    m = np.asarray(res["matrix"])
    lo, hi = (np.asarray(x) for x in res["matrix_ci95"])
    np.testing.assert_array_equal(m, -m.T)
    np.testing.assert_array_equal(np.diag(m), 0.0)
    np.testing.assert_array_equal(lo, -hi.T)
    assert np.all(lo <= m) and np.all(m <= hi)
    # The matrix estimates θ_i - θ_j (each entry within its interval's reach of the truth).
    truth = STRENGTH[:, None] - STRENGTH[None, :]
    assert np.all(np.abs(m - truth) < 3 * (hi - lo) + 1e-9)
    wins, draws, losses = (np.asarray(res[k]) for k in ("wins", "draws", "losses"))
    np.testing.assert_array_equal(wins, losses.T)
    np.testing.assert_array_equal(wins + draws + losses, 128 * (1 - np.eye(4)))
    r = res["rating"]
    assert r["ranking"] == ["best", "good", "mid", "weak"]
    elo = np.array([r["elo"][k] for k in names])
    assert abs(elo.mean()) < 1e-9
    assert all(r["elo_ci95"][k][0] <= r["elo"][k] <= r["elo_ci95"][k][1] for k in names)
    assert r["elo_ci95"]["best"][0] > r["elo_ci95"]["weak"][1]  # far apart: intervals do not overlap
    # Fencing's touch results (+1/0/-1) run the same path.
    touch = {k: np.sign(np.round(v)) for k, v in values.items()}
    assert T.summarize(names, "fencing", touch, touch, resamples=200)["rating"]["ranking"][0] == "best"


def test_bootstrap_intervals_contain_the_mean_and_shrink_with_more_bouts():
    widths = []
    for bouts in (8, 128):
        v = _synthetic(bouts=bouts, seeds=2, seed=bouts)[0][0, 2]
        lo, hi = T.interval(T.bootstrap_means(v, 1000))
        assert lo < v.mean() < hi
        widths.append(hi - lo)
    assert widths[1] < 0.5 * widths[0]  # 16x the bouts: about a quarter of the width
    # The unit is a start's pair of bouts: bouts that cancel in pairs have a zero-width interval.
    assert T.interval(T.bootstrap_means(np.array([[3.0, -3.0, 1.0, -1.0]]), 200)) == [0.0, 0.0]
    with pytest.raises(ValueError, match="even"):
        T.units(np.zeros((1, 3)))


# --------------------------------------------------------------------------- a real tiny tournament


@pytest.fixture(scope="module")
def boxers():
    """Three untrained boxers (policies of seeds 0-2) of one tiny learner (16-unit networks, the
    test clip, 30-step rounds: the settings of ``test_bout``), so every pair's bouts compile
    once. A player is what acting needs (a ``PolicyState``): no training state is built."""
    from test_bout import _env

    from jaxmotion.algos import normalizer as N
    from jaxmotion.nets.policies import PolicyState
    from jaxmotion.tasks import TaskConfig
    from jaxmotion.training.learner import NetConfig, PPOConfig, TrainConfig
    from jaxmotion.training.runs import make_learner

    task = TaskConfig(name="boxing")
    task = dataclasses.replace(task, boxing=dataclasses.replace(task.boxing, start_distance=(0.7, 0.9)))
    env = _env("boxing", task=task, episode_steps=30)
    cfg = TrainConfig(
        env=env.cfg,
        net=NetConfig(policy_hidden=(16,), critic_hidden=(16,)),
        ppo=PPOConfig(
            num_envs=2,
            horizon=4,
            minibatch_size=8,
            multi_objective=False,
            terminate_reward=None,
            absorbing_termination=False,
        ),
    )
    learner = make_learner(cfg, env=env)
    return [
        (
            f"seed{s}",
            learner,
            PolicyState(learner.policy.init(jax.random.PRNGKey(s)), N.normalizer_init(learner.norm_size)),
        )
        for s in range(3)
    ]


def test_a_tiny_boxing_tournament_is_antisymmetric_and_equals_the_reverse_order_play(boxers, tmp_path):
    from jaxmotion.evaluation.bouts import play
    from jaxmotion.evaluation.rollout import programs

    done = []
    with jit_enabled():
        res = T.run_tournament(boxers, bouts=4, seeds=2, steps=16, on_pair=lambda i, j, p: done.append((i, j)))
        # Each pair played once, in the row player's scene; the reverse order, played here, gives
        # each bout's value negated exactly (its partner bout from the same start, sides swapped).
        for i, j in done:
            (_, lr, ts_i), (_, _, ts_j) = boxers[i], boxers[j]
            back = T.play_pair((lr, ts_j), (lr, ts_i), bouts=4, seeds=2, steps=16, deterministic=True)
            fwd = T.play_pair((lr, ts_i), (lr, ts_j), bouts=4, seeds=2, steps=16, deterministic=True)
            swapped = back["value"].reshape(2, 2, 2)[..., ::-1].reshape(2, 4)
            np.testing.assert_array_equal(fwd["value"], -swapped)
            assert res["matrix"][j][i] == pytest.approx(np.mean(back["value"]), abs=1e-9)
            assert res["matrix"][i][j] == pytest.approx(-np.mean(back["value"]), abs=1e-9)
            summary, _ = play(lr, ts_j, (lr, ts_i), bouts=4, steps=16, seed=1)
            assert summary["damage_diff_mean"] == pytest.approx(np.mean(back["value"][1]), abs=1e-9)
    assert done == [(0, 1), (0, 2), (1, 2)]
    assert programs(boxers[0][1], "bouts") == 1  # one compile for the whole tournament
    m = np.asarray(res["matrix"])
    assert np.all(np.isfinite(m)) and np.all(np.isfinite(np.asarray(res["matrix_ci95"])))
    np.testing.assert_array_equal(m, -m.T)
    np.testing.assert_array_equal(np.diag(m), 0.0)
    assert any(p["falls"]["row"] + p["falls"]["column"] + abs(p["mean"]) > 0 for p in res["pairs"])
    assert (res["bouts"], res["seeds"], res["steps"], res["mode"]) == (4, 2, 16, "deterministic")
    assert sorted(res["rating"]["ranking"]) == ["seed0", "seed1", "seed2"]
    assert abs(sum(res["rating"]["elo"].values())) < 1e-6
    # The outputs.
    doc = json.loads(T.write_json(res, tmp_path / "t" / "tournament.json").read_text())
    assert doc["matrix"] == res["matrix"] and doc["players"] == ["seed0", "seed1", "seed2"]
    png = T.heat_map(res, tmp_path / "t" / "tournament.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_players_that_cannot_meet_are_refused(boxers):
    with pytest.raises(T.TournamentError, match="at least 2"):
        T.run_tournament(boxers[:1], bouts=2)
    with pytest.raises(T.TournamentError, match="even"):
        T.run_tournament(boxers, bouts=3)
    with pytest.raises(T.TournamentError, match="named twice"):
        T.check_players([boxers[0], boxers[0]])


# --------------------------------------------------------------------------- the command line


def _run_folder(tmp_path, experiment: str):
    """A run folder with only the config of ``experiment`` (enough to be refused)."""
    from jaxmotion.config.experiments import load_experiment
    from jaxmotion.training import checkpoint as ckpt

    run = tmp_path / experiment.split("/")[0]
    ckpt.write_config(run, experiment, load_experiment(experiment))
    return run


@pytest.mark.parametrize(
    "argv,message",
    [
        (["A", "B", "--bouts", "3"], "--bouts=3: must be even"),
        (["A", "--bouts", "4"], "at least 2 players"),
        (["A", "A", "--bouts", "4"], "given twice"),
        (["nowhere", "B", "--bouts", "4"], "nowhere"),
        ([str(REPO / "pretrained" / "chest_open+squat_cpu"), "--untrained", "--bouts", "4"], "single-player run"),
        (["boxing", "fencing", "--bouts", "4"], "mixed sports"),
    ],
)
def test_bad_input_is_one_error_line_and_exit_2(argv, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _run_folder(tmp_path, "boxing/selfplay")
    _run_folder(tmp_path, "fencing/selfplay")
    (tmp_path / "B").mkdir()
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0], err


def test_the_module_runs_and_refuses_bad_input_without_a_traceback():
    p = subprocess.run(
        [sys.executable, "-m", "jaxmotion.tournament", "a", "b", "--bouts", "5"],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
    )
    assert p.returncode == 2 and p.stderr.strip().splitlines() == [
        "error: --bouts=5: must be even (each pair of bouts swaps the players' sides)"
    ]
