"""Fuzz test of the clip loaders: every malformed clip gives one clear ``MotionFileError``.

``fuzz_cases()`` writes malformed clips of every format the loaders read (CompositeMotion JSON in
both layouts, DeepMimic ``.txt``/``.json``, poselib ``.npy`` for both characters, other suffixes):
truncated and empty files, NaN/inf, absurd magnitudes, wrong shapes and types, pickles that call
functions, and finite but physically impossible motion (fps 1e300, teleports, a root under the
floor). For each, the motion CLI must print exactly one ``ERROR <path>: <problem>`` line and exit
non-zero without a traceback, ``load_clips`` must raise ``MotionFileError`` (nothing else), and
nothing may appear on disk besides the clip (a pickle that ran code would leave a file behind).
"""

from __future__ import annotations

import os

import pytest

from fuzz_clip_cases import fuzz_cases
from jaxmotion.motion.__main__ import main as motion_main
from jaxmotion.motion.loaders import MotionFileError, load_clips

CASES = fuzz_cases()


def _files(root) -> set[str]:
    return {os.path.relpath(os.path.join(d, f), root) for d, dirs, fs in os.walk(root) for f in fs + dirs}


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_malformed_clip_is_one_clear_error(case, tmp_path, monkeypatch, capsys):
    name, suffix, make = case
    monkeypatch.chdir(tmp_path)
    path = tmp_path / f"clip{suffix}"
    path.write_bytes(make())
    made = _files(tmp_path)

    rc = motion_main([str(path)])
    out, err = capsys.readouterr()
    assert rc != 0
    assert "Traceback" not in out + err
    errors = [line for line in out.splitlines() if line.startswith("ERROR ")]
    assert len(errors) == 1 and errors[0].startswith(f"ERROR {path}: "), out
    assert len(errors[0]) > len(f"ERROR {path}: ") + 5

    with pytest.raises(MotionFileError) as info:
        load_clips([str(path)])
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    assert _files(tmp_path) == made, "a clip wrote files (a pickle ran code?)"


def test_fuzz_case_count():
    assert 150 <= len(CASES) <= 260 and len({c[0] for c in CASES}) == len(CASES)
