"""Learning curves from ``metrics.jsonl``: one run's dashboard, or several runs overlaid.

``plot_run(run_dir)`` writes PNGs into the run folder (x axis: samples): ``plot_overview.png``
with every panel, and one ``plot_<panel>.png`` per panel:

* ``returns``: ``return/<k>`` per objective (named after the body groups when the run is
  multi-objective),
* ``disc_rewards``: ``reward/<group>``,
* ``disc_losses``: ``disc/<group>/loss``,
* ``ppo_losses``: ``ppo/policy_loss`` and ``ppo/value_loss``,
* ``popart``: ``popart/mean/<k>`` and ``popart/std/<k>`` per critic head,
* ``throughput``: ``steps_per_s``; ``terminations``: ``env/terminated``,
* ``imitation_error``: ``eval/<group>/dtw_error_m`` (or ``..._mean``) when such keys exist.

``python -m jaxmotion.plot RUN [RUN ...] [--out FILE] [--labels ...] [--keys ...]`` overlays
runs. A RUN may be a run folder or a folder of run folders (e.g. ``runs/<experiment>``). Runs whose
``config.json`` differs only in ``seed`` (and ``resume``) form one curve: the mean over seeds
with a ±1 std band, interpolated onto the samples they share, as in the Composite Motion paper's
ablation figure (multi-objective vs summed rewards vs no PopArt). Curves are labelled by the
config fields that tell them apart (e.g. ``multi_objective=False``) unless ``--labels`` names them
(one label per curve, in order of first appearance). ``--keys`` takes metric names or glob
patterns (default: ``reward/*`` and any ``eval/*/dtw_error_m*``). With a single run folder and
neither ``--out`` nor ``--keys``, it writes that run's PNGs as ``plot_run`` does.

``--reach 'KEY>=VALUE' ['KEY<=VALUE' ...]`` measures sample efficiency: for each curve (the
smoothed mean over its seeds) the samples at which it first reaches VALUE, interpolated between
logged points, and their ratio to the first curve's (e.g. scratch vs incremental training, paper
Fig. 11); printed as a table, and drawn as a dashed line on the KEY panel.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import re
import sys
from pathlib import Path
from collections.abc import Iterable, Sequence

import numpy as np

_IGNORED_CONFIG = ("seed", "resume")
_BOOKKEEPING = ("iterations", "chunk", "checkpoint_every", "eval_episodes")


def _mpl():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


# ---- reading -----------------------------------------------------------------------------------
def read_metrics(run_dir: str | Path) -> list[dict]:
    """The rows of ``run_dir/metrics.jsonl`` (unreadable lines, e.g. a half-written last line of
    a run in progress, are skipped; a repeated iteration keeps its last row), by iteration."""
    path = Path(run_dir) / "metrics.jsonl"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no metrics.jsonl (is {run_dir} a run folder?)")
    rows: dict = {}
    for i, line in enumerate(path.read_text().splitlines()):
        line = line.strip()
        if not line:
            continue
        try:
            d = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(d, dict):
            rows[d.get("iteration", i)] = d
    return [rows[k] for k in sorted(rows, key=lambda k: (isinstance(k, str), k))]


def read_config(run_dir: str | Path) -> dict:
    """``config.json`` of a run as a dict (``{}`` if absent)."""
    p = Path(run_dir) / "config.json"
    return json.loads(p.read_text()) if p.is_file() else {}


def series(rows: Sequence[dict], key: str, x_key: str = "samples") -> tuple[np.ndarray, np.ndarray]:
    """(x, y) float arrays of the rows that have a finite number under ``key``, sorted by x
    (``x_key`` falls back to ``iteration`` when a row lacks it)."""
    xs, ys = [], []
    for i, r in enumerate(rows):
        v = r.get(key)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
            xs.append(float(r.get(x_key, r.get("iteration", i))))
            ys.append(float(v))
    x, y = np.asarray(xs), np.asarray(ys)
    o = np.argsort(x, kind="stable")
    return x[o], y[o]


def smooth(y: np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average over ``window`` points (shorter at the start)."""
    if window <= 1 or len(y) < 2:
        return y
    c = np.cumsum(np.insert(y, 0, 0.0))
    n = np.arange(1, len(y) + 1)
    lo = np.maximum(n - window, 0)
    return (c[n] - c[lo]) / (n - lo)


