"""What the browser tests share (tests/test_view_browser.py, tests/test_pendant_browser.py):
Debian's headless Chromium driven by Playwright, and ``irl view`` as a process of its own.

Importing this module skips the importing test file when Chromium is not installed, except
where ``IRL_REQUIRE_BROWSER=1`` (CI, whose .ci/run installs it): there it fails.
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import time

import pytest

from tests.conftest import IRL, ROOT, free_port

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
if CHROMIUM is None:
    if os.environ.get("IRL_REQUIRE_BROWSER") == "1":
        pytest.fail("Chromium is needed here (IRL_REQUIRE_BROWSER=1): apt-get install chromium", pytrace=False)
    pytest.skip("Chromium is not installed (apt-get install chromium)", allow_module_level=True)

playwright = pytest.importorskip("playwright.sync_api")

#: Chromium's flags for a headless run on a machine with no GPU and a closed network.
FLAGS = ["--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-dev-shm-usage"]
LOAD = 60.0  # s: a page that takes longer has hung (not a timing assertion)


@pytest.fixture(scope="module")
def browser():
    with playwright.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        yield b
        b.close()


class View:
    """``irl view ARGS`` as a process, with the URL it printed (``url``) and, live, the
    pendant's (``pendant``)."""

    def __init__(self, *args):
        self.proc = subprocess.Popen([*IRL, "view", *map(str, args), "--port", str(free_port())], cwd=ROOT,
                                     stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True)
        self.output = []
        deadline = time.monotonic() + LOAD
        self.url = self.pendant = None
        live = "--endpoint" in args
        while self.url is None or (live and self.pendant is None):
            line = self.proc.stdout.readline()
            if not line:
                pytest.fail(f"irl view ended ({self.proc.wait()}) before serving:\n{''.join(self.output)}")
            self.output.append(line)
            found = re.search(r"irl view: (the pendant: )?(http://127\.0\.0\.1:\d+/\S*)", line)
            if found and found.group(1):
                self.pendant = found.group(2)
            elif found:
                self.url = found.group(2)
            assert time.monotonic() < deadline, "".join(self.output)

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(15)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
