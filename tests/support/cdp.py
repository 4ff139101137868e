"""Headless Chromium driven through its DevTools protocol over a pipe (`--remote-debugging-pipe`:
JSON messages separated by NUL on file descriptors 3 and 4), with the standard library only:
load a page, run JavaScript, move the mouse, take screenshots, collect console errors.

    with Browser(exe, tmp_path) as b:
        b.open(path)                      # waits for the load event
        b.evaluate("1 + 1")               # -> 2 (promises awaited)
        b.drag(x0, y0, x1, y1)
        b.screenshot(png_path, clip)
        b.errors                          # console errors and uncaught exceptions, as text
"""
from __future__ import annotations

import base64
import fcntl
import json
import os
import shutil
import subprocess
import time
from pathlib import Path

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


class Browser:
    def __init__(self, exe: str, workdir: Path, width: int = 1280, height: int = 900, timeout: float = 120):
        self.profile = Path(workdir) / "cdp-profile"
        to_child, self._w = os.pipe()
        self._r, from_child = os.pipe()

        def fds():                                  # the child's fd 3 reads, fd 4 writes
            a, b = (fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (to_child, from_child))
            os.dup2(a, 3)
            os.dup2(b, 4)
        self.proc = subprocess.Popen(
            [exe, *FLAGS, "--remote-debugging-pipe", f"--user-data-dir={self.profile}",
             f"--window-size={width},{height}", "about:blank"],
            preexec_fn=fds, pass_fds=(3, 4), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(to_child), os.close(from_child)
        self.timeout, self._id, self._buf, self.events, self.errors = timeout, 0, b"", [], []
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        for domain in ("Page", "Runtime", "Log"):
            self.call(f"{domain}.enable", session=True)

    # ------------------------------------------------------------ the protocol
    def _read(self) -> dict:
        while b"\0" not in self._buf:
            chunk = os.read(self._r, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the pipe")
            self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        m = json.loads(msg)
        if m.get("method") in ("Runtime.exceptionThrown",):
            self.errors.append(json.dumps(m["params"]["exceptionDetails"])[:500])
        elif m.get("method") == "Runtime.consoleAPICalled" and m["params"]["type"] == "error":
            self.errors.append(" ".join(str(a.get("value", a.get("description", ""))) for a in m["params"]["args"]))
        elif m.get("method") == "Log.entryAdded" and m["params"]["entry"]["level"] == "error":
            self.errors.append(m["params"]["entry"]["text"])
        return m

    def call(self, method: str, session: bool = False, **params):
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params}
        if session:
            msg["sessionId"] = self.session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        end = time.monotonic() + self.timeout
        while time.monotonic() < end:
            m = self._read()
            if m.get("id") == self._id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m["result"]
            self.events.append(m)
        raise TimeoutError(method)

    def wait_event(self, method: str):
        for k, m in enumerate(self.events):
            if m.get("method") == method:
                return self.events.pop(k)
        end = time.monotonic() + self.timeout
        while time.monotonic() < end:
            m = self._read()
            if m.get("method") == method:
                return m
            self.events.append(m)
        raise TimeoutError(method)

    # ------------------------------------------------------------ the page
    def open(self, path: Path) -> float:
        """Load a file; the seconds until its load event."""
        t0 = time.monotonic()
        self.events.clear()
        self.call("Page.navigate", session=True, url=Path(path).resolve().as_uri())
        self.wait_event("Page.loadEventFired")
        return time.monotonic() - t0

    def evaluate(self, expression: str):
        r = self.call("Runtime.evaluate", session=True, expression=expression, awaitPromise=True, returnByValue=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def drag(self, x0: float, y0: float, x1: float, y1: float, steps: int = 12):
        self.call("Input.dispatchMouseEvent", session=True, type="mouseMoved", x=x0, y=y0)
        self.call("Input.dispatchMouseEvent", session=True, type="mousePressed", x=x0, y=y0, button="left",
                  clickCount=1, buttons=1)
        for k in range(1, steps + 1):
            self.call("Input.dispatchMouseEvent", session=True, type="mouseMoved", button="left", buttons=1,
                      x=x0 + (x1 - x0) * k / steps, y=y0 + (y1 - y0) * k / steps)
        self.call("Input.dispatchMouseEvent", session=True, type="mouseReleased", x=x1, y=y1, button="left",
                  clickCount=1, buttons=0)

    def screenshot(self, png: Path, clip: dict | None = None) -> Path:
        params = {"format": "png", "captureBeyondViewport": True}
        if clip:
            params["clip"] = {**clip, "scale": 1}
        Path(png).write_bytes(base64.b64decode(self.call("Page.captureScreenshot", session=True, **params)["data"]))
        return Path(png)

    def close(self):
        try:
            self.call("Browser.close")
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._r), os.close(self._w)
        shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
