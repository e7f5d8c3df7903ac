"""A real headless Chromium for tests, driven over the DevTools protocol with the stdlib only.

Chromium is started with ``--remote-debugging-pipe``: it reads protocol messages from file
descriptor 3 and writes to 4, each a JSON object ended by a NUL byte (what Playwright
does). No websocket library, no chromedriver session, no network port: just two pipes.

Install (Debian/Ubuntu): ``apt-get install -y chromium chromium-driver``. Tests that
need it skip with that line as the reason when no browser is found; ``BOMC_CHROMIUM``
may name another Chromium-compatible executable.
"""

from __future__ import annotations

import base64
import contextlib
import fcntl
import json
import os
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

APT_PACKAGES = ("chromium", "chromium-driver")
INSTALL_HINT = f"no headless Chromium: apt-get install -y {' '.join(APT_PACKAGES)}"
CANDIDATES = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")


def find_chromium() -> str | None:
    """The browser to use: ``$BOMC_CHROMIUM``, Debian's ``/usr/bin/chromium``, or one on PATH."""
    named = os.environ.get("BOMC_CHROMIUM")
    if named:
        return named if os.access(named, os.X_OK) else None
    for path in CANDIDATES:
        if os.access(path, os.X_OK):
            return path
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


class BrowserError(RuntimeError):
    pass


class Browser:
    """One headless Chromium with one page; ``open``, ``evaluate``, ``wait_for``, ``screenshot``."""

    def __init__(self, executable: str | None = None, size: tuple[int, int] = (1400, 900),
                 timeout: float = 20.0):
        exe = executable or find_chromium()
        if exe is None:
            raise BrowserError(INSTALL_HINT)
        self.size = size
        self.timeout = timeout
        self.errors: list[str] = []  # uncaught page exceptions and console.error lines
        self._profile = tempfile.mkdtemp(prefix="bomc-chromium-")
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()

        def wire_pipes() -> None:  # in the child: our pipe ends become its fds 3 and 4
            a = fcntl.fcntl(to_browser_r, fcntl.F_DUPFD, 10)
            b = fcntl.fcntl(from_browser_w, fcntl.F_DUPFD, 10)
            os.dup2(a, 3)
            os.dup2(b, 4)

        args = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--remote-debugging-pipe", f"--user-data-dir={self._profile}",
                f"--window-size={size[0]},{size[1]}",
                "--no-first-run", "--no-default-browser-check", "--hide-scrollbars", "--mute-audio",
                "--disable-background-networking", "--disable-extensions", "about:blank"]
        quiet = subprocess.DEVNULL
        self.proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=wire_pipes,
                                     stdin=quiet, stdout=quiet, stderr=quiet)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._next_id = 0
        self._replies: dict[int, dict[str, Any]] = {}
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        try:
            target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
            attached = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})
            self.session = attached["sessionId"]
            for domain in ("Page.enable", "Runtime.enable"):
                self.call(domain, session=True)
            metrics = {"width": size[0], "height": size[1], "deviceScaleFactor": 1, "mobile": False}
            self.call("Emulation.setDeviceMetricsOverride", metrics, session=True)
        except Exception:
            self.close()
            raise

    # ----------------------------------------------------------------- protocol
    def _read(self) -> None:
        buffer = b""
        while True:
            try:
                chunk = os.read(self._from_browser, 1 << 16)
            except OSError:
                chunk = b""
            if not chunk:
                with self._cond:
                    self._replies[-1] = {"error": {"message": "the browser exited"}}
                    self._cond.notify_all()
                return
            buffer += chunk
            *messages, buffer = buffer.split(b"\0")
            for raw in messages:
                self._dispatch(json.loads(raw))

    def _dispatch(self, message: dict[str, Any]) -> None:
        method = message.get("method")
        if method == "Runtime.exceptionThrown":
            details = message["params"]["exceptionDetails"]
            self.errors.append(details.get("exception", {}).get("description") or details.get("text", "?"))
        elif method == "Runtime.consoleAPICalled" and message["params"].get("type") == "error":
            args = message["params"]["args"]
            self.errors.append(" ".join(str(a.get("value", a.get("description", ""))) for a in args))
        if "id" in message:
            with self._cond:
                self._replies[message["id"]] = message
                self._cond.notify_all()

    def call(self, method: str, params: dict[str, Any] | None = None,
             session: bool = False) -> dict[str, Any]:
        """Send one protocol command and wait for its reply (``session``: to the page)."""
        with self._cond:
            self._next_id += 1
            ident = self._next_id
        message: dict[str, Any] = {"id": ident, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = self.session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + self.timeout
        with self._cond:
            while ident not in self._replies and -1 not in self._replies:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise BrowserError(f"{method}: no reply within {self.timeout} s")
                self._cond.wait(left)
            reply = self._replies.pop(ident, None) or self._replies[-1]
        if "error" in reply:
            raise BrowserError(f"{method}: {reply['error'].get('message')}")
        return reply.get("result", {})

    # --------------------------------------------------------------------- page
    def open(self, url: str) -> None:
        """Navigate and wait until the document has loaded."""
        self.call("Page.navigate", {"url": url}, session=True)
        time.sleep(0.05)  # let the old document go before asking for the new one's readyState
        self.wait_for("document.readyState === 'complete' && location.href !== 'about:blank'",
                      what=f"load {url}")

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page (promises awaited)."""
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                "awaitPromise": True}, session=True)
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            raise BrowserError(f"{expression!r}: {details.get('exception', {}).get('description', details)}")
        return result.get("result", {}).get("value")

    def wait_for(self, expression: str, timeout: float | None = None, what: str = "") -> Any:
        """Poll ``expression`` until it is truthy; returns its value, raises with the last one."""
        deadline = time.monotonic() + (timeout if timeout is not None else self.timeout)
        value: Any = None
        while time.monotonic() < deadline:
            try:
                value = self.evaluate(expression)
            except BrowserError as exc:  # the page may be between documents
                value = str(exc)
            else:
                if value:
                    return value
            time.sleep(0.05)
        raise AssertionError(f"timed out waiting for {what or expression}; last value: {value!r}")

    def screenshot(self, path: str | Path) -> Path:
        data = self.call("Page.captureScreenshot", {"format": "png"}, session=True)["data"]
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(data))
        return path

    def close(self) -> None:
        try:
            if self.proc.poll() is None:
                self.call("Browser.close")
        except (BrowserError, OSError):
            pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for fd in (self._to_browser, self._from_browser):
            with contextlib.suppress(OSError):
                os.close(fd)
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
