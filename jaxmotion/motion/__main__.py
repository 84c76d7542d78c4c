"""Lists motion files: ``python -m jaxmotion.motion <file-or-folder> [...] [--json FILE]``.

Prints one row per file (path, format, frames, fps, duration, mean root speed, fk error) and
``ERROR <path>: <message>`` for files that fail to load; the exit code is 1 if any file failed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from jaxmotion.motion.clip import mean_root_speed
from jaxmotion.motion.loaders import MotionFileError, find_motion_files, load_clip


def _expand(paths: list[str], errors: list[dict]) -> list[Path]:
    files: list[Path] = []
    for p in paths:
        try:
            files += find_motion_files(p)
        except MotionFileError as e:
            errors.append({"path": e.path, "error": e.problem})
    return files


def _row(clip, path: Path) -> dict:
    return {
        "path": str(path),
        "format": clip.format,
        "frames": clip.num_frames,
        "fps": round(clip.fps, 6),
        "duration_s": round(clip.duration, 6),
        "root_speed_mps": round(mean_root_speed(clip), 6),
        "fk_error_m": clip.fk_error_m,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m jaxmotion.motion", description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", help="motion files or folders (searched recursively)")
    ap.add_argument("--json", metavar="FILE", help="also write the table as JSON to FILE")
    args = ap.parse_args(argv)

    errors: list[dict] = []
    rows: list[dict] = []
    files = _expand(args.paths, errors)
    for err in errors:
        print(f"ERROR {err['path']}: {err['error']}")
    width = max([len(str(f)) for f in files] + [4])
    header = f"{'path':<{width}}  {'format':<20} {'frames':>6} {'fps':>8} {'dur_s':>7} {'speed_m/s':>9} {'fk_err_m':>9}"
    print(header)
    for f in files:
        try:
            clip = load_clip(f)
        except MotionFileError as e:
            errors.append({"path": e.path, "error": e.problem})
            print(f"ERROR {e.path}: {e.problem}")
            continue
        except Exception as e:  # noqa: BLE001 - report, never a traceback
            errors.append({"path": str(f), "error": f"{type(e).__name__}: {e}"})
            print(f"ERROR {f}: {type(e).__name__}: {e}")
            continue
        r = _row(clip, f)
        rows.append(r)
        print(
            f"{r['path']:<{width}}  {r['format']:<20} {r['frames']:>6d} {r['fps']:>8.3f} "
            f"{r['duration_s']:>7.2f} {r['root_speed_mps']:>9.3f} {r['fk_error_m']:>9.2e}"
        )
    max_fk = max((r["fk_error_m"] for r in rows), default=float("nan"))
    print(f"{len(rows)} clips loaded, {len(errors)} errors, max fk error {max_fk:.2e} m")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"clips": rows, "errors": errors}, fh, indent=1)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
