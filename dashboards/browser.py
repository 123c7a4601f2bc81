"""Open a rendered report in headless Chromium and record what the page did.

Used by the browser test and for the README screenshot. Talks the Chrome DevTools Protocol
over ``--remote-debugging-pipe`` (JSON messages separated by NUL bytes on file descriptors 3
and 4 of the browser process), so no websocket client and no open port are needed.

Recorded: every request the page started (``Network.requestWillBeSent``), console messages
(``Runtime.consoleAPICalled``), uncaught exceptions (``Runtime.exceptionThrown``), browser log
entries (``Log.entryAdded``: failed loads, Content-Security-Policy violations) and a PNG
screenshot.

References
----------
.. [1] Chrome DevTools Protocol, https://chromedevtools.github.io/devtools-protocol/
       (domains Target, Page, Network, Runtime, Log, Emulation).
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from dashboards.errors import ReportError

#: Flags for a quiet, offline, sandbox-free headless run (we run as root in CI containers).
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--mute-audio",
    # Nothing may resolve: a request that tries to leave is still recorded (requestWillBeSent
    # fires first) but never reaches the network.
    "--host-resolver-rules=MAP * ~NOTFOUND",
)
CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome binary (``STORMLANE_CHROMIUM`` overrides), or ``None``."""
    env = os.environ.get("STORMLANE_CHROMIUM")
    if env:
        return env
    for name in CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


@dataclass
class PageVisit:
    """What happened when a page was opened.

    Attributes
    ----------
    url : str
    requests : list of str
        URL of every request the page started, in order (the document itself included).
    console : list of (level, text)
        Console API calls and browser log entries.
    exceptions : list of str
        Uncaught JavaScript exceptions.
    screenshot_png : bytes
    title : str
        ``document.title`` after load.
    values : dict
        The results of the ``evaluate`` expressions (JSON values), by name.
    pdf : bytes
        The page printed to PDF (``print_pdf``), as Chromium's "Save as PDF" prints it.
    """

    url: str
    requests: list = field(default_factory=list)
    console: list = field(default_factory=list)
    exceptions: list = field(default_factory=list)
    screenshot_png: bytes = b""
    title: str = ""
    values: dict = field(default_factory=dict)
    pdf: bytes = b""

    @property
    def errors(self) -> list[str]:
        """Console errors and exceptions."""
        return [text for level, text in self.console if level in ("error", "assert")] + list(self.exceptions)

    def requests_leaving(self, allowed=("file:", "data:")) -> list[str]:
        """Requests whose scheme is not in ``allowed`` (``data:`` URIs are bytes inside the page)."""
        return [u for u in self.requests if not u.startswith(allowed)]


class _Pipe:
    def __init__(self, proc, write_fd, read_fd, timeout_s):
        self.proc, self.w, self.r, self.deadline = proc, write_fd, read_fd, time.monotonic() + timeout_s
        self.buf = b""
        self.next_id = 0
        self.events: list[dict] = []

    def _read_message(self) -> dict:
        while b"\0" not in self.buf:
            left = self.deadline - time.monotonic()
            if left <= 0:
                raise ReportError("headless Chromium did not answer in time")
            ready, _, _ = select.select([self.r], [], [], min(left, 1.0))
            if ready:
                chunk = os.read(self.r, 1 << 20)
                if not chunk:
                    raise ReportError(f"headless Chromium closed the DevTools pipe (exit code {self.proc.poll()})")
                self.buf += chunk
        raw, self.buf = self.buf.split(b"\0", 1)
        return json.loads(raw)

    def call(self, method: str, session: str | None = None, **params) -> dict:
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params}
        if session:
            msg["sessionId"] = session
        os.write(self.w, json.dumps(msg).encode() + b"\0")
        while True:
            reply = self._read_message()
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise ReportError(f"DevTools {method} failed: {reply['error'].get('message')}")
                return reply.get("result", {})
            if "method" in reply:
                self.events.append(reply)

    def wait_for(self, method: str, timeout_s: float) -> bool:
        end = min(self.deadline, time.monotonic() + timeout_s)
        if any(e["method"] == method for e in self.events):
            return True
        saved = self.deadline
        self.deadline = end
        try:
            while True:
                ev = self._read_message()
                if "method" in ev:
                    self.events.append(ev)
                    if ev["method"] == method:
                        return True
        except ReportError:
            return False
        finally:
            self.deadline = saved

    def drain(self, quiet_s: float) -> None:
        """Collect events until none arrives for ``quiet_s`` seconds."""
        while True:
            ready, _, _ = select.select([self.r], [], [], quiet_s)
            if not ready and b"\0" not in self.buf:
                return
            if ready:
                chunk = os.read(self.r, 1 << 20)
                if not chunk:
                    return
                self.buf += chunk
            while b"\0" in self.buf:
                raw, self.buf = self.buf.split(b"\0", 1)
                msg = json.loads(raw)
                if "method" in msg:
                    self.events.append(msg)


