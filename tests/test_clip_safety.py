"""Clip safety: the restricted unpickler, physical plausibility limits, frame ranges and the motion
CLI's JSON and errors. (The broad malformed-file sweep is ``test_fuzz_clips``.)"""

from __future__ import annotations

import collections
import io
import json
import os
import pickle

import numpy as np
import pytest

from jaxmotion.motion import plausibility as plaus
from jaxmotion.motion.__main__ import finite_or_none
from jaxmotion.motion.__main__ import main as motion_main
from jaxmotion.motion.clip import make_test_clip, select_frames
from jaxmotion.motion.frame_ranges import split_frame_ranges
from jaxmotion.motion.loaders import MotionFileError, find_motion_files, load_clip, load_clips
from jaxmotion.motion.safe_pickle import RefusedPickle, SafeUnpickler, load_pickled_npy
from jaxmotion.physics.character import character

from conftest import DATA

SHARED_NPY = [p for p in find_motion_files(DATA) if p.suffix == ".npy"] if DATA.is_dir() else []


def _poselib_dict(T=6, sword_shield=False, fps=30):
    ch = character(sword_shield)
    rotq = np.zeros((T, ch.num_bodies, 4), np.float32)
    rotq[..., 3] = 1

    def arr(a):
        return {"arr": a, "context": {"dtype": str(a.dtype)}}

    root = np.tile(np.float32([0, 0, 0.9]), (T, 1))
    root[:, 0] = np.arange(T) / fps  # 1 m/s
    return {
        "rotation": arr(rotq),
        "root_translation": arr(root),
        "skeleton_tree": collections.OrderedDict(
            node_names=list(ch.body_names),
            parent_indices=arr(np.array(ch.parents)),
            local_translation=arr(ch.body_offsets.astype(np.float32)),
        ),
        "is_local": True,
        "fps": np.float64(fps),
        "__name__": "SkeletonMotion",
    }


def _npy_with_pickle(path, payload: bytes):
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "|O", "fortran_order": False, "shape": ()})
    path.write_bytes(buf.getvalue() + payload)
    return path


def _save_dict(path, d, protocol: int | None = None):
    if protocol is None:
        np.save(path, d, allow_pickle=True)
        return path
    a = np.empty((), object)
    a[()] = d
    return _npy_with_pickle(path, pickle.dumps(a, protocol=protocol))


class _Calls:
    def __init__(self, fn, *args):
        self.fn, self.args = fn, args

    def __reduce__(self):
        return self.fn, self.args


def _composite(T=6, fps=30, root=lambda t: [t / 30.0, 0.0, 0.9]):
    names = character(False).body_names
    frames = []
    for t in range(T):
        f = {b: [0.0, 0.0, 0.0, 1.0] for b in names[1:]}
        f["pelvis"] = [list(root(t)), [0.0, 0.0, 0.0, 1.0]]
        frames.append(f)
    return {"fps": fps, "frames": frames}


def _write(path, d):
    path.write_text(json.dumps(d))
    return path


# ----------------------------------------------------------------------------- restricted unpickler


@pytest.mark.parametrize(
    "fn, args, made",
    [
        (open, ("made_by_open", "w"), "made_by_open"),
        (os.system, ("touch made_by_system",), "made_by_system"),
        (exec, ("open('made_by_exec', 'w').close()",), "made_by_exec"),
    ],
)
def test_crafted_pickle_runs_nothing_and_names_the_global(tmp_path, monkeypatch, fn, args, made):
    monkeypatch.chdir(tmp_path)
    d = _poselib_dict()
    d["fps"] = _Calls(fn, *args)  # deep inside an otherwise valid clip
    path = _save_dict(tmp_path / "evil.npy", d, protocol=3)
    with pytest.raises(MotionFileError) as info:
        load_clip(path)
    refused = f"{fn.__module__}.{fn.__name__}"
    assert str(info.value) == (
        f"{path}: refusing to unpickle {refused}: a clip may hold only containers, numpy arrays and scalars"
    )
    assert not (tmp_path / made).exists()


def test_crafted_top_level_pickle_runs_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = _npy_with_pickle(tmp_path / "evil.npy", pickle.dumps(_Calls(os.system, "touch made"), protocol=2))
    with pytest.raises(RefusedPickle, match=f"refusing to unpickle {os.system.__module__}.system"):
        load_pickled_npy(path)
    assert os.listdir(tmp_path) == ["evil.npy"]


def test_numpy_globals_outside_the_whitelist_are_refused():
    for obj in (_Calls(np.save, "x.npy", [1.0]), _Calls(np.ndarray, (10**12,)), _Calls(np.load, "x.npy")):
        with pytest.raises(RefusedPickle, match="refusing to unpickle"):
            SafeUnpickler(io.BytesIO(pickle.dumps(obj, protocol=4))).load()


