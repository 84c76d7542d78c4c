"""Lists motion files: ``python -m jaxmotion.motion <file-or-folder>[range] [...] [--json FILE]``.

Prints one row per file (path, format, frames, fps, duration, mean root speed, fk error) and
``ERROR <path>: <message>`` for files that fail to load; the exit code is 1 if any file failed.
A file may name frame ranges as training does, ``squat.json[0:33,58:]`` or ``walk.json[-30:]``
(Python slices). ``--json`` writes the table as strict JSON (non-finite numbers as null); a
``--json`` path whose folder does not exist is refused before anything is loaded (exit 2).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

from jaxmotion.config.errors import JaxmotionError, cli_errors
from jaxmotion.motion.clip import mean_root_speed
from jaxmotion.motion.frame_ranges import Ranges, format_ranges
from jaxmotion.motion.loaders import MotionFileError, find_clip_specs, load_clip_frames


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


@cli_errors
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m jaxmotion.motion", description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", help="motion files or folders (searched recursively); file[a:b] for frames")
    ap.add_argument("--json", metavar="FILE", help="also write the table as JSON to FILE")
    args = ap.parse_args(argv)
    if args.json:
        _check_json_target(args.json)

    errors: list[dict] = []
    rows: list[dict] = []
    specs = _expand(args.paths, errors)
    for err in errors:
        print(f"ERROR {err['path']}: {err['error']}")
    width = max([len(_label(*s)) for s in specs] + [4])
    header = f"{'path':<{width}}  {'format':<20} {'frames':>6} {'fps':>8} {'dur_s':>7} {'speed_m/s':>9} {'fk_err_m':>9}"
    print(header)
    for path, ranges in specs:
        try:
            clip = load_clip_frames(path, ranges)
        except MotionFileError as e:
            errors.append({"path": e.path, "error": e.problem})
            print(f"ERROR {e.path}: {e.problem}")
            continue
        except Exception as e:  # noqa: BLE001 - report, never a traceback
            problem = " ".join(f"{type(e).__name__}: {e}".split())
            errors.append({"path": str(path), "error": problem})
            print(f"ERROR {path}: {problem}")
            continue
        r = _row(clip, _label(path, ranges))
        rows.append(r)
        print(
            f"{r['path']:<{width}}  {r['format']:<20} {r['frames']:>6d} {r['fps']:>8.3f} "
            f"{r['duration_s']:>7.2f} {r['root_speed_mps']:>9.3f} {r['fk_error_m']:>9.2e}"
        )
    max_fk = max((r["fk_error_m"] for r in rows), default=float("nan"))
    print(f"{len(rows)} clips loaded, {len(errors)} errors, max fk error {max_fk:.2e} m")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(finite_or_none({"clips": rows, "errors": errors}), fh, indent=1, allow_nan=False)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
