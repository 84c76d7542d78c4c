"""Lists motion files: ``python -m jaxmotion.motion <file-or-folder>[range] [...] [--json FILE]``.

``python -m jaxmotion.motion retarget FILE.bvh [--skeleton NAME|MAPPING.json] --out CLIP.json`` retargets
a BVH onto the character and writes it as a CompositeMotion JSON clip (``motion.retarget``, docs/bvh.md);
it prints the BVH's skeleton, frames, fps and the retarget report. A ``.bvh`` in the listing is
retargeted the same way (the first packaged mapping that covers its joints) and its report printed
under its row.

Prints one row per file (path, format, frames, fps, duration, mean root speed, fk error, and how
fast its fastest joint turns against the servo's reach) and ``ERROR <path>: <message>`` for files
that fail to load; the exit code is 1 if any file failed. A file may name frame ranges as training
does, ``squat.json[0:33,58:]`` or ``walk.json[-30:]`` (Python slices). ``--json`` writes the table
as strict JSON (non-finite numbers as null); a ``--json`` path whose folder does not exist is
refused before anything is loaded (exit 2).

``speed/reach`` is the largest, over the clip's joints, of the joint's 99th-percentile speed over
frames (``physics.servo.clip_speeds``) divided by the peak speed the PD servo turns that joint at
(``physics.servo.reach`` of ``PhysicsConfig(sword_shield=<the clip's character>,
servo_damping=--servo-damping, sim_hz=--sim-hz)``); ``joint`` names that joint. Above 1 (marked
``!``) the character cannot follow the clip at full speed, whatever the policy. Where the servo
probe itself goes unstable (``physics.servo.probe_problem``: the sword-and-shield character at
120 Hz with actuator damping) the ratio is not judged (``n/a``, null in JSON) and the reason is
printed.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from jaxmotion.config.errors import JaxmotionError, cli_errors
from jaxmotion.motion.clip import mean_root_speed
from jaxmotion.motion.frame_ranges import Ranges, format_ranges
from jaxmotion.motion.clip import select_frames
from jaxmotion.motion.loaders import MotionFileError, find_clip_specs, load_clip_frames
from jaxmotion.motion.retarget import clip_to_json, retarget_file, skeleton_names
from jaxmotion.physics import servo, sim
from jaxmotion.physics.character import character

SPEED_PERCENTILE = 99.0
"""Percentile over frames of each joint's speed compared with the servo's reach (a single-frame
spike, e.g. an Euler-angle branch switch, does not count unless the clip is short)."""


def _expand(paths: list[str], errors: list[dict]) -> list[tuple[Path, Ranges | None]]:
    specs: list[tuple[Path, Ranges | None]] = []
    for p in paths:
        try:
            specs += find_clip_specs(p)
        except MotionFileError as e:
            errors.append({"path": e.path, "error": e.problem})
    return specs


def _label(path: Path, ranges: Ranges | None) -> str:
    return str(path) if ranges is None else f"{path}[{format_ranges(ranges)}]"


def _row(clip, label: str) -> dict:
    return {
        "path": label,
        "format": clip.format,
        "frames": clip.num_frames,
        "fps": round(clip.fps, 6),
        "duration_s": round(clip.duration, 6),
        "root_speed_mps": round(mean_root_speed(clip), 6),
        "fk_error_m": clip.fk_error_m,
    }


@functools.cache
def servo_reach(sword_shield: bool, servo_damping: str, sim_hz: float) -> tuple[tuple[float, ...] | None, str | None]:
    """(reach [n_dof] in rad/s, None), or (None, why not) where the servo probe goes unstable;
    measured once per character variant and servo setting (~0.03 s each)."""
    cfg = sim.PhysicsConfig(sword_shield=sword_shield, servo_damping=servo_damping, sim_hz=sim_hz)
    problem = servo.probe_problem(cfg)
    if problem is not None:
        return None, problem
    return tuple(float(v) for v in servo.reach(cfg)), None


def speed_fields(clip, servo_damping: str, sim_hz: float) -> dict:
    """The clip's per-joint 99th-percentile speeds against the servo's reach: ``peak_joint_speed_rad_s``
    (joint name -> rad/s), ``servo_reach_ratio`` (the largest speed / reach; None where the reach
    cannot be measured) and ``limiting_joint`` (the joint of that ratio)."""
    names = character(clip.sword_shield).joint_names
    speed = servo.clip_speeds(clip.dof_pos, clip.fps, SPEED_PERCENTILE)
    out = {
        "peak_joint_speed_rad_s": {n: round(float(v), 3) for n, v in zip(names, speed)},
        "servo_reach_ratio": None,
        "limiting_joint": None,
    }
    reach, _ = servo_reach(clip.sword_shield, servo_damping, sim_hz)
    if reach is not None:
        ratio = speed / np.maximum(np.asarray(reach), 1e-9)
        i = int(np.argmax(ratio))
        out["servo_reach_ratio"] = round(float(ratio[i]), 4)
        out["limiting_joint"] = names[i]
    return out


def _servo_label(servo_damping: str, sim_hz: float) -> str:
    default_hz = sim.PhysicsConfig().sim_hz
    return f"servo_damping={servo_damping}" + ("" if sim_hz == default_hz else f", sim_hz={sim_hz:g}")


def _ratio_cell(r: dict) -> str:
    ratio = r["servo_reach_ratio"]
    if ratio is None:
        return f"{'n/a':>11}  {'-'}"
    return f"{ratio:>11.2f}{'!' if ratio > 1 else ' '} {r['limiting_joint']}"


def _positive(text: str) -> float:
    v = float(text)
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number of Hz, got {text!r}")
    return v


def finite_or_none(x):
    """``x`` with every non-finite float (NaN, inf) inside dicts/lists replaced by None: strict
    JSON has no NaN or Infinity, and ``json.dump(..., allow_nan=False)`` refuses them."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite_or_none(v) for v in x]
    return x


