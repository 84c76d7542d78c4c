"""Time to result: the samples and wall time a run took to reach given evaluation errors.

Throughput alone hides a speed change that costs learning; the samples and the wall time to a
result show both. A run's ``metrics.jsonl`` holds its periodic evaluations (``eval_every``; e.g.
``eval/upper/dtw_error_m``) and, per row, the training's wall time so far (``wall_s``; runs logged
before it existed: the chunks' compute time, from ``steps_per_s``, evaluations and checkpoints
left out). The result is the first evaluation at which every target holds, so it is as coarse as
the run's ``eval_every``.

``python -m jaxmotion.bench --time-to-result RUN [--targets upper=0.10,lower=0.09]`` prints it;
the default targets are paper Table 1's row 3 (chest open + squat), DTW errors in metres.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

TABLE1 = {"upper": 0.10, "lower": 0.09}
"""Paper Table 1, row 3 (Xu et al. 2023): DTW imitation error (m) per body group."""


def parse_targets(text: str) -> dict[str, float]:
    """``'upper=0.10,lower=0.09'`` -> ``{'upper': 0.1, 'lower': 0.09}`` (ValueError if malformed)."""
    out = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"target {item!r} is not group=error (e.g. upper=0.10)")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"target {item!r}: {value!r} is not a number") from None
    if not out:
        raise ValueError("no targets given (e.g. upper=0.10,lower=0.09)")
    return out


def read_rows(run_dir: Path) -> list[dict]:
    """The rows of ``run_dir/metrics.jsonl`` in order (FileNotFoundError without one); an
    unreadable line (the half-written last line of a run in progress) is skipped. Unlike
    ``viz.plot.read_metrics`` an evaluation's row stays beside its iteration's training row."""
    rows = []
    with open(Path(run_dir) / "metrics.jsonl") as f:
        for line in f:
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue
            if isinstance(row, dict):
                rows.append(row)
    return rows


def wall_times(rows: list[dict]) -> list[float]:
    """Seconds of training up to each row: its ``wall_s`` (or the last one before it), or for a
    log without any the sum of the chunks' compute times (a chunk's rows share one
    ``steps_per_s``; its time is its samples over it)."""
    out, t, prev = [], 0.0, 0
    if any("wall_s" in r for r in rows):  # an evaluation's row has the time of the row before
        for r in rows:
            t = float(r.get("wall_s", t))
            out.append(t)
        return out
    for r in rows:
        if "steps_per_s" in r:  # a training row (an evaluation's row repeats the samples)
            sps = float(r["steps_per_s"])
            t += (r["samples"] - prev) / sps if sps > 0 else math.nan
            prev = r["samples"]
        out.append(t)
    return out


def time_to_result(rows: list[dict], targets: dict[str, float], metric: str = "dtw_error_m") -> dict:
    """The first row whose ``eval/<group>/<metric>`` is at most the target for every group.

    Returns ``reached`` (bool) and, when reached, ``iteration``, ``samples``, ``wall_s`` and the
    errors there; always the number of evaluations and the best errors seen."""
    keys = {g: f"eval/{g}/{metric}" for g in targets}
    walls = wall_times(rows)
    evals = [(r, w) for r, w in zip(rows, walls) if all(k in r for k in keys.values())]
    best = {g: min((r[k] for r, _ in evals), default=math.nan) for g, k in keys.items()}
    out = {"targets": targets, "evaluations": len(evals), "best": best, "reached": False}
    for r, w in evals:
        if all(r[keys[g]] <= t for g, t in targets.items()):
            out.update(
                reached=True,
                iteration=r["iteration"],
                samples=r["samples"],
                wall_s=w,
                errors={g: r[k] for g, k in keys.items()},
            )
            break
    return out


def report(run_dir: str, targets_text: str, out: str | None = None) -> int:
    """Prints (and with ``out`` writes as JSON) a run's time to ``targets_text``; 0 if reached,
    1 if not, a ``ConfigError`` (one line) for a folder without a log or malformed targets."""
    from jaxmotion.config.errors import ConfigError

    try:
        targets = parse_targets(targets_text)
        rows = read_rows(Path(run_dir))
    except (ValueError, OSError) as e:
        raise ConfigError(f"--time-to-result {run_dir}: {e}") from None
    res = {"run": str(run_dir), **time_to_result(rows, targets)}
    goal = " and ".join(f"{g} <= {t:g} m" for g, t in targets.items())
    if res["reached"]:
        print(
            f"{run_dir}: {goal} first at iteration {res['iteration']} ({res['samples'] / 1e6:.2f}M samples, "
            f"{res['wall_s'] / 60:.1f} min of training; {res['evaluations']} evaluations in the log)"
        )
    else:
        best = ", ".join(f"{g} {v:.3f} m" for g, v in res["best"].items())
        print(f"{run_dir}: {goal} not reached in {res['evaluations']} evaluations (best: {best})")
    if out:
        with open(out, "w") as f:
            json.dump(res, f, indent=2)
    return 0 if res["reached"] else 1
