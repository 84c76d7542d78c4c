"""Time to result (``evaluation/time_to_result.py``, ``bench --time-to-result``) on hand-made logs."""

from __future__ import annotations

import json

import pytest

from jaxmotion import bench
from jaxmotion.evaluation import time_to_result as T


def _log(with_wall: bool) -> list[dict]:
    """Chunks of 2 iterations x 100 samples at 50 samples/s (4 s per chunk), an evaluation row
    after every second chunk: upper 0.20, 0.09, 0.05; lower 0.30, 0.12, 0.08."""
    rows, wall = [], 0.0
    errors = [(0.20, 0.30), (0.09, 0.12), (0.05, 0.08)]
    for c in range(6):
        for i in range(2):
            it = 2 * c + i + 1
            wall += 2.0 + (1.0 if with_wall and i == 0 and c % 2 == 0 and c else 0.0)  # + evaluation time
            row = {"iteration": it, "samples": 100 * it, "steps_per_s": 50.0}
            if with_wall:
                row["wall_s"] = wall
            rows.append(row)
        if c % 2 == 1:
            up, lo = errors[c // 2]
            rows.append(
                {
                    "iteration": rows[-1]["iteration"],
                    "samples": rows[-1]["samples"],
                    "eval/upper/dtw_error_m": up,
                    "eval/lower/dtw_error_m": lo,
                }
            )
    return rows


def test_parse_targets():
    assert T.parse_targets("upper=0.10, lower=0.09") == {"upper": 0.10, "lower": 0.09}
    for bad in ("upper", "=0.1", "upper=x", ""):
        with pytest.raises(ValueError):
            T.parse_targets(bad)


def test_wall_time_from_chunk_throughput_when_not_logged():
    rows = _log(with_wall=False)
    walls = T.wall_times(rows)
    train = [(r, w) for r, w in zip(rows, walls) if "steps_per_s" in r]
    # 100 samples per iteration at 50 samples/s: 2 s each; an evaluation row adds nothing.
    assert [w for _, w in train] == pytest.approx([2.0 * r["iteration"] for r, _ in train])
    assert walls[rows.index(next(r for r in rows if "eval/upper/dtw_error_m" in r))] == pytest.approx(8.0)


def test_first_evaluation_meeting_every_target():
    res = T.time_to_result(_log(with_wall=True), {"upper": 0.10, "lower": 0.09})
    # The second evaluation meets upper only; the third meets both: iteration 12, 1200 samples.
    assert res["reached"] and res["iteration"] == 12 and res["samples"] == 1200
    assert res["errors"] == {"upper": 0.05, "lower": 0.08}
    assert res["wall_s"] == pytest.approx(24.0 + 2.0)  # two evaluations' 1 s each, logged in wall_s
    assert res["evaluations"] == 3
    miss = T.time_to_result(_log(with_wall=True), {"upper": 0.01, "lower": 0.09})
    assert not miss["reached"] and miss["best"] == {"upper": 0.05, "lower": 0.08}


def test_bench_cli(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in _log(with_wall=False)))
    out = tmp_path / "ttr.json"
    assert bench.main(["--time-to-result", str(run), "--out", str(out)]) == 0
    assert "first at iteration 12 (0.00M samples, 0.4 min" in capsys.readouterr().out
    assert json.loads(out.read_text())["samples"] == 1200
    # A run in progress: its half-written last line is skipped.
    with open(run / "metrics.jsonl", "a") as f:
        f.write('{"iteration": 13, "samp')
    assert bench.main(["--time-to-result", str(run), "--out", str(out)]) == 0
    assert bench.main(["--time-to-result", str(run), "--targets", "upper=0.01", "--out", str(out)]) == 1
    # A folder without a log and malformed targets: one line, exit 2.
    for argv in (["--time-to-result", str(tmp_path / "none")], ["--time-to-result", str(run), "--targets", "up"]):
        assert bench.main(argv + ["--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: --time-to-result")