def _evaluate(pipe, session, expressions: dict | None, values: dict) -> None:
    """Evaluate each expression by the DevTools protocol (a promise awaited) into ``values``."""
    for name, expression in (expressions or {}).items():
        reply = pipe.call("Runtime.evaluate", session, expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in reply:
            raise ReportError(f"evaluate {name}: {reply['exceptionDetails'].get('text', 'exception')}")
        values[name] = reply.get("result", {}).get("value")


def visit(
    path_or_url,
    *,
    width: int = 1280,
    height: int = 900,
    full_page: bool = False,
    chromium: str | None = None,
    timeout_s: float = 60.0,
    evaluate: dict | None = None,
    print_pdf: bool = False,
    print_evaluate: dict | None = None,
) -> PageVisit:
    """Open a page headless, let it settle, take a screenshot and return what it did.

    Parameters
    ----------
    path_or_url : str or Path
        A local file (opened as ``file://``) or a URL.
    width, height : int
        Viewport size in CSS pixels.
    full_page : bool
        Screenshot of the whole page instead of the first viewport.
    chromium : str, optional
        Browser binary; default :func:`find_chromium`.
    evaluate : dict of str -> str, optional
        JavaScript expressions evaluated by the DevTools protocol after load, in order (the page's
        Content-Security-Policy binds the page's own scripts, not the inspector's); a promise is
        awaited. Their JSON values land in ``PageVisit.values`` (layout measures, anchor checks).
    print_pdf : bool
        Also print the page to PDF (print media, backgrounds) into ``PageVisit.pdf``.
    print_evaluate : dict of str -> str, optional
        Like ``evaluate``, with the print style sheet applied (CSS media emulated as ``print``,
        what "Print" and "Save as PDF" lay out); after ``evaluate``, into ``PageVisit.values``.
    """
    binary = chromium or find_chromium()
    if binary is None:
        raise ReportError("no Chromium found (install Debian's 'chromium' package or set STORMLANE_CHROMIUM)")
    text = str(path_or_url)
    url = text if "://" in text else Path(text).resolve().as_uri()
    profile = tempfile.mkdtemp(prefix="stormlane-chromium-")
    proc, cmd_w, res_r = _launch(binary, profile, width, height)
    pipe = _Pipe(proc, cmd_w, res_r, timeout_s)
    result = PageVisit(url=url)
    try:
        target = pipe.call("Target.createTarget", url="about:blank")["targetId"]
        session = pipe.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        for domain in ("Page", "Network", "Runtime", "Log"):
            pipe.call(f"{domain}.enable", session)
        pipe.call("Emulation.setDeviceMetricsOverride", session, width=width, height=height, deviceScaleFactor=1, mobile=False)
        _load_and_capture(pipe, session, url, result, full_page=full_page, timeout_s=timeout_s, evaluate=evaluate,
                          print_pdf=print_pdf, print_evaluate=print_evaluate)
        pipe.drain(quiet_s=0.2)
        _collect_events(pipe.events, result)
        try:
            pipe.call("Browser.close")
        except ReportError:
            pass
    finally:
        os.close(cmd_w)
        os.close(res_r)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
        shutil.rmtree(profile, ignore_errors=True)
    return result


def _launch(binary: str, profile: str, width: int, height: int):
    """Start Chromium with the DevTools protocol on a pipe: (process, our command fd, our reply fd)."""
    cmd_r, cmd_w = os.pipe()  # we write commands, the browser reads them on fd 3
    res_r, res_w = os.pipe()  # the browser writes replies on fd 4

    def _child_fds():  # runs in the child between fork and exec
        # Move both ends out of the way first (either may already sit on 3 or 4), then place
        # them on 3 and 4 and make them survive exec (os.pipe() fds are close-on-exec).
        a = fcntl.fcntl(cmd_r, fcntl.F_DUPFD, 10)
        b = fcntl.fcntl(res_w, fcntl.F_DUPFD, 10)
        os.dup2(a, 3)
        os.dup2(b, 4)
        os.set_inheritable(3, True)
        os.set_inheritable(4, True)

    args = [binary, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--remote-debugging-pipe", f"--window-size={width},{height}", "about:blank"]
    proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, preexec_fn=_child_fds, close_fds=False)
    os.close(cmd_r)
    os.close(res_w)
    return proc, cmd_w, res_r


def _load_and_capture(pipe, session, url: str, result: PageVisit, *, full_page: bool, timeout_s: float, evaluate, print_pdf: bool,
                      print_evaluate) -> None:
    """Navigate, wait for the load event and a quiet network, then screenshot, evaluate and print into ``result``."""
    pipe.events.clear()
    pipe.call("Page.navigate", session, url=url)
    if not pipe.wait_for("Page.loadEventFired", timeout_s=timeout_s / 2):
        raise ReportError(f"{url} did not finish loading")
    pipe.drain(quiet_s=0.5)
    shot = {"format": "png"}
    if full_page:
        metrics = pipe.call("Page.getLayoutMetrics", session)
        size = metrics.get("cssContentSize") or metrics["contentSize"]
        shot.update(captureBeyondViewport=True, clip={"x": 0, "y": 0, "width": size["width"], "height": size["height"], "scale": 1})
    result.screenshot_png = base64.b64decode(pipe.call("Page.captureScreenshot", session, **shot)["data"])
    result.title = pipe.call("Runtime.evaluate", session, expression="document.title", returnByValue=True).get("result", {}).get("value", "")
    _evaluate(pipe, session, evaluate, result.values)
    if print_evaluate:
        pipe.call("Emulation.setEmulatedMedia", session, media="print")
        _evaluate(pipe, session, print_evaluate, result.values)
        pipe.call("Emulation.setEmulatedMedia", session, media="")
    if print_pdf:
        result.pdf = base64.b64decode(pipe.call("Page.printToPDF", session, printBackground=True)["data"])


def _collect_events(events, result: PageVisit) -> None:
    """The page's requests, console lines and uncaught exceptions, from the protocol's events."""
    for ev in events:
        method, params = ev["method"], ev.get("params", {})
        if method == "Network.requestWillBeSent":
            result.requests.append(params["request"]["url"])
        elif method == "Runtime.consoleAPICalled":
            text_args = " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", []))
            result.console.append((params.get("type", "log"), text_args))
        elif method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            result.exceptions.append(details.get("exception", {}).get("description") or details.get("text", "exception"))
        elif method == "Log.entryAdded":
            entry = params.get("entry", {})
            result.console.append((entry.get("level", "info"), f"{entry.get('source', '')}: {entry.get('text', '')} {entry.get('url', '')}".strip()))


def is_blank_png(png: bytes, min_std: float = 8.0, min_ink_frac: float = 0.02) -> bool:
    """True when a screenshot is (nearly) one flat colour: grey-level std below ``min_std`` or
    fewer than ``min_ink_frac`` of the pixels differing from the most common value."""
    import io

    import numpy as np
    from PIL import Image

    grey = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)
    values, counts = np.unique(grey, return_counts=True)
    background = values[np.argmax(counts)]
    ink = float(np.mean(np.abs(grey - background) > 16))
    return grey.std() < min_std or ink < min_ink_frac


def screenshot(report_path, png_path, *, width: int = 1280, height: int = 900, chromium: str | None = None) -> Path:
    """Save a screenshot of the first viewport of a report (e.g. for the README)."""
    shot = visit(report_path, width=width, height=height, chromium=chromium)
    png_path = Path(png_path)
    png_path.parent.mkdir(parents=True, exist_ok=True)
    png_path.write_bytes(shot.screenshot_png)
    return png_path