def _auto_window(n: int) -> int:
    return max(1, n // 50)


# ---- one run -----------------------------------------------------------------------------------
def objective_names(cfg: dict) -> list[str]:
    """Names of the critic heads/objectives of a run config (groups in order, or ['sum'])."""
    c = cfg.get("config", cfg)
    groups = [g.get("name", str(i)) for i, g in enumerate(c.get("env", {}).get("groups", []))]
    if not c.get("ppo", {}).get("multi_objective", True):
        return ["sum"]
    return groups


def _keys(rows: Sequence[dict], pattern: str) -> list[str]:
    rx = re.compile(pattern)
    seen: dict[str, None] = {}
    for r in rows:
        for k in r:
            if rx.fullmatch(k):
                seen.setdefault(k, None)
    return sorted(seen, key=lambda k: [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", k)])


def run_panels(rows: Sequence[dict], cfg: dict) -> list[tuple[str, str, list[tuple[str, str]]]]:
    """(file stem, title, [(key, legend label)]) of the panels a run has data for."""
    names = objective_names(cfg)

    def head(k: str) -> str:
        i = k.rsplit("/", 1)[-1]
        return f"{i} ({names[int(i)]})" if i.isdigit() and int(i) < len(names) else i

    groups = [g.get("name") for g in cfg.get("config", cfg).get("env", {}).get("groups", [])]

    def by_group(keys: list[str]) -> list[str]:  # config order of the groups, then the rest
        rank = lambda k: groups.index(k.split("/")[1]) if k.split("/")[1] in groups else len(groups)
        return sorted(keys, key=rank)

    panels = [
        ("returns", "return per objective", [(k, head(k)) for k in _keys(rows, r"return/.+")]),
        (
            "disc_rewards",
            "discriminator reward per group",
            [(k, k.split("/", 1)[1]) for k in by_group(_keys(rows, r"reward/.+"))],
        ),
        (
            "disc_losses",
            "discriminator loss per group",
            [(k, k.split("/")[1]) for k in by_group(_keys(rows, r"disc/[^/]+/loss"))],
        ),
        ("ppo_losses", "PPO losses", [(k, k.split("/", 1)[1]) for k in _keys(rows, r"ppo/(policy|value)_loss")]),
        (
            "popart",
            "PopArt statistics per head",
            [(k, f"{k.split('/')[1]} {head(k)}") for k in _keys(rows, r"popart/(mean|std)/.+")],
        ),
        ("throughput", "throughput (steps_per_s)", [(k, k) for k in _keys(rows, r"steps_per_s")]),
        ("terminations", "early terminations (env/terminated)", [(k, k) for k in _keys(rows, r"env/terminated")]),
        (
            "imitation_error",
            "DTW imitation error per group (m)",
            [(k, k.split("/")[1]) for k in by_group(_keys(rows, r"eval/[^/]+/dtw_error_m(_mean)?"))],
        ),
    ]
    return [p for p in panels if p[2]]


def _draw_run_panel(ax, rows, title, keys, window):
    for key, label in keys:
        x, y = series(rows, key)
        if not len(x):
            continue
        w = _auto_window(len(y)) if window is None else window
        if w > 1:
            (line,) = ax.plot(x, smooth(y, w), label=label, lw=1.5)
            ax.plot(x, y, color=line.get_color(), alpha=0.25, lw=0.8)
        else:
            ax.plot(x, y, label=label, lw=1.5, marker="." if len(x) < 30 else None)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("samples")
    ax.grid(alpha=0.3)
    if len(keys) > 1:
        ax.legend(fontsize=7)


def plot_run(run_dir: str | Path, out_dir: str | Path | None = None, smooth_window: int | None = None) -> list[Path]:
    """Writes the run's learning-curve PNGs (see the module docstring) and returns their paths.

    Args:
        run_dir: a run folder with ``metrics.jsonl`` (and ``config.json`` for objective names).
        out_dir: where to write (default: the run folder).
        smooth_window: moving-average window in iterations (None: about 1/50 of the run; the
            raw curve is drawn faintly behind a smoothed one).
    """
    plt = _mpl()
    run_dir = Path(run_dir)
    out_dir = Path(out_dir) if out_dir is not None else run_dir
    out_dir.mkdir(parents=True, exist_ok=True)
    rows, cfg = read_metrics(run_dir), read_config(run_dir)
    panels = run_panels(rows, cfg)
    paths = []
    if not panels:
        return paths
    name = cfg.get("experiment", run_dir.name)
    for stem, title, keys in panels:
        fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
        _draw_run_panel(ax, rows, title, keys, smooth_window)
        fig.suptitle(f"{name} — {run_dir.name}", fontsize=9)
        fig.tight_layout()
        p = out_dir / f"plot_{stem}.png"
        fig.savefig(p)
        plt.close(fig)
        paths.append(p)
    cols = 3
    nrows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(5 * cols, 3.6 * nrows), dpi=90, squeeze=False)
    for ax, (_, title, keys) in zip(axes.flat, panels):
        _draw_run_panel(ax, rows, title, keys, smooth_window)
    for ax in list(axes.flat)[len(panels) :]:
        ax.axis("off")
    fig.suptitle(f"{name} — {run_dir}", fontsize=10)
    fig.tight_layout()
    p = out_dir / "plot_overview.png"
    fig.savefig(p)
    plt.close(fig)
    return paths + [p]


def learning_curves(run: Path) -> None:
    """Writes the run's learning-curve PNGs (``plot_run``) and says where, or why there are none."""
    try:
        print(f"plots: {len(plot_run(run))} PNGs in {run}")
    except FileNotFoundError as e:
        print(f"plots skipped: {e}", file=sys.stderr)


def plot_meta_weights(learner, ro: dict, out: str | Path, episode: int = 0) -> Path:
    """Incremental learning: the meta-action weights w (paper Figs. 7-8). Left, w of every DoF
    over one episode (rows grouped by body, 0.5 the neutral colour); right, the histogram of w
    over every step of every episode, one curve per body group of the run."""
    plt = _mpl()
    w, stepped = np.asarray(ro["meta_w"]), np.asarray(ro["stepped"])
    ch = learner.env.character
    t = np.flatnonzero(stepped[:, episode])
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 6), dpi=100, gridspec_kw={"width_ratios": [2.2, 1]})
    im = ax.imshow(
        w[t, episode].T,
        aspect="auto",
        cmap="coolwarm",
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
        extent=(0, len(t) * learner.env.dt, len(ch.joint_names) - 0.5, -0.5),
    )
    ax.set_yticks(range(len(ch.joint_names)), ch.joint_names, fontsize=6)
    ax.set_xlabel("time (s)")
    ax.set_title(f"w per DoF, episode {episode} (1: follow the meta policy)")
    fig.colorbar(im, ax=ax, fraction=0.03)
    bins = np.linspace(0, 1, 41)
    for g, (links, _) in zip(learner.cfg.env.groups, learner.env.group_idx):
        dofs = [d for b in np.asarray(links) for d in ch.body_joints(int(b))]
        if dofs:
            ax2.hist(w[stepped][:, dofs].ravel(), bins=bins, histtype="step", density=True, label=g.name)
    ax2.set_xlabel("w")
    ax2.set_title("w over all steps, by body group")
    ax2.legend()
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out)
    plt.close(fig)
    return out


