"""The report in a real browser: Debian's chromium, headless, with the network off.

Driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``:
the browser reads commands on fd 3 and writes replies on fd 4, each a JSON
message ended by a NUL byte), so the test sees what a user's browser does:
console errors, uncaught exceptions, every request the page makes, and the
DOM after plotly.js has drawn. It installs nothing: it is skipped, with the
reason, where no chromium is installed (``.ci/run`` installs it).
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest

from report_support import ARTIFACTS, HOSTILE, hostile_results, run_suite_once
from reports.figures import plot_text
from reports.render import write_report

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if os.access("/usr/bin/chromium", os.X_OK) else None)

pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="no chromium here; install it with 'apt-get install -y chromium' (.ci/run does)"
)

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


#: Run in the page once plotly.js is done: per plot, what it was meant to draw and what is in the DOM.
PLOTS_DRAWN = """JSON.stringify(Array.from(document.querySelectorAll("div.xval-plot")).map(function (div) {
  var traces = div.querySelectorAll(".scatterlayer .trace");
  var lines = Array.from(div.querySelectorAll(".scatterlayer path.js-line"))
      .filter(function (p) { return (p.getAttribute("d") || "").length > 2; }).length;
  return {id: div.id, expected: Number(div.getAttribute("data-expected-traces")), drawn: traces.length,
          lines: lines, legend: Array.from(div.querySelectorAll(".legendtext")).map(function (t) { return t.textContent; })};
}))"""


def open_in_browser(report: Path, profile: Path, screenshot: Path | None = None) -> dict[str, Any]:
    """Load ``report`` offline; return its console errors, requests, plots drawn and page state."""
    browser = DevTools(profile)
    try:
        target = browser.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = browser.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Network", "Page"):
            browser.call(f"{domain}.enable", session=session)
        browser.call("Network.emulateNetworkConditions",
                     {"offline": True, "latency": 0, "downloadThroughput": -1, "uploadThroughput": -1}, session)
        browser.call("Emulation.setDeviceMetricsOverride",
                     {"width": 1300, "height": 1000, "deviceScaleFactor": 1, "mobile": False}, session)
        browser.call("Page.navigate", {"url": report.resolve().as_uri()}, session)
        browser.wait_for("Page.loadEventFired")
        deadline = time.monotonic() + TIMEOUT
        state = "pending"
        while state == "pending" and time.monotonic() < deadline:
            state = browser.evaluate('document.getElementById("xval-render-status").getAttribute("data-state")', session)
            time.sleep(0.1)
        result = {
            "state": state,
            "status": browser.evaluate('document.getElementById("xval-render-status").textContent', session),
            "plots": json.loads(browser.evaluate(PLOTS_DRAWN, session)),
            "injected": browser.evaluate("typeof window.__xval_injected", session),
        }
        if screenshot is not None:
            height = browser.evaluate("document.documentElement.scrollHeight", session)
            shot = browser.call("Page.captureScreenshot", {
                "format": "png", "captureBeyondViewport": True,
                "clip": {"x": 0, "y": 0, "width": 1300, "height": min(height, 12000), "scale": 1},
            }, session)
            screenshot.parent.mkdir(parents=True, exist_ok=True)
            screenshot.write_bytes(base64.b64decode(shot["data"]))
        events = browser.events
    finally:
        browser.close()
    result["errors"] = [_describe(e) for e in events if _is_error(e)]
    result["requests"] = [e["params"]["request"]["url"] for e in events if e["method"] == "Network.requestWillBeSent"]
    return result


def _is_error(event: dict[str, Any]) -> bool:
    method, params = event["method"], event.get("params", {})
    return (method == "Runtime.exceptionThrown"
            or (method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"))
            or (method == "Log.entryAdded" and params["entry"].get("level") == "error"))


def _describe(event: dict[str, Any]) -> str:
    return json.dumps(event.get("params", {}))[:500]


def assert_rendered_offline(result: dict[str, Any]) -> None:
    assert result["errors"] == []
    # The page itself and nothing else: no CDN, no font, no tracker.
    assert all(url.startswith(("file:", "data:", "blob:", "about:")) for url in result["requests"]), result["requests"]
    assert result["state"] == "done", result["status"]
    for plot in result["plots"]:
        assert plot["drawn"] == plot["expected"] > 0, plot
        assert plot["lines"] > 0, plot


@pytest.fixture(scope="module")
def small_report(tmp_path_factory):
    results = run_suite_once(tmp_path_factory.getbasetemp())
    return write_report(results, tmp_path_factory.mktemp("browser") / "small.html").path


def test_small_report_draws_every_plot_offline_without_console_errors(small_report, tmp_path):
    result = open_in_browser(small_report, tmp_path / "profile", screenshot=ARTIFACTS / "report-small.png")
    assert_rendered_offline(result)
    assert [p["id"] for p in result["plots"]] == ["s0-wp", "s0-dt", "s0-ts", "s0-path",
                                                   "s1-wp", "s1-dt", "s1-ts", "s1-path"]
    assert result["status"] == "8 plots drawn."
    assert (ARTIFACTS / "report-small.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_hostile_strings_show_as_text_and_run_nothing(tmp_path_factory, tmp_path):
    report = write_report(hostile_results(tmp_path_factory.getbasetemp()), tmp_path / "hostile.html").path
    result = open_in_browser(report, tmp_path / "profile", screenshot=ARTIFACTS / "report-escaping.png")
    assert_rendered_offline(result)
    assert result["injected"] == "undefined"
    # plotly.js shows the legend entry as the literal string from the results file.
    legends = [text for plot in result["plots"] for text in plot["legend"]]
    assert HOSTILE in legends, legends
    assert plot_text(HOSTILE) not in legends
