"""Checking a page in headless Chromium (tests, and a quick look at a replay page without a
display): ``check_in_browser`` opens it over the Chrome DevTools Protocol, shows a frame, collects
errors and takes a screenshot. Kept apart from ``replay_html`` (which writes the pages) because it
is a small protocol client with nothing of the replay in it but ``window.__replay``.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
from pathlib import Path
from collections.abc import Sequence

CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-default-apps",
    "--disable-extensions",
    "--mute-audio",
    "--hide-scrollbars",
    # WebGL without a GPU: SwiftShader (newer Chromium wants the 'unsafe' opt-in for it).
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
)


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome binary (``$CHROMIUM``, /usr/bin/chromium, or on PATH) or None."""
    import shutil

    for c in (os.environ.get("CHROMIUM"), "/usr/bin/chromium", "chromium", "chromium-browser", "google-chrome"):
        if c and (os.path.isfile(c) and os.access(c, os.X_OK) or (os.sep not in c and shutil.which(c))):
            return c if os.sep in c else shutil.which(c)
    return None


class _PipeCDP:
    """Chrome DevTools Protocol over ``--remote-debugging-pipe`` (fd 3 in, fd 4 out): no ports,
    no websocket library."""

    def __init__(self, chromium: str, user_data_dir: str, extra_flags: Sequence[str] = ()):
        import fcntl
        import shutil
        import subprocess

        cmd_r, self._cmd_w = os.pipe()
        self._res_r, res_w = os.pipe()
        # Chromium's ends go to fds >= 10 first, so that they cannot collide with 3 and 4.
        hi = []
        for fd in (cmd_r, res_w):
            hi.append(fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10))
            os.close(fd)
        cmd_r, res_w = hi
        argv = [
            chromium,
            *CHROMIUM_FLAGS,
            *extra_flags,
            f"--user-data-dir={user_data_dir}",
            "--remote-debugging-pipe",
            "about:blank",
        ]
        from jaxmotion.viz.render import quiet_fork

        # bash moves our pipe ends onto fds 3 and 4, where Chromium expects them.
        with quiet_fork():
            self.proc = subprocess.Popen(
                [
                    shutil.which("bash") or "/bin/bash",
                    "-c",
                    f'exec "$@" 3<&{cmd_r} 4>&{res_w} {cmd_r}<&- {res_w}>&-',
                    "bash",
                    *argv,
                ],
                pass_fds=(cmd_r, res_w),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        os.close(cmd_r)
        os.close(res_w)
        self._buf = b""
        self._id = 0
        self.events: list[dict] = []

    def _read_message(self, deadline: float) -> dict:
        import select
        import time

        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("no answer from Chromium")
            ready, _, _ = select.select([self._res_r], [], [], left)
            if ready:
                chunk = os.read(self._res_r, 1 << 20)
                if not chunk:
                    raise RuntimeError("Chromium closed the DevTools pipe")
                self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def send(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 30.0) -> dict:
        import time

        self._id += 1
        m = {"id": self._id, "method": method, "params": params or {}}
        if session:
            m["sessionId"] = session
        os.write(self._cmd_w, json.dumps(m).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            r = self._read_message(deadline)
            if r.get("id") == self._id:
                if "error" in r:
                    raise RuntimeError(f"{method}: {r['error']}")
                return r.get("result", {})
            self.events.append(r)

    def pump(self, seconds: float) -> None:
        """Collects events for ``seconds``."""
        import time

        deadline = time.monotonic() + seconds
        try:
            while True:
                self.events.append(self._read_message(deadline))
        except TimeoutError:
            pass

    def close(self) -> None:
        import subprocess

        with contextlib.suppress(Exception):
            self.send("Browser.close", timeout=5)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for fd in (self._cmd_w, self._res_r):
            with contextlib.suppress(OSError):
                os.close(fd)


def check_in_browser(
    html_path: str | os.PathLike,
    png_path: str | os.PathLike | None = None,
    width: int = 800,
    height: int = 600,
    frame: int | None = None,
    chromium: str | None = None,
    timeout: float = 60.0,
) -> dict:
    """Opens a replay page in headless Chromium, shows ``frame`` (None: the middle one), and
    reports what happened.

    Returns:
        ``{"ready": bool, "errors": [str], "warnings": [str], "png": path or None}``, where errors
        are uncaught exceptions, ``console.error`` calls and error-level log entries (e.g. a
        failed load). Raises FileNotFoundError when no Chromium is found.
    """
    import tempfile
    import time

    chromium = chromium or find_chromium()
    if chromium is None:
        raise FileNotFoundError("no Chromium found (apt-get install chromium)")
    url = Path(html_path).resolve().as_uri()
    with tempfile.TemporaryDirectory(prefix="jaxmotion-chromium-") as udd:
        cdp = _PipeCDP(chromium, udd)
        try:
            target = cdp.send("Target.createTarget", {"url": "about:blank"}, timeout=timeout)["targetId"]
            s = cdp.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
            for m in ("Runtime.enable", "Log.enable", "Page.enable"):
                cdp.send(m, session=s)
            cdp.send(
                "Emulation.setDeviceMetricsOverride",
                {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
                session=s,
            )
            cdp.send("Page.navigate", {"url": url}, session=s)
            deadline = time.monotonic() + timeout
            ready = False
            while time.monotonic() < deadline:
                r = cdp.send(
                    "Runtime.evaluate",
                    {"expression": "!!(window.__replay && window.__replay.ready)", "returnByValue": True},
                    session=s,
                )
                ready = bool(r.get("result", {}).get("value"))
                failed = cdp.send(
                    "Runtime.evaluate",
                    {"expression": "!!(window.__replay && !window.__replay.ready)", "returnByValue": True},
                    session=s,
                )
                if ready or failed.get("result", {}).get("value"):
                    break
                cdp.pump(0.2)
            if ready:
                expr = (
                    "window.__replay.setFrame("
                    + ("Math.floor(window.__replay.frames / 2)" if frame is None else str(int(frame)))
                    + ")"
                )
                cdp.send("Runtime.evaluate", {"expression": expr}, session=s)
            cdp.pump(0.5)
            png = None
            if png_path is not None:
                shot = cdp.send("Page.captureScreenshot", {"format": "png"}, session=s, timeout=timeout)
                png = Path(png_path)
                png.write_bytes(base64.b64decode(shot["data"]))
            cdp.pump(0.2)
        finally:
            cdp.close()
    errors, warnings = [], []
    for e in cdp.events:
        p = e.get("params", {})
        if e.get("method") == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            errors.append(d.get("exception", {}).get("description") or d.get("text", "exception"))
        elif e.get("method") == "Runtime.consoleAPICalled":
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", []))
            if p.get("type") in ("error", "assert"):
                errors.append(text)
            elif p.get("type") == "warning":
                warnings.append(text)
        elif e.get("method") == "Log.entryAdded":
            entry = p.get("entry", {})
            if entry.get("level") == "error":
                errors.append(f"{entry.get('source')}: {entry.get('text')} {entry.get('url', '')}".strip())
            elif entry.get("level") == "warning":
                warnings.append(entry.get("text", ""))
    return {"ready": ready, "errors": errors, "warnings": warnings, "png": png}
