"""``python -m jaxmotion.play RUN [RUN ...]``: drive trained policies in MuJoCo's interactive viewer.

The runs' policies act on one character, deterministically, in real time (paper Fig. 9: policy
switching). They must share observation and action sizes (eval's ``--switch`` asks the same).

Keys (GLFW codes, read by ``mujoco.viewer``'s key callback):

* ``1`` ... ``9``: the acting policy (the runs in the order given). Only the acting parameters
  change; the character's state carries on.
* arrow keys: move the task's target 0.5 m in the world x/y plane (location and aim tasks; for
  the heading task up/down change the speed along the heading);
* PageUp / PageDown: turn the goal direction by +-15 degrees (heading, aim);
* Enter: restart from a new reference state.

The episode time limit does not apply while playing; a fall restarts the character. Tasks expose
what the keys change through ``Task.steer`` (tasks without a steerable goal ignore them). Where
there is no display the command says so and exits with status 2 (``eval --video`` renders
off-screen instead).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.config.errors import cli_errors

KEY_ENTER, KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP, KEY_PAGE_UP, KEY_PAGE_DOWN = 257, 262, 263, 264, 265, 266, 267
MOVE_STEP_M = 0.5
TURN_STEP_RAD = math.radians(15.0)
_MOVES = {KEY_RIGHT: (1.0, 0.0), KEY_LEFT: (-1.0, 0.0), KEY_UP: (0.0, 1.0), KEY_DOWN: (0.0, -1.0)}


class Player:
    """The viewer-free core of ``play``: one character, several policies, key commands.

    ``key(code)`` queues a command; ``tick()`` applies it and advances one control step with the
    acting policy. Everything the viewer shows comes from ``tick``'s return value, so the logic
    is testable without a display."""

    def __init__(self, learner, policies: Sequence, seed: int = 0, actors: Sequence = ()):
        """``actors``: the learner whose networks act for each policy (default: ``learner`` for
        all); runs that share spaces may differ in networks, e.g. one has a meta policy."""
        if not policies:
            raise ValueError("no policies to play")
        actors = tuple(actors) or (learner,) * len(policies)
        if len(actors) != len(policies):
            raise ValueError(f"{len(policies)} policies but {len(actors)} learners to act for them")
        self.learner, self.env = learner, learner.env
        self.policies = tuple(policies)
        self.active = 0
        self.restarts = 0
        self._rng = jax.random.PRNGKey(seed)
        self._move = np.zeros(2, np.float32)
        self._turn = 0.0
        self._restart = False
        env, task = self.env, self.env.task
        limit = env.cfg.episode_steps - 2
        last = lambda s: jax.tree.map(lambda x: x[-1], s.hist)

        def make_step(actor):
            def step(ts, state, move, turn):
                state = state.replace(
                    goal=task.steer(state.goal, last(state), move, turn), steps=jnp.minimum(state.steps, limit)
                )  # no time limit in play
                obs = env.policy_obs(state)
                action = actor.act(ts, obs[None], None)[0][0]
                state, out = env.step(state, action)
                return state, state.data.qpos, task.markers(state.goal, last(state)), out.terminated

            return jax.jit(step)

        steps = {id(a): make_step(a) for a in actors}  # one program per distinct learner
        self._steps = tuple(steps[id(a)] for a in actors)
        self._reset = jax.jit(lambda k: env.reset(k)[0])
        self.state = self._new_state()

    def _new_state(self):
        self._rng, k = jax.random.split(self._rng)
        return self._reset(k)

    def key(self, code: int) -> None:
        """Queues the command of a key (see the module docstring); unknown keys are ignored."""
        if ord("1") <= code <= ord("9") and code - ord("1") < len(self.policies):
            self.active = code - ord("1")
        elif code in _MOVES:
            self._move += MOVE_STEP_M * np.asarray(_MOVES[code], np.float32)
        elif code == KEY_PAGE_UP:
            self._turn += TURN_STEP_RAD
        elif code == KEY_PAGE_DOWN:
            self._turn -= TURN_STEP_RAD
        elif code == KEY_ENTER:
            self._restart = True

    def tick(self) -> tuple[np.ndarray, dict[str, np.ndarray], bool]:
        """One control step: (qpos, markers name -> [2, 3], fell)."""
        if self._restart:
            self.state, self._restart = self._new_state(), False
            self.restarts += 1
        move, turn = jnp.asarray(self._move), jnp.asarray(self._turn, jnp.float32)
        self._move[:], self._turn = 0.0, 0.0
        step = self._steps[self.active]
        self.state, qpos, markers, fell = step(self.policies[self.active], self.state, move, turn)
        if bool(fell):  # the env restarted it; count it
            self.restarts += 1
        return np.asarray(qpos), {k: np.asarray(v) for k, v in markers.items()}, bool(fell)


def display_problem() -> str | None:
    """Why no window can open here, or None."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "no display (neither DISPLAY nor WAYLAND_DISPLAY is set)"
    return None


def _view(player: Player, title: str) -> None:
    import mujoco
    import mujoco.viewer

    from jaxmotion.viz import render
    from jaxmotion.physics import sim

    model = sim.mj_model(player.env.cfg.physics)
    data = mujoco.MjData(model)
    dt = player.env.dt
    with mujoco.viewer.launch_passive(model, data, key_callback=player.key) as viewer:
        print(
            f"{title}: keys 1-{len(player.policies)} switch policy, arrows move the target, "
            "PageUp/PageDown turn, Enter restarts"
        )
        while viewer.is_running():
            t0 = time.perf_counter()
            qpos, markers, _ = player.tick()
            with viewer.lock():
                data.qpos[:] = qpos
                mujoco.mj_forward(model, data)
                viewer.user_scn.ngeom = 0
                render.add_markers(viewer.user_scn, render.marker_list(markers))
            viewer.sync()
            time.sleep(max(0.0, dt - (time.perf_counter() - t0)))


@cli_errors
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m jaxmotion.play", description=__doc__.split("\n")[0])
    p.add_argument("runs", type=Path, nargs="+", help="run folders; keys 1-9 pick the acting one")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    problem = display_problem()
    if problem:
        print(
            f"error: play opens an interactive window, but there is {problem}. "
            "Use `python -m jaxmotion.eval RUN --video out.mp4` to render off-screen.",
            file=sys.stderr,
        )
        return 2
    from jaxmotion.training.runs import load_run, spaces_mismatch

    try:
        loaded = [load_run(r) for r in args.runs]
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    learner = loaded[0][2]
    if learner.env.cfg.players != 1:
        print("error: play drives one character; two-player runs are shown by eval --video / --html", file=sys.stderr)
        return 2
    problem = spaces_mismatch([(r, o[2]) for r, o in zip(args.runs, loaded)])
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    player = Player(learner, [ts for *_, ts in loaded], seed=args.seed, actors=[o[2] for o in loaded])
    try:
        _view(player, " | ".join(e for e, *_ in loaded))
    except Exception as e:  # GL / window-system failures: one clear line, not a traceback
        print(f"error: could not open MuJoCo's viewer: {type(e).__name__}: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
