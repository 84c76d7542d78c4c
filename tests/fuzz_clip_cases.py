"""The malformed clips of ``test_fuzz_clips``: valid bases of every format the loaders read, the
mutations that break them (truncated and empty files, NaN/inf, absurd magnitudes, wrong shapes and
types, pickles that call functions, physically impossible motion) and ``fuzz_cases()``, which
lists them as (name, suffix, bytes factory)."""

from __future__ import annotations

import _codecs
import copy
import io
import json
import os
import pickle
import subprocess
from collections.abc import Callable

import numpy as np

from jaxmotion.physics.character import character

T = 5
IDENT_XYZW = [0.0, 0.0, 0.0, 1.0]
IDENT_WXYZ = [1.0, 0.0, 0.0, 0.0]

# ----------------------------------------------------------------------------- valid bases


def composite_new() -> dict:
    """CompositeMotion JSON, ``pelvis: [[x, y, z], [qx, qy, qz, qw]]``: a slow walk along x."""
    names = character(False).body_names
    frames = []
    for t in range(T):
        f = {b: list(IDENT_XYZW) for b in names[1:]}
        f["pelvis"] = [[0.03 * t, 0.0, 0.9], list(IDENT_XYZW)]
        frames.append(f)
    return {"fps": 30, "frames": frames}


def composite_old() -> dict:
    """CompositeMotion JSON, ``base_position`` + ``pelvis`` quaternion layout."""
    names = character(False).body_names
    frames = []
    for t in range(T):
        f = {b: list(IDENT_XYZW) for b in names}
        f["base_position"] = [0.03 * t, 0.0, 0.9]
        frames.append(f)
    return {"fps": 30, "frames": frames}


def deepmimic() -> dict:
    """DeepMimic humanoid3d (y-up): dt, root pos, root wxyz, then 8 quaternions and 4 hinges."""
    joints = IDENT_WXYZ * 3 + [-0.5] + IDENT_WXYZ * 2 + [0.0] + IDENT_WXYZ + [-0.5] + IDENT_WXYZ * 2 + [0.0]
    return {"Loop": "wrap", "Frames": [[1 / 30, 0.03 * t, 0.9, 0.0] + IDENT_WXYZ + joints for t in range(T)]}


def poselib(sword_shield: bool = False) -> dict:
    """poselib ``SkeletonMotion`` dict as ``np.save`` stores it."""
    ch = character(sword_shield)
    rotq = np.zeros((T, ch.num_bodies, 4), np.float32)
    rotq[..., 3] = 1

    def arr(a):
        return {"arr": a, "context": {"dtype": str(a.dtype)}}

    root = np.tile(np.float32([0, 0, 0.9]), (T, 1))
    root[:, 0] = 0.03 * np.arange(T)
    return {
        "rotation": arr(rotq),
        "root_translation": arr(root),
        "skeleton_tree": {
            "node_names": list(ch.body_names),
            "parent_indices": arr(np.array(ch.parents)),
            "local_translation": arr(ch.body_offsets.astype(np.float32)),
        },
        "is_local": True,
        "fps": np.array(30, np.int32),
        "__name__": "SkeletonMotion",
    }


# ----------------------------------------------------------------------------- encoders


def json_bytes(d) -> bytes:
    return json.dumps(d).encode() if not isinstance(d, (bytes, str)) else (d if isinstance(d, bytes) else d.encode())


def npy_bytes(obj, protocol: int = 3) -> bytes:
    """``np.save`` of a pickled object (a 0-d object array, pickled with ``protocol``) or a plain array."""
    if isinstance(obj, np.ndarray) and obj.dtype != object:
        buf = io.BytesIO()
        np.save(buf, obj)
        return buf.getvalue()
    a = np.empty((), object)
    a[()] = obj
    return npy_raw_pickle(pickle.dumps(a, protocol=protocol))


