"""The progressive pipeline (``training/progressive.py``): when a stage is frozen, which clips and
which starting point each stage gets, the composer over the frozen stages, and resuming at any
stage. The stages' training is replaced by a recorder that writes what a real stage leaves in its
folder (a checkpoint, mining rows, ``hard_clips.json``), so the order and hand-over are checked
without compiling; the real training a stage runs is ``jaxmotion.train.train``."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from jaxmotion import config as C
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.training import progressive as P
from jaxmotion.training.hparams import ProgressiveConfig
from jaxmotion.training.runs import final_stage

CLIPS = ("a.txt", "b.txt", "c.txt", "d.txt")


def test_a_stage_is_frozen_when_its_success_stops_rising():
    assert not P.plateaued([], 2)
    assert not P.plateaued([0.25, 0.5], 2)  # too few passes to tell
    assert not P.plateaued([0.25, 0.5, 0.5, 0.75], 2)  # the last two beat 0.5
    assert P.plateaued([0.25, 0.5, 0.5, 0.5], 2)  # two passes without a rise
    assert P.plateaued([0.5, 0.75, 0.5, 0.75], 2)  # equal is no rise
    assert P.plateaued([0.25, 1.0], 5)  # every clip tracked


def test_mining_rates_skip_other_rows_and_a_line_cut_short(tmp_path):
    rows = [{"iteration": 10, "x": 1.0}, {"iteration": 10, "mining/success_rate": 0.5}, {"iteration": 20}]
    text = "".join(json.dumps(r) + "\n" for r in rows) + '{"iteration": 30, "mining/succ'
    (tmp_path / "metrics.jsonl").write_text(text)
    assert P.mining_rates(tmp_path) == [0.5]
    assert P.mining_rates(tmp_path / "missing") == []


def _base(**progressive):
    cfg = C.load_experiment("track/pmcp_small")
    pc = dataclasses.replace(cfg.progressive, **progressive)
    return dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, init_motions=CLIPS), progressive=pc)


class Recorder:
    """Stands in for ``jaxmotion.train.train``: writes a finished stage into its folder. Stage i
    (in call order) fails ``fails[i]`` and reports ``rates[i]``; ``stop_in`` interrupts that call
    after its first checkpoint, as a kill would."""

    def __init__(self, fails, rates, stop_in=None):
        self.fails, self.rates, self.stop_in, self.calls = fails, rates, stop_in, []

    def __call__(self, experiment, cfg, run_dir=None, until=None):
        run_dir = Path(run_dir if run_dir is not None else cfg.resume)
        i = len(self.calls)
        self.calls.append((run_dir.name, cfg))
        if not cfg.resume:
            ckpt.write_config(run_dir, experiment, cfg)
        start = P.latest_step(Path(cfg.init_from)) if cfg.init_from else 0
        (run_dir / "checkpoints" / str(start + 10)).mkdir(parents=True, exist_ok=True)
        if i == self.stop_in:
            raise KeyboardInterrupt
        with open(run_dir / "metrics.jsonl", "a") as f:
            for r in self.rates[i]:
                f.write(json.dumps({"iteration": start + 10, "mining/success_rate": r}) + "\n")
        (run_dir / "hard_clips.json").write_text(json.dumps({"failed": list(self.fails[i])}))
        (run_dir / "checkpoints" / str(cfg.iterations)).mkdir(parents=True, exist_ok=True)
        assert until is not None


def test_each_stage_starts_from_its_predecessor_on_the_clips_it_failed(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = _base(primitives=3, stage_iterations=600, composer_iterations=300)
    rec = Recorder(fails=[("b.txt", "c.txt"), ("c.txt",), ("c.txt",), ()], rates=[[0.5], [0.5], [0.0], [0.75]])
    root = P.run_pipeline("track/pmcp_small", cfg, rec, say=lambda s: None)
    names = [n for n, _ in rec.calls]
    assert names == ["primitive_1", "primitive_2", "primitive_3", "composer"]
    p1, p2, p3, comp = (c for _, c in rec.calls)
    assert p1.env.init_motions == CLIPS and p1.init_from == "" and p1.iterations == 600
    assert p2.env.init_motions == ("b.txt", "c.txt") and p2.init_from == str(root / "primitive_1")
    assert p2.iterations == 600 + 600  # counted from where primitive 1 ended
    assert p3.env.init_motions == ("c.txt",) and p3.init_from == str(root / "primitive_2")
    assert comp.primitives == tuple(str(root / n) for n in names[:3]) and comp.env.init_motions == CLIPS
    assert comp.iterations == 300 and not comp.init_from
    for c in (p1, p2, p3, comp):  # the stages are plain runs, and every stage keeps the motion prior's clips
        assert c.progressive == ProgressiveConfig() and c.env.groups == cfg.env.groups
    state = json.loads((root / "pipeline.json").read_text())
    assert state["final"] == "composer" and state["stages"]["primitive_2"]["failed"] == ["c.txt"]
    assert final_stage(root) == root / "composer"


def test_no_stage_without_failed_clips_and_no_composer_over_one_primitive(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rec = Recorder(fails=[()], rates=[[1.0]])
    root = P.run_pipeline("track/pmcp_small", _base(primitives=3), rec, say=lambda s: None)
    assert [n for n, _ in rec.calls] == ["primitive_1"]
    assert final_stage(root) == root / "primitive_1"


def test_a_killed_pipeline_resumes_at_the_stage_it_was_in(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = _base(primitives=2)
    first = Recorder(fails=[("b.txt",), ()], rates=[[0.75], [1.0]], stop_in=1)
    with pytest.raises(KeyboardInterrupt):
        P.run_pipeline("track/pmcp_small", cfg, first, say=lambda s: None)
    (root,) = Path("runs/track/pmcp_small").iterdir()
    assert final_stage(root) == root / "primitive_1"  # a pipeline stands for its last finished stage
    again = Recorder(fails=[(), ()], rates=[[1.0], [0.75]])
    P.run_pipeline("track/pmcp_small", dataclasses.replace(cfg, resume=str(root)), again, say=lambda s: None)
    assert [n for n, _ in again.calls] == ["primitive_2", "composer"]  # primitive 1 is not trained again
    assert again.calls[0][1].resume == str(root / "primitive_2")  # continued from its checkpoint
    assert again.calls[1][1].primitives == (str(root / "primitive_1"), str(root / "primitive_2"))


def test_the_recovery_primitive_comes_after_the_imitation_ones_and_joins_the_composer(tmp_path, monkeypatch):
    """PHC's order: imitation primitives with recovery off, the recovery primitive from the last
    of them on its own clips with recovery on, then a composer over all with recovery on."""
    monkeypatch.chdir(tmp_path)
    on = lambda c: c.env.task.track.recovery.enabled
    cfg = P.with_recovery(
        _base(primitives=2, stage_iterations=600, recovery_iterations=200, recovery_clips=("a.txt",)), True
    )
    rec = Recorder(fails=[("b.txt",), ("b.txt",), (), ()], rates=[[0.75], [0.75], [0.5], [0.75]])
    root = P.run_pipeline("track/pmcp_small", cfg, rec, say=lambda s: None)
    assert [n for n, _ in rec.calls] == ["primitive_1", "primitive_2", "recovery", "composer"]
    p1, p2, recov, comp = (c for _, c in rec.calls)
    assert not on(p1) and not on(p2) and on(recov) and on(comp)
    assert recov.env.init_motions == ("a.txt",) and recov.init_from == str(root / "primitive_2")
    assert recov.iterations == 1200 + 200  # counted from where primitive 2 ended
    assert comp.primitives == tuple(str(root / n) for n in ("primitive_1", "primitive_2", "recovery"))
    assert json.loads((root / "pipeline.json").read_text())["stages"]["recovery"]["status"] == "done"
    again = Recorder(fails=[], rates=[])
    P.run_pipeline("track/pmcp_small", dataclasses.replace(cfg, resume=str(root)), again, say=lambda s: None)
    assert again.calls == []  # every stage done: nothing is trained again


def test_a_pipeline_needs_mining_and_whole_chunks():
    cfg = _base(primitives=2, stage_iterations=605)
    with pytest.raises(C.ConfigError, match="progressive.stage_iterations"):
        P.run_pipeline("track/pmcp_small", cfg, None)
    with pytest.raises(C.ConfigError, match="hard-negative mining"):
        P.run_pipeline("track/pmcp_small", dataclasses.replace(_base(primitives=2), hard_negatives_every=0), None)


def test_a_pipeline_with_no_finished_stage_is_one_line(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(KeyboardInterrupt):
        P.run_pipeline("track/pmcp_small", _base(primitives=2), Recorder([()], [[1.0]], stop_in=0), say=lambda s: None)
    (root,) = Path("runs/track/pmcp_small").iterdir()
    with pytest.raises(ckpt.RunFolderError, match="no finished stage"):
        final_stage(root)
    assert final_stage(tmp_path) == tmp_path  # a folder that is no pipeline stands for itself


@pytest.mark.slow
def test_a_stage_on_fewer_clips_starts_from_its_predecessors_networks(tmp_path):
    """``init_from`` a run of another clip set (a stage on its predecessor's failed clips): every
    network, statistic and the iteration count come from the predecessor, the per-clip mining
    counts are the new run's own."""
    import jax
    import numpy as np

    from conftest import jit_enabled
    from jaxmotion.motion import MotionLib, make_test_clip
    from jaxmotion.training import runs
    from test_track import tiny_tracker
    from test_train import _leaves

    clips = [make_test_clip(20, 30.0, name=f"c{i}") for i in range(2)]
    both, hard = MotionLib.from_clips(clips), MotionLib.from_clips(clips[1:])
    with jit_enabled():
        first = tiny_tracker(both)
        prev = first.init(jax.random.PRNGKey(1))
        prev = prev.replace(iteration=prev.iteration + 30, clip_fails=prev.clip_fails + 1)
        ckpt.write_config(tmp_path / "p1", "x", first.cfg)
        mgr = ckpt.manager(tmp_path / "p1")
        ckpt.save(mgr, 30, prev)
        mgr.close()
        second = tiny_tracker(hard)
        fresh = second.init(jax.random.PRNGKey(2))
        got = runs.init_from(second, fresh, tmp_path / "p1")
    for field in ("policy_params", "critic_params", "disc_params", "obs_norm", "disc_norm", "popart", "opt_state"):
        want = dict(_leaves(getattr(prev, field)))
        for k, x in _leaves(getattr(got, field)):
            np.testing.assert_array_equal(x, want[k], err_msg=f"{field}{k}")
    assert int(got.iteration) == 30
    np.testing.assert_array_equal(got.clip_fails, fresh.clip_fails)  # one clip, its own count
    assert got.clip_fails.shape == (1,)


def test_the_next_stage_gets_the_union_of_the_judged_passes_failures(tmp_path):
    passes = [
        {"iteration": 100, "failed": ["a.txt"]},
        {"iteration": 200, "failed": ["c.txt", "b.txt"]},
        {"iteration": 300, "failed": ["b.txt"]},
    ]
    (tmp_path / "hard_clips.json").write_text(json.dumps({"failed": ["b.txt"], "passes": passes}))
    assert P.failed_clips(tmp_path, 1) == ["b.txt"]
    assert P.failed_clips(tmp_path, 2) == ["c.txt", "b.txt"]
    assert P.failed_clips(tmp_path, 5) == ["a.txt", "c.txt", "b.txt"]
    assert P.failed_clips(tmp_path / "no_pass_yet") == []


def test_a_stage_is_judged_only_after_a_mining_pass(tmp_path):
    """``until`` reads the stage's log after the chunks that mined, not after every chunk."""
    seen = []

    def train(experiment, cfg, run_dir=None, until=None):
        rows = [{"iteration": i, "mining/success_rate": 0.5} for i in (10, 20, 30)]
        (run_dir / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
        end = type("End", (), {})
        for last in ({"iteration": 31}, {"iteration": 30, "mining/success_rate": 0.5}):
            end.last = last
            seen.append(until(end))

    (tmp_path / "stage").mkdir()
    P._train_stage("x", tmp_path / "stage", _base(primitives=2), train, ProgressiveConfig(primitives=2, patience=2))
    assert seen == [False, True]