@pytest.mark.parametrize("protocol", [None, 0, 2, 3, 4, 5])
def test_poselib_like_dict_with_arrays_loads(tmp_path, protocol):
    d = _poselib_dict(sword_shield=True)
    d["extra"] = {"ints": np.arange(3), "set": {1, 2}, "tuple": (1.5, "a", None), "c": complex(1, 2)}
    path = _save_dict(tmp_path / "ok.npy", d, protocol)
    got = load_pickled_npy(path)
    assert isinstance(got["skeleton_tree"], collections.OrderedDict)
    np.testing.assert_array_equal(got["rotation"]["arr"], d["rotation"]["arr"])
    assert got["rotation"]["arr"].dtype == np.float32 and got["fps"] == 30.0
    assert got["extra"]["set"] == {1, 2} and got["extra"]["tuple"] == (1.5, "a", None)
    clip = load_clip(path)
    assert clip.sword_shield and clip.num_frames == 6 and clip.fps == 30.0


@pytest.mark.skipif(not SHARED_NPY, reason="shared motion data not found")
def test_every_shared_npy_unpickles_as_numpy_does():
    for p in SHARED_NPY:
        ours = load_pickled_npy(p)
        ref = np.load(p, allow_pickle=True).item()  # the shared clips are trusted
        assert ours.keys() == ref.keys(), p
        for key in ("rotation", "root_translation"):
            np.testing.assert_array_equal(ours[key]["arr"], ref[key]["arr"])
            assert ours[key]["arr"].dtype == ref[key]["arr"].dtype
        assert ours["skeleton_tree"]["node_names"] == ref["skeleton_tree"]["node_names"]
        assert float(ours["fps"]) == float(ref["fps"])


# ----------------------------------------------------------------------------- plausibility


def test_teleport_message_names_file_frame_and_quantity(tmp_path):
    root = lambda t: [t / 30.0 + (100.0 if t >= 41 else 0.0), 0.0, 0.9]  # noqa: E731
    path = _write(tmp_path / "jump.json", _composite(T=45, root=root))
    with pytest.raises(MotionFileError) as info:
        load_clip(path)
    assert str(info.value) == (
        f"{path}: frame 41: root moves 100 m in one frame (3001 m/s; a body moves at most 20 m/s)"
    )


@pytest.mark.parametrize(
    "fps, root, expect",
    [
        (1e300, None, "bad fps 1e+300 (need 1 to 1000"),
        (1e-300, None, "bad fps 1e-300"),
        (True, None, "bad fps True (need a number"),
        ("30", None, "bad fps '30'"),
        (30, lambda t: [1e30, 0.0, 0.9], "frame 0: root is 1e+30 m from the origin"),
        (30, lambda t: [0.0, 0.0, -5.0], "frame 0: root height -5 m is under the floor"),
        (30, lambda t: [10.0 * (t >= 3), 0.0, 0.9], "frame 3: root moves 10 m in one frame (300 m/s"),
    ],
)
def test_extreme_but_finite_clips_are_refused(tmp_path, fps, root, expect):
    d = _composite(fps=fps, root=root) if root else _composite(fps=fps)
    path = _write(tmp_path / "x.json", d)
    with pytest.raises(MotionFileError) as info:
        load_clip(path)
    assert str(info.value).startswith(f"{path}: {expect}"), str(info.value)


def test_limits_pass_just_inside_and_fail_just_outside():
    T, fps = 4, 30.0
    still = np.tile([0.0, 0.0, 0.9], (T, 1))
    ident = np.tile([1.0, 0.0, 0.0, 0.0], (T, 15, 1))
    names = character(False).body_names
    assert plaus.motion_problem(fps, still, ident, names) is None
    for f, ok in ((1.0, True), (1000.0, True), (0.99, False), (1000.1, False), (np.array(30, np.int32), True)):
        assert (plaus.fps_problem(f) is None) == ok, f
    assert plaus.fps_problem(np.bool_(True)) and plaus.fps_problem(10**400)
    run = still + np.arange(T)[:, None] * [plaus.MAX_ROOT_SPEED / fps * 0.99, 0, 0]
    assert plaus.root_speed_problem(run, fps) is None
    assert plaus.root_speed_problem(still + np.arange(T)[:, None] * [0.7, 0, 0], fps).startswith("frame 1:")
    for z, ok in ((-0.24, True), (2.99, True), (-0.3, False), (3.1, False)):
        assert (plaus.root_position_problem(still + [0, 0, z - 0.9]) is None) == ok, z
    assert plaus.root_position_problem(still + [999.0, -999.0, 0.0]) is None
    assert "from the origin" in plaus.root_position_problem(still + [0.0, 1001.0, 0.0])
    # A hinge turning 4 rad/s vs 200 rad/s (at 100 fps: 0.04 and 2 rad between frames).
    for rate, ok in ((4.0, True), (200.0, False)):
        half = 0.5 * rate / 100.0 * np.arange(T)
        q = ident.copy()
        q[:, 10] = np.stack([np.cos(half), 0 * half, np.sin(half), 0 * half], -1)
        problem = plaus.angular_speed_problem(q, 100.0, names)
        assert (problem is None) == ok and (ok or "'right_shin' turns 2 rad in one frame (200 rad/s" in problem)
    assert "length 1.41e+300" in plaus.quat_norm_problem(np.array([[1e300, 1e300, 0.0, 0.0]]), "q")
    assert plaus.frame_time_problem(np.array([1 / 30, 2 / 30, 1 / 30])) is None  # humanoid3d_roll's double frame
    assert "at most 4x" in plaus.frame_time_problem(np.array([0.01, 0.01, 0.05]))


