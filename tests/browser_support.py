"""A minimal DevTools-protocol client for Debian's chromium, headless, network off (tests and scripts/report_timing.py).

Driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``:
the browser reads commands on fd 3 and writes replies on fd 4, each a JSON
message ended by a NUL byte), so a caller sees what a user's browser does:
console errors, uncaught exceptions, every request the page makes, and the
DOM after plotly.js has drawn. Nothing is installed; CHROMIUM is None where
no chromium is (``.ci/run`` installs it).
"""

from __future__ import annotations

import fcntl
import json
import os
import select
import subprocess
import time
from pathlib import Path
from typing import Any

from ci_mode import chromium

CHROMIUM = chromium()  # $XVAL_CHROMIUM, else on PATH or /usr/bin/chromium (tests/ci_mode.py)

#: Flags from the issue, plus the DevTools pipe and everything that keeps the browser off the network.
FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--remote-debugging-pipe",
    # Any request that tried to leave would fail here, and the test below would see it.
    "--proxy-server=127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND",
    "--allow-file-access-from-files",
]
#: Seconds to wait for the browser and the page.
TIMEOUT = 90


class DevTools:
    """A minimal DevTools-protocol client over the browser's fd 3 / fd 4 pipe."""

    def __init__(self, profile: Path) -> None:
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()
        # Lift the browser's ends above 9 (close-on-exec) so that putting them on 3 and 4 cannot clobber them.
        high = [fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10) for fd in (to_browser_r, from_browser_w)]
        os.close(to_browser_r)
        os.close(from_browser_w)

        def onto_3_and_4() -> None:  # in the child, before exec; dup2 leaves the copies inheritable
            os.dup2(high[0], 3)
            os.dup2(high[1], 4)

        profile.mkdir(parents=True, exist_ok=True)
        self.log = profile.with_name(profile.name + ".log")
        with self.log.open("wb") as log:
            self.process = subprocess.Popen(
                [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", "about:blank"],
                preexec_fn=onto_3_and_4, close_fds=False, stdin=subprocess.DEVNULL, stdout=log, stderr=log,
            )
        for fd in high:
            os.close(fd)
        self._buffer = b""
        self._next_id = 0
        self.events: list[dict[str, Any]] = []

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=10)
        except Exception:
            pass
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        os.close(self._to_browser)
        os.close(self._from_browser)

    def _receive(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([self._from_browser], [], [], remaining)[0]:
                raise TimeoutError(f"no reply from chromium; its log: {self.log.read_text(errors='replace')[-2000:]}")
            chunk = os.read(self._from_browser, 1 << 20)
            if not chunk:
                raise ConnectionError(f"chromium closed the pipe; its log: {self.log.read_text(errors='replace')[-2000:]}")
            self._buffer += chunk
        message, _, self._buffer = self._buffer.partition(b"\0")
        return json.loads(message)

    def call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None,
             timeout: float = TIMEOUT) -> dict[str, Any]:
        """Send one command and return its result; events that arrive meanwhile are kept in ``events``."""
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            reply = self._receive(deadline)
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            if "method" in reply:
                self.events.append(reply)

    def wait_for(self, method: str, timeout: float = TIMEOUT) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while True:
            for event in self.events:
                if event["method"] == method:
                    return event
            self.events.append(self._receive(deadline))

    def evaluate(self, expression: str, session: str) -> Any:
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")


class Page:
    """One report opened in a fresh headless chromium, offline, at ``width`` × ``height`` px.

    ``ready_ms`` : ms from navigation start until the page says it is interactive (its status element's
    ``data-ready-ms``: plotly.js unpacked and the plots of the first screen drawn).
    """

    def __init__(self, report: Path, profile: Path, width: int = 1300, height: int = 1000, timeout: float = TIMEOUT) -> None:
        self.browser = DevTools(profile)
        try:
            target = self.browser.call("Target.createTarget", {"url": "about:blank"})["targetId"]
            self.session = self.browser.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
            for domain in ("Runtime", "Log", "Network", "Page"):
                self.browser.call(f"{domain}.enable", session=self.session)
            self.browser.call("Network.emulateNetworkConditions",
                              {"offline": True, "latency": 0, "downloadThroughput": -1, "uploadThroughput": -1}, self.session)
            self.resize(width, height)
            self.browser.call("Page.navigate", {"url": report.resolve().as_uri()}, self.session)
            self.browser.wait_for("Page.loadEventFired", timeout)
            self.state = self.wait('document.getElementById("xval-render-status").getAttribute("data-state") !== "pending"', timeout)
            self.ready_ms = self.evaluate('Number(document.getElementById("xval-render-status").getAttribute("data-ready-ms"))')
        except BaseException:
            self.browser.close()
            raise

    def evaluate(self, expression: str) -> Any:
        return self.browser.evaluate(expression, self.session)

    def await_promise(self, expression: str, timeout: float = TIMEOUT) -> Any:
        result = self.browser.call("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                        "awaitPromise": True}, self.session, timeout)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait(self, expression: str, timeout: float = 30) -> Any:
        """Poll ``expression`` until it is truthy; its value, or TimeoutError."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = self.evaluate(expression)
            if value:
                return value
            time.sleep(0.05)
        raise TimeoutError(f"not true within {timeout} s: {expression}")

    def resize(self, width: int, height: int) -> None:
        self.browser.call("Emulation.setDeviceMetricsOverride",
                          {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}, self.session)

    def screenshot(self, path: Path, height_limit: int = 12000, top: float = 0) -> None:
        """A PNG of the page from ``top`` px down (at most ``height_limit`` px)."""
        import base64

        height = self.evaluate("document.documentElement.scrollHeight")
        width = self.evaluate("document.documentElement.clientWidth")
        shot = self.browser.call("Page.captureScreenshot", {
            "format": "png", "captureBeyondViewport": True,
            "clip": {"x": 0, "y": top, "width": width, "height": min(height - top, height_limit), "scale": 1},
        }, self.session)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(shot["data"]))

    def errors(self) -> list[str]:
        return [json.dumps(e.get("params", {}))[:500] for e in self.browser.events if is_error(e)]

    def requests(self) -> list[str]:
        return [e["params"]["request"]["url"] for e in self.browser.events if e["method"] == "Network.requestWillBeSent"]

    def close(self) -> None:
        self.browser.close()

    def __enter__(self) -> "Page":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def is_error(event: dict[str, Any]) -> bool:
    """Whether a DevTools event is a console error, an uncaught exception or an error log entry."""
    method, params = event["method"], event.get("params", {})
    return (method == "Runtime.exceptionThrown"
            or (method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"))
            or (method == "Log.entryAdded" and params["entry"].get("level") == "error"))