def npy_raw_pickle(payload: bytes) -> bytes:
    """A ``.npy`` whose header says "0-d object array" followed by an arbitrary pickle."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "|O", "fortran_order": False, "shape": ()})
    return buf.getvalue() + payload


# ----------------------------------------------------------------------------- payloads that act


class Calls:
    """Pickles as ``fn(*args)``: unpickling it calls ``fn`` (what a hostile clip does)."""

    def __init__(self, fn, *args):
        self.fn, self.args = fn, args

    def __reduce__(self):
        return self.fn, self.args


def _evil_payloads() -> dict[str, Calls]:
    """Each one leaves a file named ``pwned_*`` in the working folder if it runs."""
    return {
        "os_system": Calls(os.system, "touch pwned_system"),
        "builtin_open": Calls(open, "pwned_open", "w"),
        "builtin_exec": Calls(exec, "open('pwned_exec', 'w').close()"),
        "builtin_eval": Calls(eval, "open('pwned_eval', 'w')"),
        "subprocess": Calls(subprocess.call, ["touch", "pwned_subprocess"]),
        "os_mkdir": Calls(os.mkdir, "pwned_mkdir"),
        "numpy_save": Calls(np.save, "pwned_npsave.npy", [1.0]),
        "numpy_savetxt": Calls(np.savetxt, "pwned_savetxt", [1.0]),
        "io_open": Calls(io.open, "pwned_io", "w"),
    }


def _deep_list_npy(*keys: str, depth: int = 100_000) -> Callable[[], bytes]:
    """A poselib clip whose ``d[keys...]`` is a list nested ``depth`` deep (written as pickle
    opcodes: ``pickle.dumps`` itself would recurse too deep)."""

    def make():
        d = poselib(False)
        _set(keys, "PLACEHOLDER")(d)
        a = np.empty((), object)
        a[()] = d
        op = b"X" + len(b"PLACEHOLDER").to_bytes(4, "little") + b"PLACEHOLDER"
        return npy_raw_pickle(pickle.dumps(a, protocol=2).replace(op, b"]" * depth + b"a" * (depth - 1)))

    return make


def _cyclic_list():
    a: list = []
    a.append(a)
    return a


# ----------------------------------------------------------------------------- mutations

Mut = Callable[[dict], object]  # mutates (or replaces) a document, returns the new one


def _set(path: tuple, value) -> Mut:
    """Sets ``doc[path...] = value`` (a path of keys/indices)."""

    def f(d):
        x = d
        for k in path[:-1]:
            x = x[k]
        x[path[-1]] = value
        return d

    return f


def _each_frame(key, value_of_t) -> Mut:
    def f(d):
        for t, fr in enumerate(d["frames"]):
            fr[key] = value_of_t(t, fr[key])
        return d

    return f


def _composite_root(layout: str, t: int | None, value) -> Mut:
    """Sets the root position (of frame t, or all frames with t=None) in either layout."""

    def f(d):
        for i, fr in enumerate(d["frames"]):
            if t is None or i == t:
                v = value(i, fr) if callable(value) else copy.deepcopy(value)
                if layout == "new":
                    fr["pelvis"][0] = v
                else:
                    fr["base_position"] = v
        return d

    return f


def _root_xyz(layout, fr):
    return list(fr["pelvis"][0] if layout == "new" else fr["base_position"])


def _composite_cases(layout: str) -> dict[str, Mut]:
    root = lambda t, v: _composite_root(layout, t, v)  # noqa: E731

    def teleport(i, fr):
        p = _root_xyz(layout, fr)
        return [p[0] + (100.0 if i >= 2 else 0.0), p[1], p[2]]

    def shift_z(z):
        return lambda i, fr: _root_xyz(layout, fr)[:2] + [z]

    def spin(d):  # the torso flips by 180 degrees every frame at 1000 fps (3142 rad/s), the root still
        d = root(None, [0.0, 0.0, 0.9])(d)
        d["fps"] = 1000
        for i, fr in enumerate(d["frames"]):
            fr["torso"] = [1.0, 0.0, 0.0, 0.0] if i % 2 else list(IDENT_XYZW)
        return d

    cases: dict[str, Mut] = {
        "fps_zero": _set(("fps",), 0),
        "fps_negative": _set(("fps",), -30),
        "fps_1e300": _set(("fps",), 1e300),
        "fps_1e-300": _set(("fps",), 1e-300),
        "fps_true": _set(("fps",), True),
        "fps_false": _set(("fps",), False),
        "fps_string": _set(("fps",), "30"),
        "fps_null": _set(("fps",), None),
        "fps_list": _set(("fps",), [30]),
        "fps_object": _set(("fps",), {"value": 30}),
        "fps_nan": _set(("fps",), float("nan")),
        "fps_inf": _set(("fps",), float("inf")),
        "fps_huge_int": _set(("fps",), 10**400),
        "fps_missing": lambda d: {k: v for k, v in d.items() if k != "fps"},
        "frames_null": _set(("frames",), None),
        "frames_string": _set(("frames",), "frames"),
        "frames_object": _set(("frames",), {}),
        "frames_empty": _set(("frames",), []),
        "frames_one": lambda d: {**d, "frames": d["frames"][:1]},
        "frames_numbers": _set(("frames",), [1, 2, 3]),
        "frame_is_list": _set(("frames", 2), [1, 2]),
        "frame_is_null": _set(("frames", 1), None),
        "missing_body": lambda d: (d["frames"][3].pop("left_shin"), d)[1],
        "unknown_body": _set(("frames", 0, "tail"), list(IDENT_XYZW)),
        "root_nan": root(2, [float("nan"), 0.0, 0.9]),
        "root_inf": root(1, [0.0, float("inf"), 0.9]),
        "root_neg_inf": root(3, [0.0, 0.0, float("-inf")]),
        "root_1e30": root(None, [1e30, 1e30, 0.9]),
        "root_teleport_100m": root(None, teleport),
        "root_under_floor_5m": root(None, shift_z(-5.0)),
        "root_100m_high": root(None, shift_z(100.0)),
        "root_string": root(1, ["0", "0", "0.9"]),
        "root_bool": root(1, [True, False, True]),
        "root_null": root(1, [0.0, None, 0.9]),
        "root_len2": root(None, [0.0, 0.9]),
        "root_len4": root(None, [0.0, 0.0, 0.9, 1.0]),
        "root_nested": root(None, [[0.0, 0.0, 0.9]]),
        "root_object": root(2, {"x": 0.0}),
        "quat_zero": _each_frame("torso", lambda t, q: [0.0, 0.0, 0.0, 0.0]),
        "quat_1e300": _each_frame("torso", lambda t, q: [1e300, 1e300, 0.0, 0.0]),
        "quat_1e-300": _each_frame("head", lambda t, q: [0.0, 0.0, 0.0, 1e-300]),
        "quat_nan": _set(("frames", 2, "torso", 0), float("nan")),
        "quat_string": _set(("frames", 1, "head"), ["0", "0", "0", "1"]),
        "quat_bool": _set(("frames", 1, "head"), [False, False, False, True]),
        "quat_mixed_bool": _set(("frames", 1, "head"), [0.0, 0.0, 0.0, True]),
        "quat_null": _set(("frames", 1, "head"), None),
        "quat_len3": _set(("frames", 1, "right_thigh"), [0.0, 0.0, 1.0]),
        "quat_len5": _set(("frames", 1, "right_thigh"), [0.0, 0.0, 0.0, 1.0, 0.0]),
        "quat_nested": _set(("frames", 0, "left_foot"), [[0.0, 0.0, 0.0, 1.0]]),
        "quat_object": _set(("frames", 0, "left_foot"), {"w": 1.0}),
        "joint_spin": spin,
    }
    if layout == "new":
        cases["pelvis_string"] = _set(("frames", 1, "pelvis"), "pelvis")
        cases["pelvis_flat"] = _set(("frames", 1, "pelvis"), [0.0, 0.0, 0.9, 0.0, 0.0, 0.0, 1.0])
        cases["pelvis_quat_zero"] = _set(("frames", 1, "pelvis", 1), [0.0, 0.0, 0.0, 0.0])
        cases["pelvis_quat_huge"] = _set(("frames", 1, "pelvis", 1), [1e200, 0.0, 0.0, 1e200])
    else:
        cases["base_position_missing"] = lambda d: (d["frames"][2].pop("base_position"), d)[1]
    return cases


def _dm_frame(t: int, col: int, value) -> Mut:
    def f(d):
        for i, fr in enumerate(d["Frames"]):
            if t is None or i == t:
                fr[col] = value(i, fr[col]) if callable(value) else value
        return d

    return f


def _deepmimic_cases() -> dict[str, Mut]:
    col = _dm_frame
    return {
        "frames_null": _set(("Frames",), None),
        "frames_string": _set(("Frames",), "x"),
        "frames_empty": _set(("Frames",), []),
        "frames_one": lambda d: {**d, "Frames": d["Frames"][:1]},
        "width_43": lambda d: {**d, "Frames": [f[:43] for f in d["Frames"]]},
        "width_45": lambda d: {**d, "Frames": [f + [0.0] for f in d["Frames"]]},
        "width_mixed": lambda d: (d["Frames"][2].pop(), d)[1],
        "frame_is_object": _set(("Frames", 1), {"dt": 0.03}),
        "value_string": col(1, 5, "0"),
        "value_bool": col(1, 5, True),
        "value_null": col(1, 5, None),
        "value_list": col(1, 5, [0.0]),
        "dt_zero": col(None, 0, 0.0),
        "dt_negative": col(1, 0, -0.03),
        "dt_nan": col(1, 0, float("nan")),
        "dt_1e300": col(None, 0, 1e300),
        "dt_1e-300": col(None, 0, 1e-300),
        "dt_true": col(None, 0, True),
        "dt_one_huge": col(2, 0, 1e6),
        "dt_one_tiny": col(2, 0, 1e-9),
        "root_nan": col(2, 1, float("nan")),
        "root_inf": col(2, 2, float("inf")),
        "root_1e30": col(None, 1, 1e30),
        "root_teleport_100m": col(None, 1, lambda i, v: v + (100.0 if i >= 2 else 0.0)),
        "root_under_floor_5m": col(None, 2, -5.0),
        "root_100m_high": col(None, 2, 100.0),
        "root_quat_zero": lambda d: {**d, "Frames": [f[:4] + [0.0] * 4 + f[8:] for f in d["Frames"]]},
        "root_quat_huge": col(None, 4, 1e300),
        "torso_quat_nan": col(3, 9, float("nan")),
        "knee_nan": col(2, 20, float("nan")),
        "knee_1e30": col(None, 20, 1e30),
        "knee_spin": lambda d: {  # 0 and pi in turn at 1000 fps: 3142 rad/s
            **d,
            "Frames": [[0.001, 0.0] + f[2:20] + [np.pi * (i % 2)] + f[21:] for i, f in enumerate(d["Frames"])],
        },
        "huge_int": col(1, 1, 10**400),
    }


def _poselib_cases(sword_shield: bool) -> dict[str, Callable[[], bytes]]:
    def mut(m: Mut, protocol: int = 3):
        return lambda: npy_bytes(m(poselib(sword_shield)), protocol)

    def setter(*keys):  # sets (or maps, given a function) d[keys...]["arr"] or a plain entry
        def with_value(value):
            def f(d):
                x = d
                for k in keys[:-1]:
                    x = x[k]
                x[keys[-1]] = value(x[keys[-1]]) if callable(value) else value
                return d

            return f

        return with_value

    root, rotation = setter("root_translation", "arr"), setter("rotation", "arr")

    def tree(key, value):
        return setter("skeleton_tree", key, *(["arr"] if key != "node_names" else []))(value)

    def teleport(a):
        a = a.copy()
        a[2:, 0] += 100.0
        return a

    def under_floor(a):
        a = a.copy()
        a[:, 2] = -5.0
        return a

    def spin(d):  # the torso flips by 180 degrees every frame at 1000 fps (3142 rad/s), the root still
        d["fps"] = np.float64(1000.0)
        d["root_translation"]["arr"][:, 0] = 0.0
        r = d["rotation"]["arr"]
        r[1::2, 1] = [1.0, 0.0, 0.0, 0.0]
        return d

    def nan_at(a, idx):
        a = a.astype(np.float64)
        a[idx] = np.nan
        return a

    base = poselib(sword_shield)
    n = len(base["skeleton_tree"]["node_names"])
    good_root = base["root_translation"]["arr"]
    cases: dict[str, Callable[[], bytes]] = {
        "fps_true": mut(_set(("fps",), True)),
        "fps_np_bool": mut(_set(("fps",), np.bool_(True))),
        "fps_1e300": mut(_set(("fps",), 1e300)),
        "fps_1e-300": mut(_set(("fps",), np.float64(1e-300))),
        "fps_string": mut(_set(("fps",), "30")),
        "fps_none": mut(_set(("fps",), None)),
        "fps_nan": mut(_set(("fps",), np.float64("nan"))),
        "fps_array2": mut(_set(("fps",), np.array([30, 30]))),
        "fps_str_array": mut(_set(("fps",), np.array("30"))),
        "fps_missing": mut(lambda d: {k: v for k, v in d.items() if k != "fps"}),
        "root_nan": mut(root(lambda a: nan_at(a, (2, 1)))),
        "root_1e30": mut(root(lambda a: a + 1e30)),
        "root_teleport_100m": mut(root(teleport)),
        "root_under_floor_5m": mut(root(under_floor)),
        "root_shape_T2": mut(root(good_root[:, :2])),
        "root_shape_T": mut(root(good_root[:, 0])),
        "root_shape_3d": mut(root(good_root[None])),
        "root_str_dtype": mut(root(good_root.astype(str))),
        "root_object_none": mut(root(np.full((T, 3), None, object))),
        "root_list_strings": mut(root([["a", "b", "c"]] * T)),
        "root_bool": mut(root(np.ones((T, 3), bool))),
        "root_frames_mismatch": mut(root(good_root[:-1])),
        "root_cyclic_list": mut(root(_cyclic_list())),
        "root_deep_nested": _deep_list_npy("root_translation", "arr"),
        "fps_deep_nested": _deep_list_npy("fps"),
        "names_deep_nested": _deep_list_npy("skeleton_tree", "node_names"),
        "rotation_nan": mut(rotation(lambda a: nan_at(a, (1, 2, 0)))),
        "rotation_zero": mut(rotation(lambda a: np.zeros_like(a))),
        "rotation_1e300": mut(rotation(lambda a: np.full(a.shape, 1e300))),
        "rotation_shape_N3": mut(rotation(lambda a: a[..., :3])),
        "rotation_shape_2d": mut(rotation(lambda a: a[:, :, 0])),
        "rotation_str": mut(rotation(lambda a: a.astype(str))),
        "rotation_one_frame": mut(lambda d: root(good_root[:1])(rotation(lambda a: a[:1])(d))),
        "rotation_missing": mut(lambda d: {k: v for k, v in d.items() if k != "rotation"}),
        "joint_spin": mut(spin),
        "tree_missing": mut(lambda d: {k: v for k, v in d.items() if k != "skeleton_tree"}),
        "tree_list": mut(_set(("skeleton_tree",), [1, 2, 3])),
        "names_int": mut(tree("node_names", 15)),
        "names_wrong": mut(tree("node_names", lambda v: list(reversed(v)))),
        "names_many": mut(tree("node_names", [f"b{i}" for i in range(5000)])),
        "names_none": mut(tree("node_names", [None] * n)),
        "parents_wrong": mut(tree("parent_indices", np.zeros(n, np.int64))),
        "parents_str": mut(tree("parent_indices", np.array(["x"] * n))),
        "offsets_nan": mut(tree("local_translation", np.full((n, 3), np.nan, np.float32))),
        "offsets_1e30": mut(tree("local_translation", np.full((n, 3), 1e30))),
        "offsets_shape": mut(tree("local_translation", np.zeros((n, 2)))),
        "top_list": lambda: npy_bytes([1, 2, 3]),
        "top_string": lambda: npy_bytes("SkeletonMotion"),
        "top_none": lambda: npy_bytes(None),
        "is_local_false": mut(_set(("is_local",), False)),
        "is_local_string": mut(_set(("is_local",), "yes")),
        "evil_in_fps": mut(_set(("fps",), Calls(os.system, "touch pwned_fps"))),
        "evil_in_rotation": mut(rotation(Calls(open, "pwned_rotation", "w"))),
        "evil_in_tree_proto2": mut(tree("node_names", Calls(os.system, "touch pwned_tree")), protocol=2),
        "evil_in_root_proto5": mut(root(Calls(exec, "open('pwned_root', 'w').close()")), protocol=5),
    }
    return cases


def _npy_file_cases() -> dict[str, Callable[[], bytes]]:
    good = npy_bytes(poselib(False))
    cases: dict[str, Callable[[], bytes]] = {
        "empty": lambda: b"",
        "truncated_half": lambda: good[: len(good) // 2],
        "truncated_header": lambda: good[:20],
        "magic_only": lambda: b"\x93NUMPY",
        "bad_magic": lambda: b"\x93NUMPX\x01\x00" + good[8:],
        "text_file": lambda: b'{"fps": 30, "frames": []}',
        "header_garbage": lambda: b"\x93NUMPY\x01\x00\x10\x00{'descr': os.sys\n",
        "float_array": lambda: npy_bytes(np.zeros((T, 3))),
        "huge_shape_float": lambda: npy_raw_header("<f8", (10**12,)),
        "object_2d": lambda: _object_array_npy((2, 2)),
        "pickle_truncated": lambda: npy_raw_pickle(pickle.dumps({"a": np.zeros(3)}, protocol=3)[:-5]),
        "pickle_garbage": lambda: npy_raw_pickle(b"\x80\x03garbage"),
        "pickle_persid": lambda: npy_raw_pickle(b"\x80\x02Pfoo\n."),
        "pickle_ext": lambda: npy_raw_pickle(b"\x80\x02\x82\x01."),
        "pickle_ndarray_huge": _pickled(Calls(np.ndarray, (10**12,)), 2),  # a memory bomb via a needed global
        "pickle_copyreg": lambda: npy_raw_pickle(b"\x80\x02ccopyreg\n_reconstructor\nq\x00."),
        "pickle_codecs_rot13": lambda: npy_raw_pickle(pickle.dumps(Calls(_codecs.encode, "x", "rot13"), protocol=2)),
        "pickle_object_setstate_bytes": lambda: npy_raw_pickle(_object_array_from_bytes()),
    }
    for name, evil in _evil_payloads().items():
        cases[f"evil_{name}"] = _pickled(evil, 3)
    for protocol in (0, 4, 5):
        cases[f"evil_os_system_proto{protocol}"] = _pickled(Calls(os.system, f"touch pwned_p{protocol}"), protocol)
    return cases


def _pickled(obj, protocol: int) -> Callable[[], bytes]:
    return lambda: npy_raw_pickle(pickle.dumps(obj, protocol=protocol))


def _json_case(base: Callable[[], dict], m: Mut) -> Callable[[], bytes]:
    return lambda: json_bytes(m(base()))


def npy_raw_header(descr: str, shape: tuple) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue() + b"\x00" * 64


def _object_array_npy(shape) -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.full(shape, None, object), allow_pickle=True)
    return buf.getvalue()


def _object_array_from_bytes() -> bytes:
    """An object array whose state is raw bytes (pointers, were numpy to accept them)."""
    reconstruct = np.zeros(0).__reduce__()[0]
    mod, name = reconstruct.__module__, reconstruct.__name__
    return (
        b"\x80\x02c" + mod.encode() + b"\n" + name.encode() + b"\n"
        b"cnumpy\nndarray\nK\x00\x85C\x01b\x87R"
        b"(K\x01K\x01\x85cnumpy\ndtype\nX\x02\x00\x00\x00O8\x89\x88\x87R"
        b"(K\x03X\x01\x00\x00\x00|NNNJ\xff\xff\xff\xffJ\xff\xff\xff\xffK?tb\x89C\x08AAAAAAAAtb."
    )


def _json_file_cases(suffix: str) -> dict[str, Callable[[], bytes]]:
    good = json_bytes(composite_new() if suffix == ".json" else deepmimic())
    return {
        "empty": lambda: b"",
        "whitespace": lambda: b"  \n\t ",
        "truncated_half": lambda: good[: len(good) // 2],
        "truncated_last_byte": lambda: good[:-1],
        "not_utf8": lambda: b'{"fps": 30, "frames": ["\xff\xfe"]}',
        "null": lambda: b"null",
        "list": lambda: b"[]",
        "number": lambda: b"42",
        "string": lambda: b'"frames"',
        "no_layout_key": lambda: b'{"fps": 30}',
        "deep_nesting": lambda: b"[" * 100000 + b"]" * 100000,
        "deep_nesting_frames": lambda: b'{"fps": 30, "frames": ' + b"[" * 50000 + b"]" * 50000 + b"}",
        "bom": lambda: b"\xef\xbb\xbf" + good,
        "nan_literal_fps": lambda: b'{"fps": NaN, "frames": []}',
    }


def _other_cases() -> dict[str, tuple[str, Callable[[], bytes]]]:
    return {
        "bvh": (".bvh", lambda: b"HIERARCHY\nROOT Hips\n"),
        "csv": (".csv", lambda: b"0,0,0\n"),
        "no_suffix": ("", lambda: json_bytes(composite_new())),
    }


# The 17-body skeleton goes through the same reader: the cases where its size could matter.
SWORD_SHIELD_CASES = ("fps_true", "root_teleport_100m", "root_under_floor_5m", "rotation_nan", "joint_spin")
SWORD_SHIELD_CASES += ("rotation_shape_N3", "names_wrong", "offsets_1e30", "evil_in_fps")


def fuzz_cases() -> list[tuple[str, str, Callable[[], bytes]]]:
    """Every malformed clip: ``(case id, file suffix, make bytes)``."""
    out: list[tuple[str, str, Callable[[], bytes]]] = []
    for layout, base in (("new", composite_new), ("old", composite_old)):
        for name, m in _composite_cases(layout).items():
            if layout == "old" and not name.startswith(("root_", "base_", "fps_true", "quat_1e300", "missing")):
                continue  # the same checks as the new layout: only what differs between them
            out.append((f"composite_{layout}-{name}", ".json", _json_case(base, m)))
    for suffix in (".txt", ".json"):
        for name, m in _deepmimic_cases().items():
            if suffix == ".json" and name not in ("root_1e30", "root_teleport_100m", "dt_zero", "width_43"):
                continue  # the same reader: a few cases under the other suffix
            out.append((f"deepmimic{suffix}-{name}", suffix, _json_case(deepmimic, m)))
    for suffix in (".json", ".txt"):
        for name, make in _json_file_cases(suffix).items():
            if suffix == ".txt" and name not in ("empty", "truncated_half", "not_utf8", "deep_nesting", "bom"):
                continue
            out.append((f"file{suffix}-{name}", suffix, make))
    for ss in (False, True):
        for name, make in _poselib_cases(ss).items():
            if ss and name not in SWORD_SHIELD_CASES:
                continue
            out.append((f"poselib{17 if ss else 15}-{name}", ".npy", make))
    for name, make in _npy_file_cases().items():
        out.append((f"npy-{name}", ".npy", make))
    for name, (suffix, make) in _other_cases().items():
        out.append((f"other-{name}", suffix, make))
    return out