# ---- several runs ------------------------------------------------------------------------------
def find_runs(paths: Iterable[str | Path]) -> list[Path]:
    """Run folders (those with ``metrics.jsonl``) named directly or found below the paths."""
    out: list[Path] = []
    for p in map(Path, paths):
        if (p / "metrics.jsonl").is_file():
            out.append(p)
            continue
        found = sorted(q.parent for q in p.rglob("metrics.jsonl")) if p.is_dir() else []
        if not found:
            raise FileNotFoundError(f"{p}: not a run folder and no run folders below it")
        out += found
    seen: dict[Path, None] = {}
    for p in out:
        seen.setdefault(p.resolve(), None)
    return list(seen)


def _flat(d, prefix=""):
    out = {}
    if isinstance(d, dict):
        for k, v in d.items():
            out.update(_flat(v, f"{prefix}{k}."))
    else:
        out[prefix[:-1]] = json.dumps(d, sort_keys=True)
    return out


def config_key(cfg: dict) -> str:
    """The config of a run without the fields that seeds of one setting may differ in."""
    c = dict(cfg.get("config", cfg))
    for k in _IGNORED_CONFIG:
        c.pop(k, None)
    return json.dumps(c, sort_keys=True)


def group_runs(runs: Sequence[Path]) -> list[tuple[str, list[Path]]]:
    """Runs grouped by ``config_key`` (order of first appearance), each with an automatic label:
    the config fields that differ between the groups (or the experiment name)."""
    groups: dict[str, list[Path]] = {}
    cfgs: dict[str, dict] = {}
    for r in runs:
        cfg = read_config(r)
        k = config_key(cfg)
        groups.setdefault(k, []).append(r)
        cfgs.setdefault(k, cfg)
    flats = {k: _flat(json.loads(k)) for k in groups}
    all_fields = sorted(set().union(*flats.values())) if flats else []
    differing = [f for f in all_fields if len({fl.get(f) for fl in flats.values()}) > 1]
    # Bookkeeping fields name a curve only when nothing else tells the curves apart.
    algo = [f for f in differing if f not in _BOOKKEEPING]
    differing = algo or differing
    exps = {cfgs[k].get("experiment", "") for k in groups}
    out = []
    for k, rs in groups.items():
        parts = []
        if len(exps) > 1:
            parts.append(cfgs[k].get("experiment", "?"))
        for f in differing[:4]:
            v = flats[k].get(f)
            parts.append(f"{f.split('.')[-1]}={'-' if v is None else json.loads(v)}")
        if len(differing) > 4:
            parts.append("…")
        label = ", ".join(parts) or cfgs[k].get("experiment") or rs[0].parent.name
        out.append((label, rs))
    return out