def _check_json_target(path: str) -> None:
    """Refuses a ``--json`` target that cannot be written, before any clip is loaded."""
    target = Path(path).expanduser()
    folder = target.parent
    if not folder.is_dir():
        raise JaxmotionError(f"--json {path}: folder {str(folder)!r} does not exist (create it first)")
    if target.is_dir():
        raise JaxmotionError(f"--json {path}: is a folder, not a file")
    if not os.access(folder, os.W_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise JaxmotionError(f"--json {path}: not writable")


def _short_names(labels: list[str]) -> dict[str, str]:
    """Each row's path relative to the folder all rows share (``deepmimic/punch.txt``), or its
    file name if there is one row."""
    if not labels:
        return {}
    common = os.path.commonpath([os.path.dirname(os.path.abspath(x)) for x in labels])
    return {x: os.path.relpath(os.path.abspath(x), common) for x in labels}


def _servo_summary(rows: list[dict], sword_shield: list[bool], servo_damping: str, sim_hz: float) -> dict:
    """Prints which clips need joints faster than the servo turns (and which could not be judged);
    returns the servo settings and each used character's reach for the JSON report."""
    label = _servo_label(servo_damping, sim_hz)
    over = sorted((r for r in rows if (r["servo_reach_ratio"] or 0.0) > 1), key=lambda r: -r["servo_reach_ratio"])
    short = _short_names([r["path"] for r in rows])
    names = ", ".join(f"{short[r['path']]} ({r['servo_reach_ratio']:.2f} {r['limiting_joint']})" for r in over)
    print(f"{len(over)} clips need joints faster than the servo can turn ({label})" + (f": {names}" if over else ""))
    info = {"servo_damping": servo_damping, "sim_hz": sim_hz, "speed_percentile": SPEED_PERCENTILE, "characters": {}}
    for ss in sorted(set(sword_shield)):
        reach, problem = servo_reach(ss, servo_damping, sim_hz)
        kind = "sword_shield" if ss else "humanoid"
        names_ = character(ss).joint_names
        info["characters"][kind] = {
            "reach_rad_s": None if reach is None else {n: round(v, 3) for n, v in zip(names_, reach)},
            "problem": problem,
        }
        if problem is not None:
            n = sword_shield.count(ss)
            print(
                f"{n} clips not judged: the servo reach of the {character(ss).num_bodies}-body character "
                f"({label}) cannot be measured: {problem}"
            )
    return info


def _units(text: str) -> str | float:
    try:
        return float(text)
    except ValueError:
        return text


def retarget_main(argv: list[str]) -> int:
    """``retarget FILE.bvh --out CLIP.json``: see the module docstring; exit 2 with one line on a bad file."""
    ap = argparse.ArgumentParser(prog="python -m jaxmotion.motion retarget", description="Retargets a BVH file.")
    ap.add_argument("bvh", help="the BVH file")
    ap.add_argument(
        "--skeleton",
        help=f"mapping of BVH joints to bodies: a packaged one ({', '.join(skeleton_names())}) or a JSON "
        "file; default: the first packaged one that covers the file's joints",
    )
    ap.add_argument("--out", required=True, metavar="CLIP.json", help="where to write the clip (CompositeMotion JSON)")
    ap.add_argument(
        "--units", type=_units, help="m, cm, mm, inch, auto or metres per file unit (default: the mapping's)"
    )
    ap.add_argument("--up", choices=("y", "z"), help="the file's up axis (default: the mapping's)")
    ap.add_argument("--no-floor", action="store_true", help="keep the scaled BVH's heights (no feet-on-floor step)")
    args = ap.parse_args(argv)
    _check_json_target(args.out)
    clip, report = retarget_file(args.bvh, args.skeleton, args.units, args.up, floor=not args.no_floor)
    note = f"retargeted from {args.bvh} by python -m jaxmotion.motion retarget: {report.summary()}"
    with open(args.out, "w") as fh:
        json.dump(clip_to_json(clip, note), fh)
    print(f"{args.bvh}: {report.summary()}")
    print(f"wrote {args.out} ({clip.num_frames} frames at {clip.fps:g} fps)")
    return 0


def _load(path: Path, ranges: Ranges | None):
    """(clip, the retarget summary of a BVH or None)."""
    if path.suffix.lower() != ".bvh":
        return load_clip_frames(path, ranges), None
    clip, report = retarget_file(path)
    if ranges is not None:
        try:
            clip = select_frames(clip, ranges)
        except ValueError as e:
            raise MotionFileError(path, str(e)) from None
    return clip, report.summary()


@cli_errors
def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["retarget"]:
        return retarget_main(argv[1:])
    ap = argparse.ArgumentParser(prog="python -m jaxmotion.motion", description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", help="motion files or folders (searched recursively); file[a:b] for frames")
    ap.add_argument("--json", metavar="FILE", help="also write the table as JSON to FILE")
    default = sim.PhysicsConfig()
    ap.add_argument(
        "--servo-damping",
        choices=("actuator", "joint"),
        default=default.servo_damping,
        help="where the PD servo's damping lives (PhysicsConfig.servo_damping; default %(default)s)",
    )
    ap.add_argument(
        "--sim-hz",
        type=_positive,
        default=default.sim_hz,
        help="physics rate the servo's reach is measured at (PhysicsConfig.sim_hz; default %(default)g)",
    )
    args = ap.parse_args(argv)
    if args.json:
        _check_json_target(args.json)

    errors: list[dict] = []
    rows: list[dict] = []
    sword_shield: list[bool] = []  # each row's character
    specs = _expand(args.paths, errors)
    for err in errors:
        print(f"ERROR {err['path']}: {err['error']}")
    width = max([len(_label(*s)) for s in specs] + [4])
    header = (
        f"{'path':<{width}}  {'format':<20} {'frames':>6} {'fps':>8} {'dur_s':>7} {'speed_m/s':>9} {'fk_err_m':>9}"
        f" {'speed/reach':>11}  joint"
    )
    print(header)
    for path, ranges in specs:
        try:
            clip, bvh_summary = _load(path, ranges)
        except MotionFileError as e:
            errors.append({"path": e.path, "error": e.problem})
            print(f"ERROR {e.path}: {e.problem}")
            continue
        except Exception as e:  # noqa: BLE001 - report, never a traceback
            problem = " ".join(f"{type(e).__name__}: {e}".split())
            errors.append({"path": str(path), "error": problem})
            print(f"ERROR {path}: {problem}")
            continue
        r = _row(clip, _label(path, ranges)) | speed_fields(clip, args.servo_damping, args.sim_hz)
        rows.append(r)
        sword_shield.append(clip.sword_shield)
        print(
            f"{r['path']:<{width}}  {r['format']:<20} {r['frames']:>6d} {r['fps']:>8.3f} "
            f"{r['duration_s']:>7.2f} {r['root_speed_mps']:>9.3f} {r['fk_error_m']:>9.2e} {_ratio_cell(r)}"
        )
        if bvh_summary:
            r["retarget"] = bvh_summary
            print(f"  bvh: {bvh_summary}")
    max_fk = max((r["fk_error_m"] for r in rows), default=float("nan"))
    print(f"{len(rows)} clips loaded, {len(errors)} errors, max fk error {max_fk:.2e} m")
    servo_info = _servo_summary(rows, sword_shield, args.servo_damping, args.sim_hz)
    if args.json:
        with open(args.json, "w") as fh:
            report = {"clips": rows, "errors": errors, "servo": servo_info}
            json.dump(finite_or_none(report), fh, indent=1, allow_nan=False)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
