"""A headless chromium the tests can ask questions of while a page runs in real time.

``--dump-dom`` with ``--virtual-time-budget`` is fine for a page that only has to
load and draw: timers run on virtual time and the budget passes in a blink. But
``requestAnimationFrame`` does not: its frames come from the compositor in real
time, so a page that plays through animation frames sees one or two of them (on
a busy machine none) before the budget is spent. To watch such a page play, this
opens it with ``--remote-debugging-pipe`` and sends DevTools protocol commands
(JSON, each ended by a NUL byte) down file descriptor 3, reading the answers from
descriptor 4, while the page runs at the speed of the clock on the wall.
"""

from __future__ import annotations

import fcntl
import json
import os
import select
import subprocess
import time
from pathlib import Path


class BrowserError(RuntimeError):
    pass


class Page:
    """chromium showing one address; ``evaluate`` runs an expression in it.

    Use as a context manager: the browser is closed (and killed if it will not
    close) on the way out."""

    def __init__(self, chromium: str, flags: list[str], url: str, profile: Path, timeout: float = 60.0):
        self.timeout = timeout
        to_browser, from_browser = os.pipe(), os.pipe()
        # the child's ends moved above 4 first, so that putting them at 3 and 4 cannot clobber each other
        child_in = fcntl.fcntl(to_browser[0], fcntl.F_DUPFD, 10)
        child_out = fcntl.fcntl(from_browser[1], fcntl.F_DUPFD, 10)
        for fd in (to_browser[0], from_browser[1]):
            os.close(fd)
        # bash puts them at 3 and 4 and becomes chromium: no Python runs between fork and exec
        # (a preexec_fn would), and dash takes no descriptor above 9
        moves = f"3<&{child_in} 4>&{child_out} {child_in}<&- {child_out}>&-"
        self.process = subprocess.Popen(
            ["bash", "-c", f'exec "$@" {moves}', "bash", chromium, *flags, f"--user-data-dir={profile}",
             "--remote-debugging-pipe", url],
            pass_fds=(child_in, child_out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(child_in)
        os.close(child_out)
        self._write, self._read = to_browser[1], from_browser[0]
        self._buffer, self._id, self.session = b"", 0, None
        try:
            deadline = time.monotonic() + timeout
            while True:  # the page's target may come a moment after the browser answers
                pages = [t for t in self.call("Target.getTargets")["targetInfos"] if t["type"] == "page"]
                if pages or time.monotonic() > deadline:
                    break
                time.sleep(0.05)
            if not pages:
                raise BrowserError(f"no page for {url} in {timeout} s")
            page = pages[0]
            self.session = self.call("Target.attachToTarget", {"targetId": page["targetId"],
                                                               "flatten": True})["sessionId"]
        except BaseException:
            self.close()
            raise

    def call(self, method: str, params: dict | None = None) -> dict:
        """send one command and return its result (events that come between are dropped)"""
        self._id += 1
        message = {"id": self._id, "method": method, "params": params or {}}
        if self.session is not None and not method.startswith(("Target.", "Browser.")):
            message["sessionId"] = self.session
        os.write(self._write, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + self.timeout
        while True:
            while b"\0" not in self._buffer:
                left = deadline - time.monotonic()
                if left <= 0 or not select.select([self._read], [], [], left)[0]:
                    raise BrowserError(f"{method}: no answer in {self.timeout} s")
                chunk = os.read(self._read, 1 << 16)
                if not chunk:
                    raise BrowserError(f"{method}: chromium closed its end (exit {self.process.poll()})")
                self._buffer += chunk
            raw, self._buffer = self._buffer.split(b"\0", 1)
            answer = json.loads(raw)
            if answer.get("id") == self._id:
                if "error" in answer:
                    raise BrowserError(f"{method}: {answer['error']}")
                return answer["result"]

    def evaluate(self, expression: str):
        """the value of a JavaScript expression in the page (JSON-able values only)"""
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True})
        if "exceptionDetails" in result:
            raise BrowserError(f"{expression}: {result['exceptionDetails'].get('text')}")
        return result["result"].get("value")

    def dataset(self) -> dict[str, str]:
        """the <html> element's data-* attributes, as they are now"""
        return self.evaluate("Object.assign({}, document.documentElement.dataset)")

    def wait_for(self, expression: str, seconds: float, every: float = 0.1):
        """poll until the expression is truthy; its value, or the last one seen when time runs out.
        An expression that throws counts as false: the page may still be on its way in."""
        deadline = time.monotonic() + seconds
        while True:
            try:
                value = self.evaluate(expression)
            except BrowserError:
                value = None
            if value or time.monotonic() > deadline:
                return value
            time.sleep(every)

    def close(self) -> None:
        try:
            if self.process.poll() is None:
                try:
                    self.call("Browser.close")
                except (BrowserError, OSError):
                    pass
                try:
                    self.process.wait(10)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait()
        finally:
            for fd in (self._write, self._read):
                try:
                    os.close(fd)
                except OSError:
                    pass

    def __enter__(self) -> "Page":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
