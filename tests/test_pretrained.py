"""Shipped policies (``pretrained/<name>/``): each is small, carries a card, evaluates from its folder
alone, and beats its experiment's untrained networks on the same episodes."""

from __future__ import annotations

import re
from pathlib import Path

import jax
import numpy as np
import pytest

from conftest import REPO, jit_enabled
from jaxmotion.evaluation.imitation import rollout_metrics
from jaxmotion.evaluation.rollout import rollout
from jaxmotion.training.runs import load_run

PRETRAINED = REPO / "pretrained"
ENTRIES = sorted(p for p in PRETRAINED.iterdir() if p.is_dir()) if PRETRAINED.is_dir() else []
MAX_BYTES = 10 * 2**20
CARD_FIELDS = ("experiment", "command", "samples", "wall time", "machine", "evaluation")


def _size(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def test_the_table_1_policy_ships():
    assert "chest_open+squat_cpu" in [e.name for e in ENTRIES]


@pytest.mark.parametrize("entry", ENTRIES, ids=[e.name for e in ENTRIES])
def test_entry_is_small_and_has_a_card(entry):
    assert _size(entry) <= MAX_BYTES, f"{entry} is {_size(entry) / 2**20:.1f} MB"
    card = (entry / "README.md").read_text().lower()
    for field in CARD_FIELDS:
        assert re.search(rf"\b{field}\b", card), f"{entry}/README.md has no {field!r}"
    assert (entry / "config.json").exists()
    assert not (entry / "metrics.jsonl").exists(), "the learning log stays out of the entry (size)"


@pytest.mark.physics
@pytest.mark.parametrize("entry", ENTRIES, ids=[e.name for e in ENTRIES])
def test_entry_evaluates_and_beats_untrained_networks(entry, data_dir, monkeypatch):
    """Two deterministic 3-s episodes from the same starts: the shipped policy stays up and
    imitates better, group by group, than its experiment's freshly initialised networks."""
    monkeypatch.setenv("JAXMOTION_DATA", str(data_dir))
    steps = 90
    with jit_enabled():
        _, cfg, learner, ts = load_run(entry)
        trained = rollout_metrics(learner, rollout(learner, ts, episodes=2, steps=steps))
        fresh = learner.init(jax.random.PRNGKey(cfg.seed))
        untrained = rollout_metrics(learner, rollout(learner, fresh, episodes=2, steps=steps))
    assert int(ts.iteration) > 0
    assert trained["fall_rate"] == 0.0 and untrained["fall_rate"] > 0.0
    for g, m in trained["groups"].items():
        assert np.isfinite(m["dtw_error_m_mean"])
        assert m["dtw_error_m_mean"] < untrained["groups"][g]["dtw_error_m_mean"], g
