"""Tests of jaxmotion.plot: one run's PNGs from a synthetic metrics.jsonl, and the multi-run
overlay that groups seeds of one config into mean ± std."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxmotion.viz import plot as P

PNG = b"\x89PNG\r\n\x1a\n"


def _config(seed=0, multi_objective=True, popart=True):
    return {
        "experiment": "toy",
        "config": {
            "env": {"groups": [{"name": "upper"}, {"name": "lower"}]},
            "ppo": {"multi_objective": multi_objective, "popart": popart, "num_envs": 16, "horizon": 8},
            "seed": seed,
            "iterations": 10,
            "resume": "",
        },
    }


def _make_run(path, seed=0, n=12, offset=0.0, eval_keys=True, truncated_tail=False, **cfg):
    path.mkdir(parents=True)
    (path / "config.json").write_text(json.dumps(_config(seed, **cfg)))
    rng = np.random.default_rng(seed)
    lines = []
    for i in range(1, n + 1):
        row = {
            "iteration": i,
            "samples": 128 * i,
            "steps_per_s": 500.0 + rng.normal(),
            "reward/upper": offset + 0.05 * i + 0.01 * rng.normal(),
            "reward/lower": 0.02 * i,
            "return/0": 0.1 * i,
            "return/1": -0.1 * i,
            "disc/upper/loss": 4.0 - 0.1 * i,
            "disc/lower/loss": 4.5 - 0.1 * i,
            "ppo/policy_loss": 0.01,
            "ppo/value_loss": 1.0 / i,
            "popart/mean/0": 0.1,
            "popart/mean/1": 0.2,
            "popart/std/0": 1.0,
            "popart/std/1": 1.1,
            "env/terminated": 0.1,
        }
        if eval_keys and i % 4 == 0:
            row["eval/upper/dtw_error_m"] = 0.3 - 0.01 * i
            row["eval/lower/dtw_error_m"] = 0.4 - 0.01 * i
        lines.append(json.dumps(row))
    text = "\n".join(lines) + "\n"
    if truncated_tail:
        text += '{"iteration": 99, "samp'
    (path / "metrics.jsonl").write_text(text)
    return path


def test_read_metrics_skips_a_half_written_line(tmp_path):
    run = _make_run(tmp_path / "r", truncated_tail=True)
    rows = P.read_metrics(run)
    assert [r["iteration"] for r in rows] == list(range(1, 13))
    x, y = P.series(rows, "eval/upper/dtw_error_m")
    np.testing.assert_array_equal(x, [512, 1024, 1536])
    with pytest.raises(FileNotFoundError, match="metrics.jsonl"):
        P.read_metrics(tmp_path)


def test_plot_run_writes_pngs(tmp_path):
    run = _make_run(tmp_path / "run")
    paths = P.plot_run(run)
    names = {p.name for p in paths}
    for stem in (
        "returns",
        "disc_rewards",
        "disc_losses",
        "ppo_losses",
        "popart",
        "throughput",
        "imitation_error",
        "overview",
    ):
        assert f"plot_{stem}.png" in names
    for p in paths:
        assert p.parent == run and p.stat().st_size > 1000 and p.read_bytes()[:8] == PNG
    # Objectives are named after the groups; without eval keys there is no imitation panel.
    panels = {stem: keys for stem, _, keys in P.run_panels(P.read_metrics(run), P.read_config(run))}
    assert ("return/0", "0 (upper)") in panels["returns"]
    assert [k for k, _ in panels["disc_rewards"]] == ["reward/upper", "reward/lower"]
    run2 = _make_run(tmp_path / "run2", eval_keys=False)
    assert "plot_imitation_error.png" not in {p.name for p in P.plot_run(run2)}


def test_mean_std_curve_on_the_common_range():
    x1, y1 = np.array([0.0, 1, 2, 3]), np.array([0.0, 1, 2, 3])
    x2, y2 = np.array([0.0, 1, 2]), np.array([2.0, 3, 4])
    x, m, s = P.mean_std_curve([(x1, y1), (x2, y2)])
    np.testing.assert_array_equal(x, [0, 1, 2])
    np.testing.assert_allclose(m, [1, 2, 3])
    np.testing.assert_allclose(s, [1, 1, 1])
    x, m, s = P.mean_std_curve([(x1, y1)])
    np.testing.assert_array_equal(m, y1) and np.testing.assert_array_equal(s, 0 * y1)


def test_overlay_groups_seeds(tmp_path):
    for seed in (0, 1, 2):
        _make_run(tmp_path / "ablation" / f"mo_s{seed}", seed=seed, offset=0.1 * seed)
    for seed in (0, 1):
        _make_run(tmp_path / "ablation" / f"sum_s{seed}", seed=seed, multi_objective=False)
    _make_run(tmp_path / "ablation" / "nopopart", popart=False, n=8)
    runs = P.find_runs([tmp_path / "ablation"])
    assert len(runs) == 6
    groups = dict(P.group_runs(runs))  # labelled by the config fields that differ
    assert {lab: len(rs) for lab, rs in groups.items()} == {
        "multi_objective=True, popart=True": 3,
        "multi_objective=False, popart=True": 2,
        "multi_objective=True, popart=False": 1,
    }
    assert sorted(r.name for r in groups["multi_objective=True, popart=True"]) == ["mo_s0", "mo_s1", "mo_s2"]
    out, _ = P.plot_compare(runs, tmp_path / "cmp.png")
    assert out.read_bytes()[:8] == PNG and out.stat().st_size > 1000
    # The CLI: names for the curves, chosen metrics; a wrong number of labels is an error.
    rc = P.main(
        [
            str(tmp_path / "ablation"),
            "--out",
            str(tmp_path / "cli.png"),
            "--labels",
            "MO",
            "w/o PopArt",
            "w/o MO",
            "--keys",
            "reward/*",
            "eval/*/dtw_error_m",
        ]
    )
    assert rc == 0 and (tmp_path / "cli.png").stat().st_size > 1000
    assert P.main([str(tmp_path / "ablation"), "--out", str(tmp_path / "x.png"), "--labels", "a"]) == 2
    assert P.expand_keys(["reward/*", "nope"], [P.read_metrics(runs[0])]) == ["reward/lower", "reward/upper"]


def test_cli_single_run_writes_into_the_run(tmp_path):
    run = _make_run(tmp_path / "one")
    assert P.main([str(run)]) == 0
    assert (run / "plot_overview.png").is_file()


def test_samples_to_reach_by_hand():
    x = np.array([0.0, 100.0, 200.0, 300.0])
    y = np.array([0.0, 0.2, 0.6, 0.5])
    assert P.samples_to_reach(x, y, 0.4) == pytest.approx(150.0)  # between 0.2 at 100 and 0.6 at 200
    assert P.samples_to_reach(x, y, 0.0) == 0.0
    assert np.isnan(P.samples_to_reach(x, y, 0.7))
    assert P.samples_to_reach(x, 1.0 - y, 0.7, rising=False) == pytest.approx(125.0)
    assert P.parse_reach("eval/task/reward_aim>=0.3") == ("eval/task/reward_aim", 0.3, True)
    with pytest.raises(ValueError, match="KEY>=VALUE"):
        P.parse_reach("reward/upper=0.3")


def test_reach_compares_sample_efficiency(tmp_path, capsys):
    """Two configs whose reward/upper rises at 0.05 per iteration (128 samples), one 0.3 ahead:
    it reaches 0.4 at iteration 2 instead of 8, a quarter of the samples."""
    _make_run(tmp_path / "cmp" / "slow", multi_objective=True)
    _make_run(tmp_path / "cmp" / "fast", multi_objective=False, offset=0.3)
    runs = P.find_runs([tmp_path / "cmp"])
    for r in runs:  # noiseless, so the crossing is exact
        rows = [json.loads(line) for line in (r / "metrics.jsonl").read_text().splitlines()]
        off = 0.3 if r.name == "fast" else 0.0
        for row in rows:
            row["reward/upper"] = off + 0.05 * row["iteration"]
        (r / "metrics.jsonl").write_text("\n".join(json.dumps(row) for row in rows) + "\n")
    out, reached = P.plot_compare(
        runs, tmp_path / "r.png", keys=["reward/upper"], smooth_window=1, reach=["reward/upper>=0.4"]
    )
    by = {r["curve"]: r for r in reached}
    slow, fast = by["multi_objective=True"], by["multi_objective=False"]
    assert slow["samples"] == pytest.approx(8 * 128) and fast["samples"] == pytest.approx(2 * 128)
    first, other = (slow, fast) if reached[0]["curve"] == slow["curve"] else (fast, slow)
    assert first["ratio"] == 1.0 and other["ratio"] == pytest.approx(other["samples"] / first["samples"])
    assert (
        P.main(
            [
                str(tmp_path / "cmp"),
                "--out",
                str(tmp_path / "c.png"),
                "--keys",
                "reward/upper",
                "--smooth",
                "1",
                "--reach",
                "reward/upper>=0.4",
            ]
        )
        == 0
    )
    assert "reaches 0.4" in capsys.readouterr().out
