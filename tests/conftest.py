"""Shared test helpers. The suite runs with JAX_DISABLE_JIT=1; tests that step MJX physics
re-enable compilation for their own scope (an un-jitted mjx.step takes seconds)."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import jax
import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ["JAXMOTION_DATA"]) if os.environ.get("JAXMOTION_DATA") else REPO.parent / "shared" / "motions"


def train_scoring_last(run, ts, chunks: int, score, last: int = 3):
    """Runs ``chunks`` compiled training chunks (``run(ts) -> (ts, metrics)``) and scores the
    policy after each of the last ``last``: ``(ts, [score(ts), ...])``. A short RL run is chaotic
    from chunk to chunk, so the learning tests judge these scores' mean, not one snapshot."""
    scores = []
    for i in range(chunks):
        ts, _ = run(ts)
        if i >= chunks - last:
            scores.append(score(ts))
    return ts, scores


@contextlib.contextmanager
def jit_enabled():
    """Compile inside this block even under JAX_DISABLE_JIT=1."""
    with jax.disable_jit(False):
        yield


@pytest.fixture(scope="session")
def data_dir() -> Path:
    if not DATA.is_dir():
        pytest.skip(f"shared motion data not found at {DATA} (set JAXMOTION_DATA)")
    return DATA