def test_error_is_one_short_line():
    e = MotionFileError("a.json", "bad\nthing " + "x" * 5000)
    assert "\n" not in str(e) and len(e.problem) <= 400 and e.problem.startswith("bad thing x")
    assert e.hint == "" and "JAXMOTION_DATA" in MotionFileError("a.json", "no such file").hint


# ----------------------------------------------------------------------------- frame ranges


def test_frame_ranges_are_python_slices(tmp_path):
    assert split_frame_ranges("a.json[-5:]") == ("a.json", ((-5, None),))
    assert split_frame_ranges("a.json[:10]") == ("a.json", ((0, 10),))
    assert split_frame_ranges("a.json[10:-3, -2:]") == ("a.json", ((10, -3), (-2, None)))
    clip = make_test_clip(20)
    assert select_frames(clip, ((-5, None),)).num_frames == 5
    assert select_frames(clip, ((10, -3),)).num_frames == 7
    path = _write(tmp_path / "walk.json", _composite(T=20))
    frames = [c.num_frames for c in load_clips([f"{path}[-5:]", f"{path}[:10]", f"{path}[10:-3]"])]
    assert frames == [5, 10, 7]
    (c,) = load_clips([f"{path}[-5:]"])
    np.testing.assert_allclose(c.root_pos[:, 0], np.arange(15, 20) / 30.0, atol=1e-9)


@pytest.mark.parametrize(
    "spec, expect",
    [
        ("[-1:]", "select 1 frame of the clip's 20; a clip needs at least 2"),
        ("[5:5]", "select no frame"),
        ("[-3:-5]", "select no frame"),
        ("[0:25]", "not within the clip's 20 frames"),
        ("[-25:]", "not within"),
        ("[5]", "bad frame range [5]"),
        ("[::2]", "bad frame range [::2]"),
        ("[a:b]", "bad frame range [a:b]"),
    ],
)
def test_bad_frame_ranges_are_clear_errors(tmp_path, spec, expect):
    path = _write(tmp_path / "walk.json", _composite(T=20))
    with pytest.raises(MotionFileError) as info:
        load_clips([f"{path}{spec}"])
    assert expect in str(info.value) and "walk.json" in str(info.value)


def test_a_folder_with_a_range_is_a_clear_error(tmp_path):
    (tmp_path / "clips").mkdir()
    _write(tmp_path / "clips" / "walk.json", _composite())
    with pytest.raises(MotionFileError, match=r"frame ranges \[0:3\] need one file, not a folder"):
        load_clips([f"{tmp_path / 'clips'}[0:3]"])


def test_a_file_named_with_brackets_is_that_file(tmp_path):
    path = _write(tmp_path / "odd.json[1:3]", _composite())
    with pytest.raises(MotionFileError, match="unsupported file type"):
        load_clips([str(path)])  # the file itself, not frames 1-3 of "odd.json"


# ----------------------------------------------------------------------------- CLI


def test_cli_json_is_strict_and_takes_frame_ranges(tmp_path, capsys):
    good = _write(tmp_path / "good.json", _composite(T=20))
    bad = _write(tmp_path / "bad.json", _composite(fps=1e300))
    out = tmp_path / "report.json"
    rc = motion_main([f"{good}[-5:]", f"{good}[2:-3]", str(bad), "--json", str(out)])
    text = capsys.readouterr().out
    assert rc == 1 and f"ERROR {bad}: bad fps 1e+300" in text
    report = json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(f"{c} in strict JSON"))
    assert [(r["path"], r["frames"]) for r in report["clips"]] == [(f"{good}[-5:]", 5), (f"{good}[2:-3]", 15)]
    assert finite_or_none({"a": [float("nan"), 1.0, float("inf")], "b": "x"}) == {"a": [None, 1.0, None], "b": "x"}


def test_cli_json_into_missing_folder_fails_before_loading(tmp_path, capsys):
    good = _write(tmp_path / "good.json", _composite())
    rc = motion_main([str(good), "--json", str(tmp_path / "no" / "such" / "r.json")])
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""  # nothing loaded, no table
    assert err.count("\n") == 1 and err.startswith("error: --json ") and "does not exist" in err
    assert "Traceback" not in err


def test_cli_bad_range_and_missing_file_are_error_lines(tmp_path, capsys):
    good = _write(tmp_path / "good.json", _composite(T=20))
    rc = motion_main([f"{good}[-1:]", str(tmp_path / "missing.json")])
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("ERROR ")]
    assert rc == 1 and len(lines) == 2
    assert "select 1 frame" in lines[1] and "no such file" in lines[0]
