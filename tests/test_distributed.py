"""Training across processes (``--processes N --process-id i --coordinator host:port``).

Two processes on localhost, one CPU device each, train the smoke experiment at test size (the
configuration of ``test_train.tiny_config``); a single process with two host devices trains the
same run. Both run the same per-device program, so the logged metrics agree (measured: bit for
bit). The pair is killed (SIGKILL) once its checkpoint of iteration 2 is on disk and a new pair
resumes it: the run ends with the single process's metrics, each iteration logged once.

Each launch is a fresh set of processes that compile the training chunk (about a minute per
process on a 2-core CPU; the MuJoCo C callback's address is in the program, so JAX's persistent
cache cannot keep it), hence the three launches of the module fixture are the file's cost.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import REPO

ITERATIONS = 6
TINY = [
    "env.episode_steps=6",
    "net.policy_hidden=[16,16]",
    "net.critic_hidden=[16,16]",
    "net.disc_hidden=[16,16]",
    "net.disc_heads=2",
    "ppo.num_envs=4",
    "ppo.horizon=4",
    "ppo.minibatch_size=8",
    "ppo.epochs=1",
    "disc.minibatch_size=8",
    "chunk=1",
    "checkpoint_every=1",
    "seed=0",
]
TIMING_FIELDS = ("steps_per_s",)
LAUNCH_TIMEOUT_S = 600


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def _env(data_dir: Path, devices: int) -> dict:
    env = dict(os.environ, JAX_DISABLE_JIT="0", JAX_PLATFORMS="cpu", JAXMOTION_DATA=str(data_dir))
    env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={devices}"
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    env.pop("JAXMOTION_DISTRIBUTED", None)
    return env


def _launch(args: list[str], cwd: Path, env: dict, processes: int) -> list[subprocess.Popen]:
    """``python -m jaxmotion.train`` with ``args``: one process, or ``processes`` on localhost."""
    cmd = [sys.executable, "-m", "jaxmotion.train", *args]
    if processes == 1:
        cmds = [cmd]
    else:
        where = f"localhost:{_free_port()}"
        cmds = [
            cmd + ["--processes", str(processes), "--process-id", str(i), "--coordinator", where]
            for i in range(processes)
        ]
    return [
        subprocess.Popen(c, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) for c in cmds
    ]


def _finish(procs: list[subprocess.Popen]) -> list[tuple[int, str]]:
    """(return code, output) of each process, killing all of them past the timeout."""
    deadline = time.monotonic() + LAUNCH_TIMEOUT_S
    out = []
    for p in procs:
        try:
            text, _ = p.communicate(timeout=max(1.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            for q in procs:
                q.kill()
            text, _ = p.communicate()
        out.append((p.returncode, text))
    return out


def _kill_after_checkpoint(procs: list[subprocess.Popen], ckpt_dir: Path, step: int) -> None:
    """SIGKILLs every process once checkpoint ``step`` is committed under ``ckpt_dir``."""
    deadline = time.monotonic() + LAUNCH_TIMEOUT_S
    while not (ckpt_dir / str(step)).is_dir():
        if time.monotonic() > deadline or any(p.poll() is not None for p in procs):
            break
        time.sleep(0.05)
    for p in procs:
        p.send_signal(signal.SIGKILL)


def _run_folder(cwd: Path) -> Path:
    (run,) = (cwd / "runs" / "smoke").iterdir()
    return run


def _rows(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines() if line.strip()]


def _steps(run: Path) -> list[int]:
    return sorted(int(p.name) for p in (run / "checkpoints").iterdir() if p.name.isdigit())


@pytest.fixture(scope="module")
def runs(data_dir, tmp_path_factory):
    """One process on two devices, uninterrupted; a pair killed after checkpoint 2; a pair
    resuming it. Returns the folders, outputs and wall times."""
    root = tmp_path_factory.mktemp("distributed")
    args = ["smoke", *TINY, f"iterations={ITERATIONS}"]
    times, outputs = {}, {}

    t = time.perf_counter()
    (root / "one").mkdir()
    outputs["one"] = _finish(_launch(args, root / "one", _env(data_dir, 2), 1))
    times["one process, two devices"] = time.perf_counter() - t
    assert outputs["one"][0][0] == 0, outputs["one"][0][1][-3000:]

    t = time.perf_counter()
    (root / "pair").mkdir()
    procs = _launch(args, root / "pair", _env(data_dir, 1), 2)
    folder = root / "pair" / "runs" / "smoke"
    while not folder.is_dir() or not any(folder.iterdir()):
        assert all(p.poll() is None for p in procs), _finish(procs)
        time.sleep(0.2)
    _kill_after_checkpoint(procs, _run_folder(root / "pair") / "checkpoints", 2)
    outputs["killed"] = _finish(procs)
    times["pair, killed after checkpoint 2"] = time.perf_counter() - t
    run = _run_folder(root / "pair")
    killed_at = _steps(run)

    t = time.perf_counter()
    outputs["resumed"] = _finish(_launch(["smoke", f"resume={run}"], root / "pair", _env(data_dir, 1), 2))
    times["pair, resumed"] = time.perf_counter() - t
    print("\nwall times:", {k: f"{v:.0f}s" for k, v in times.items()})
    return dict(one=_run_folder(root / "one"), pair=run, killed_at=killed_at, outputs=outputs)


@pytest.mark.slow
def test_a_killed_pair_resumes_from_its_checkpoint(runs):
    killed = runs["outputs"]["killed"]
    assert [code for code, _ in killed] == [-signal.SIGKILL] * 2, [text[-2000:] for _, text in killed]
    assert runs["killed_at"] and max(runs["killed_at"]) < ITERATIONS, runs["killed_at"]
    resumed = runs["outputs"]["resumed"]
    assert [code for code, _ in resumed] == [0, 0], [text[-3000:] for _, text in resumed]
    # Process 0 alone prints the run folder (and the progress bar).
    assert f"run folder: {runs['pair']}" in resumed[0][1]
    assert "run folder:" not in resumed[1][1]
    assert _steps(runs["pair"])[-1] == ITERATIONS
    # Every iteration logged once: the rows the kill left after the checkpoint were dropped.
    assert [r["iteration"] for r in _rows(runs["pair"])] == list(range(1, ITERATIONS + 1))
    doc = json.loads((runs["pair"] / "config.json").read_text())
    assert doc["resolved"]["physics"]["processes"] == 2


@pytest.mark.slow
def test_two_processes_log_what_one_process_on_two_devices_logs(runs):
    """The same global batch (4 environments, 2 per device) and the same per-device program:
    the metrics agree to float tolerance (the gradient all-reduce crosses processes through
    gloo instead of staying in one; measured equal bit for bit), the resumed part included."""
    one, pair = _rows(runs["one"]), _rows(runs["pair"])
    assert [r["iteration"] for r in one] == [r["iteration"] for r in pair]
    for a, b in zip(one, pair):
        assert a.keys() == b.keys()
        for k in a:
            if k not in TIMING_FIELDS:
                assert b[k] == pytest.approx(a[k], rel=1e-5, abs=1e-6), (a["iteration"], k)


@pytest.mark.parametrize(
    "flags, message",
    [
        (
            ["--processes", "2", "--process-id", "2", "--coordinator", "localhost:1234"],
            "--process-id 2 is out of range",
        ),
        (["--processes", "2", "--process-id", "0", "--coordinator", "localhost"], "expected host:port"),
        (["--processes", "2", "--process-id", "0"], "also needs --coordinator"),
        (["--processes", "two", "--process-id", "0", "--coordinator", "h:1"], "not an integer"),
    ],
)
def test_bad_process_flags_are_one_line(flags, message, capsys):
    from jaxmotion import train

    assert train.main(["smoke", *flags]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and "Traceback" not in err


def test_importing_the_cli_starts_no_backend():
    """``jax.distributed.initialize`` must come before JAX's backend starts: importing
    ``jaxmotion.train`` (and what it imports) must not start it."""
    code = (
        "import jax; from jax._src import xla_bridge as xb; import jaxmotion.train; "
        "assert not xb._backends, 'a module started the backend at import'"
    )
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
