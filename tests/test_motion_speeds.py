"""The motion CLI's joint speeds against the servo's reach (``python -m jaxmotion.motion``,
``physics/servo.py``): clips built in code, a CompositeMotion file written here."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from jaxmotion.motion import make_test_clip
from jaxmotion.motion.__main__ import main, servo_reach, speed_fields
from jaxmotion.physics import servo, sim
from jaxmotion.physics.character import character

FPS = 60.0


def _knee_triangle(speed: float, n: int = 31, lo: float = 0.3, hi: float = 2.3) -> np.ndarray:
    """[n] right-knee angles bouncing between ``lo`` and ``hi`` at ``speed`` rad/s, at ``FPS``."""
    span, step = hi - lo, speed / FPS
    phase = (np.arange(n) * step) % (2 * span)
    return lo + np.where(phase <= span, phase, 2 * span - phase)


def _write_composite(path: Path, knee: np.ndarray) -> Path:
    """A CompositeMotion JSON of the 15-body humanoid standing still, its right knee at ``knee``
    (the shin's local rotation about y; quaternions xyzw as the format stores them)."""
    ch = character(False)
    frames = []
    for a in knee:
        f = {b: [0.0, 0.0, 0.0, 1.0] for b in ch.body_names[1:]}
        f["right_shin"] = [0.0, float(np.sin(a / 2)), 0.0, float(np.cos(a / 2))]
        f["pelvis"] = [[0.0, 0.0, 0.9], [0.0, 0.0, 0.0, 1.0]]
        frames.append(f)
    path.write_text(json.dumps({"fps": FPS, "frames": frames}))
    return path


def test_clip_speeds_by_hand():
    """The q-th percentile over frames of |angle difference| * fps, per joint (numpy's linear
    interpolation between order statistics), checked against the numbers worked out by hand."""
    dof = np.array([[0.0, 1.0], [0.1, 1.0], [0.3, 0.5], [0.2, 0.5], [0.2, 1.5]])
    # speeds at 10 fps: joint 0 [1, 2, 1, 0], joint 1 [0, 5, 0, 10]
    np.testing.assert_allclose(servo.clip_speeds(dof, 10.0, q=50), [1.0, 2.5])
    # 99th: between the two largest (position 0.99 * 3 = 2.97): 1 + 0.97 * (2 - 1), 5 + 0.97 * 5
    np.testing.assert_allclose(servo.clip_speeds(dof, 10.0), [1.97, 9.85])
    np.testing.assert_allclose(servo.clip_speeds(dof, 10.0, q=100), [2.0, 10.0])
    np.testing.assert_array_equal(servo.clip_speeds(dof[:1], 10.0), [0.0, 0.0])


def test_speed_fields_name_the_fastest_joint_against_its_reach():
    ch = character(False)
    knee = ch.joint_names.index("right_knee")
    dof = np.zeros((31, ch.num_dof))
    dof[:, knee] = _knee_triangle(10.0)
    clip = make_test_clip(31, FPS, root_vel=(0.0, 0.0, 0.0), dof_pos=dof)
    reach = servo.reach(sim.PhysicsConfig())
    f = speed_fields(clip, "actuator", 120.0)
    assert f["peak_joint_speed_rad_s"]["right_knee"] == pytest.approx(10.0, abs=1e-3)
    assert f["limiting_joint"] == "right_knee"
    assert f["servo_reach_ratio"] == pytest.approx(10.0 / reach[knee], rel=1e-3)
    assert set(f["peak_joint_speed_rad_s"]) == set(ch.joint_names)


def test_sword_shield_clips_use_their_own_characters_reach():
    """A 17-body clip is judged by ``PhysicsConfig(sword_shield=True)``: its wrist hinges count.
    At 120 Hz with actuator damping that servo's probe goes unstable (the light wrist crosses its
    range in two steps), so the ratio is not judged; at 240 Hz it is."""
    ch = character(True)
    wrist = ch.joint_names.index("right_hand_z")
    dof = np.zeros((31, ch.num_dof))
    dof[:, wrist] = np.linspace(-1.0, 1.0, 31)  # 4 rad/s at 60 fps
    clip = make_test_clip(31, FPS, root_vel=(0.0, 0.0, 0.0), dof_pos=dof, sword_shield=True)
    reach, problem = servo_reach(True, "actuator", 120.0)
    assert reach is None and "right_hand" in problem
    assert servo.probe_problem(sim.PhysicsConfig()) is None
    f = speed_fields(clip, "actuator", 120.0)
    assert f["servo_reach_ratio"] is None and f["limiting_joint"] is None
    assert f["peak_joint_speed_rad_s"]["right_hand_z"] == pytest.approx(4.0)
    f = speed_fields(clip, "joint", 240.0)
    want = servo.reach(sim.PhysicsConfig(sword_shield=True, servo_damping="joint", sim_hz=240.0))
    assert f["limiting_joint"] == "right_hand_z"
    assert f["servo_reach_ratio"] == pytest.approx(4.0 / want[wrist], rel=1e-3)


def test_cli_marks_the_clip_the_servo_cannot_follow(tmp_path, capsys):
    """A clip whose knee swings at 60 rad/s (past the knee's 22 rad/s reach) is marked and named;
    a slow one (2 rad/s) is not; ``--servo-damping joint`` compares with the damped servo."""
    folder = tmp_path / "clips"
    folder.mkdir()
    _write_composite(folder / "slow.json", _knee_triangle(2.0))
    _write_composite(folder / "fast.json", _knee_triangle(60.0))
    knee = character(False).joint_names.index("right_knee")
    reach = {d: servo.reach(sim.PhysicsConfig(servo_damping=d))[knee] for d in ("actuator", "joint")}
    for damping in ("actuator", "joint"):
        out = tmp_path / f"{damping}.json"
        assert main([str(folder), "--json", str(out), "--servo-damping", damping]) == 0
        text = capsys.readouterr().out
        rows = {Path(r["path"]).stem: r for r in json.loads(out.read_text())["clips"]}
        fast, slow = rows["fast"], rows["slow"]
        assert fast["limiting_joint"] == "right_knee"
        assert fast["peak_joint_speed_rad_s"]["right_knee"] == pytest.approx(60.0, rel=1e-3)
        assert fast["servo_reach_ratio"] == pytest.approx(60.0 / reach[damping], rel=1e-3)
        assert fast["servo_reach_ratio"] > 1
        assert slow["peak_joint_speed_rad_s"]["right_knee"] == pytest.approx(2.0, rel=1e-3)
        assert slow["servo_reach_ratio"] == pytest.approx(2.0 / reach[damping], rel=1e-3)
        assert slow["servo_reach_ratio"] < 1
        (fast_line,) = [ln for ln in text.splitlines() if ln.startswith(str(folder / "fast.json"))]
        (slow_line,) = [ln for ln in text.splitlines() if ln.startswith(str(folder / "slow.json"))]
        assert fast_line.endswith("! right_knee") and "!" not in slow_line
        assert (
            f"1 clips need joints faster than the servo can turn (servo_damping={damping}): "
            f"fast.json ({fast['servo_reach_ratio']:.2f} right_knee)"
        ) in text
        servo_info = json.loads(out.read_text())["servo"]
        assert servo_info["servo_damping"] == damping and servo_info["characters"]["humanoid"]["problem"] is None
