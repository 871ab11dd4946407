"""A headless Chromium driven over the DevTools protocol: open the viewer's page, wait for
its scene and panels, read its text and take screenshots (tests and benchmarks).

No browser is downloaded: it runs the ``chromium`` found on the ``PATH`` (Debian's
package: ``apt-get install chromium``), headless, without a sandbox, with WebGL on
SwiftShader (software rendering: no GPU or display needed), a fresh profile, and the
background traffic switched off (``--disable-background-networking
--disable-component-update --disable-sync --no-first-run``). It talks to the browser
through ``websockets`` (a dependency of viser) on a port only this machine can reach.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

from ..errors import QpikError

__all__ = ["Browser", "BrowserError", "find_chromium"]

#: Executables tried, in order, when none is given.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


class BrowserError(QpikError, RuntimeError):
    """The browser could not be started, or a page did not do what was waited for."""


def find_chromium() -> str | None:
    """The path of a Chromium executable (``$QPIK_CHROMIUM``, then :data:`CHROMIUM_NAMES`
    on the ``PATH``), or ``None``."""
    given = os.environ.get("QPIK_CHROMIUM")
    if given:
        return given
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


class Browser:
    """A headless Chromium with one page.

    Args:
        width, height: the window [px].
        executable: the browser (default :func:`find_chromium`).
        timeout: seconds to wait for the browser to start.

    Use as a context manager (the browser and its profile are removed on exit).
    """

    def __init__(
        self,
        width: int = 1200,
        height: int = 800,
        executable: str | None = None,
        timeout: float = 60.0,
    ):
        from websockets.sync.client import connect

        path = executable or find_chromium()
        if path is None:
            raise BrowserError("no Chromium found (apt-get install chromium, or set QPIK_CHROMIUM)")
        self._profile = tempfile.mkdtemp(prefix="qpik-chromium-")
        args = [
            path,
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--use-gl=swiftshader",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-default-apps",
            "--disable-extensions",
            "--no-first-run",
            "--no-default-browser-check",
            "--hide-scrollbars",
            "--mute-audio",
            f"--user-data-dir={self._profile}",
            f"--window-size={width},{height}",
            "--remote-debugging-address=127.0.0.1",
            "--remote-debugging-port=0",
            "about:blank",
        ]
        self._process = subprocess.Popen(
            args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
        )
        self._next_id = 0
        try:
            port = self._devtools_port(timeout)
            page = self._page_socket(port, timeout)
            self._socket = connect(page, max_size=None, open_timeout=timeout)
            self.call("Page.enable")
            self.call("Runtime.enable")
            self.call(
                "Emulation.setDeviceMetricsOverride",
                width=width,
                height=height,
                deviceScaleFactor=1,
                mobile=False,
            )
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ protocol
    def _devtools_port(self, timeout: float) -> int:
        marker = Path(self._profile) / "DevToolsActivePort"
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                raise BrowserError(f"Chromium exited at start (code {self._process.returncode})")
            if marker.exists():
                lines = marker.read_text().split()
                if lines:
                    return int(lines[0])
            time.sleep(0.05)
        raise BrowserError(f"Chromium did not open its DevTools port within {timeout} s")

    def _page_socket(self, port: int, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=5) as r:
                targets = json.loads(r.read())
            pages = [t for t in targets if t.get("type") == "page"]
            if pages:
                return str(pages[0]["webSocketDebuggerUrl"])
            time.sleep(0.05)
        raise BrowserError("Chromium has no page to drive")

    def call(self, method: str, timeout: float = 60.0, **params: Any) -> dict[str, Any]:
        """Send a DevTools command and return its result (events are skipped)."""
        self._next_id += 1
        ident = self._next_id
        self._socket.send(json.dumps({"id": ident, "method": method, "params": params}))
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise BrowserError(f"{method}: no answer within {timeout} s")
            message = json.loads(self._socket.recv(timeout=remaining))
            if message.get("id") != ident:
                continue
            if "error" in message:
                raise BrowserError(f"{method}: {message['error']}")
            return dict(message.get("result", {}))

    # ------------------------------------------------------------------ page
    def open(self, url: str) -> None:
        """Navigate to ``url``."""
        self.call("Page.navigate", url=url)

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in result:
            raise BrowserError(f"{expression!r}: {result['exceptionDetails'].get('text')}")
        return result.get("result", {}).get("value")

    def text(self) -> str:
        """The page's visible text."""
        return str(self.evaluate("document.body ? document.body.innerText : ''") or "")

    def wait_for_text(self, *needles: str, timeout: float = 60.0) -> str:
        """Wait until the page's text holds every one of ``needles``; returns the text."""
        deadline = time.monotonic() + timeout
        text = ""
        while time.monotonic() < deadline:
            text = self.text()
            if all(n in text for n in needles):
                return text
            time.sleep(0.1)
        missing = [n for n in needles if n not in text]
        raise BrowserError(f"the page never showed {missing} within {timeout} s; it shows {text!r}")

    def wait_for(self, expression: str, timeout: float = 60.0) -> Any:
        """Wait until a JavaScript expression is truthy; returns its value."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = self.evaluate(expression)
            if value:
                return value
            time.sleep(0.1)
        raise BrowserError(f"{expression!r} stayed false for {timeout} s")

    def screenshot(self, path: str | os.PathLike | None = None) -> bytes:
        """A PNG of the page (written to ``path`` when given). Retried for a few seconds
        while a navigation leaves no page attached."""
        deadline = time.monotonic() + 10.0
        while True:
            try:
                result = self.call("Page.captureScreenshot", format="png")
                break
            except BrowserError as exc:
                if "Not attached" not in str(exc) or time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        data = base64.b64decode(result["data"])
        if path is not None:
            Path(path).write_bytes(data)
        return data

    # ------------------------------------------------------------------ closing
    def close(self) -> None:
        """Stop the browser and remove its profile."""
        socket = getattr(self, "_socket", None)
        if socket is not None:
            try:
                socket.close()
            except Exception:  # closing anyway
                pass
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait(timeout=10)
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