DEFAULT_KEYS = ("reward/*", "eval/*/dtw_error_m", "eval/*/dtw_error_m_mean")


def expand_keys(patterns: Sequence[str], rows_list: Sequence[Sequence[dict]]) -> list[str]:
    """Metric names matching the patterns (exact names or fnmatch globs) in any of the runs."""
    names = sorted({k for rows in rows_list for r in rows for k in r if k not in ("iteration", "samples")})
    out: list[str] = []
    for p in patterns:
        for k in names if any(c in p for c in "*?[") else [p]:
            if fnmatch.fnmatchcase(k, p) and k not in out and any(k in r for rows in rows_list for r in rows):
                out.append(k)
    return out


def mean_std_curve(
    curves: Sequence[tuple[np.ndarray, np.ndarray]], num: int = 200
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean and std of several (x, y) curves on the x range they all cover (linear interp.).

    With one curve it is returned as is (std 0)."""
    curves = [(x, y) for x, y in curves if len(x)]
    if not curves:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    if len(curves) == 1:
        x, y = curves[0]
        return x, y, np.zeros_like(y)
    lo = max(x[0] for x, _ in curves)
    hi = min(x[-1] for x, _ in curves)
    if hi < lo:  # no common range: use the union, each run held at its ends
        lo, hi = min(x[0] for x, _ in curves), max(x[-1] for x, _ in curves)
    xs = np.unique(np.concatenate([x[(x >= lo) & (x <= hi)] for x, _ in curves]))
    if len(xs) > num:
        xs = np.linspace(lo, hi, num)
    if len(xs) == 0:
        xs = np.array([lo])
    ys = np.stack([np.interp(xs, x, y) for x, y in curves])
    return xs, ys.mean(0), ys.std(0)


def parse_reach(spec: str) -> tuple[str, float, bool]:
    """'KEY>=VALUE' or 'KEY<=VALUE' -> (key, value, rising)."""
    m = re.fullmatch(r"\s*(\S+?)\s*(>=|<=)\s*([-+0-9.eE]+)\s*", spec)
    if not m:
        raise ValueError(f"--reach wants 'KEY>=VALUE' or 'KEY<=VALUE', got {spec!r}")
    return m.group(1), float(m.group(3)), m.group(2) == ">="


def samples_to_reach(x: np.ndarray, y: np.ndarray, value: float, rising: bool = True) -> float:
    """The first x at which ``y`` reaches ``value`` (from below if ``rising``, else from above),
    linearly interpolated between the two points around the crossing; nan if it never does."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    ok = (y >= value) if rising else (y <= value)
    if not ok.any():
        return float("nan")
    i = int(np.argmax(ok))
    if i == 0 or y[i] == y[i - 1]:
        return float(x[i])
    return float(x[i - 1] + (value - y[i - 1]) * (x[i] - x[i - 1]) / (y[i] - y[i - 1]))


def plot_compare(
    runs: Sequence[str | Path],
    out: str | Path,
    labels: Sequence[str] | None = None,
    keys: Sequence[str] | None = None,
    smooth_window: int | None = None,
    title: str | None = None,
    reach: Sequence[str] = (),
) -> tuple[Path, list[dict]]:
    """Overlays runs (seeds of one config grouped into mean ± std) for each metric; see the
    module docstring. Returns the written PNG path and, per ``reach`` spec and curve, a row
    {key, value, curve, samples, ratio} (ratio: samples over the first curve's)."""
    plt = _mpl()
    run_dirs = find_runs(runs)
    grouped = group_runs(run_dirs)
    if labels:
        if len(labels) != len(grouped):
            raise ValueError(
                f"{len(labels)} labels for {len(grouped)} curves: "
                + "; ".join(f"{label} ({len(rs)} runs)" for label, rs in grouped)
            )
        grouped = [(lab, rs) for lab, (_, rs) in zip(labels, grouped)]
    rows = {r: read_metrics(r) for r in run_dirs}
    goals = [parse_reach(r) for r in reach]
    patterns = list(keys or DEFAULT_KEYS) + [k for k, _, _ in goals]
    keys = list(dict.fromkeys(expand_keys(patterns, list(rows.values()))))
    if not keys:
        raise ValueError(f"no metric matches {patterns} in these runs")
    cols = min(3, len(keys))
    nrows = math.ceil(len(keys) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(5.2 * cols, 3.8 * nrows), dpi=100, squeeze=False)
    reached: list[dict] = []
    for ax, key in zip(axes.flat, keys):
        for i, (label, rs) in enumerate(grouped):
            curves = []
            for r in rs:
                x, y = series(rows[r], key)
                w = _auto_window(len(y)) if smooth_window is None else smooth_window
                curves.append((x, smooth(y, w)))
            x, m, s = mean_std_curve(curves)
            if not len(x):
                continue
            n = sum(1 for c in curves if len(c[0]))
            color = f"C{i % 10}"
            ax.plot(x, m, color=color, lw=1.6, label=f"{label} (n={n})" if n > 1 else label)
            if n > 1:
                ax.fill_between(x, m - s, m + s, color=color, alpha=0.2, lw=0)
            for k, value, rising in goals:
                if k == key:
                    reached.append(dict(key=k, value=value, curve=label, samples=samples_to_reach(x, m, value, rising)))
        for k, value, _ in goals:
            if k == key:
                ax.axhline(value, color="k", ls="--", lw=0.8)
        ax.set_title(key, fontsize=10)
        ax.set_xlabel("samples")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(keys) :]:
        ax.axis("off")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    for row in reached:
        first = next(r["samples"] for r in reached if r["key"] == row["key"] and r["value"] == row["value"])
        row["ratio"] = row["samples"] / first if first and math.isfinite(first) else float("nan")
    return out, reached


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m jaxmotion.plot", description=__doc__.split("\n")[0])
    p.add_argument("runs", nargs="+", type=Path, help="run folders, or folders of run folders")
    p.add_argument("--out", type=Path, default=None, help="overlay PNG (default: compare.png)")
    p.add_argument("--labels", nargs="+", default=None, help="one label per curve (seed group)")
    p.add_argument(
        "--keys", nargs="+", default=None, help="metric names or globs (default: reward/*, eval/*/dtw_error_m*)"
    )
    p.add_argument("--smooth", type=int, default=None, help="moving-average window in iterations (default: auto)")
    p.add_argument("--title", default=None)
    p.add_argument(
        "--reach",
        nargs="+",
        default=(),
        metavar="'KEY>=VALUE'",
        help="samples at which each curve first reaches VALUE of KEY (>= rising, <= falling)",
    )
    args = p.parse_args(argv)
    try:
        runs = find_runs(args.runs)
        if len(runs) == 1 and args.out is None and args.keys is None and not args.reach:
            for path in plot_run(runs[0], smooth_window=args.smooth):
                print(path)
            return 0
        out, reached = plot_compare(
            runs, args.out or Path("compare.png"), args.labels, args.keys, args.smooth, args.title, args.reach
        )
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for label, rs in group_runs(runs) if not args.labels else []:
        print(f"{label}: {len(rs)} run(s)")
    for r in reached:
        print(
            f"{r['key']} reaches {r['value']:g}: {r['curve']}: "
            + (
                f"{r['samples']:,.0f} samples (x{r['ratio']:.2f} of the first curve)"
                if math.isfinite(r["samples"])
                else "not reached"
            )
        )
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
