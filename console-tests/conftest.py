"""Browser tests of `motionlink console`: headless Chromium driven through chromedriver (Selenium) against the
console on the emulators.

The binary is $MOTIONLINK_BIN, else target/debug/motionlink (built by `cargo test` / `cargo build`). The browser
is $MOTIONLINK_CHROMIUM (default /usr/bin/chromium) and the driver $MOTIONLINK_CHROMEDRIVER (default
/usr/bin/chromedriver); an empty value names no program. When either is missing, each test reports itself
skipped by name; with MOTIONLINK_REQUIRE_BROWSER=1 (as in .ci/run) a missing browser fails the test instead.

The screenshot of the page during a move goes to $MOTIONLINK_SCREENSHOT, else target/console.png: the run leaves
the tracked docs/console.png alone (copy a new screenshot there by hand when the page changed visibly).

Tests wait on the emulator's events (`motionlink sim ... --events`) and on the page's state, never after a
fixed sleep.
"""

import os
import queue
import re
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(os.environ.get("MOTIONLINK_BIN", ROOT / "target" / "debug" / "motionlink"))
CHROMIUM = os.environ.get("MOTIONLINK_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("MOTIONLINK_CHROMEDRIVER", "/usr/bin/chromedriver")
REQUIRE_BROWSER = os.environ.get("MOTIONLINK_REQUIRE_BROWSER") == "1"
SCREENSHOT = Path(os.environ.get("MOTIONLINK_SCREENSHOT") or ROOT / "target" / "console.png")


class Lines:
    """The lines of a child's pipe, followed on a thread."""

    def __init__(self, pipe):
        self.lines = []
        self.cond = threading.Condition()
        self.closed = False
        threading.Thread(target=self._follow, args=(pipe,), daemon=True).start()

    def _follow(self, pipe):
        for raw in pipe:
            with self.cond:
                self.lines.append(raw.decode("utf-8", "replace").rstrip("\n"))
                self.cond.notify_all()
        with self.cond:
            self.closed = True
            self.cond.notify_all()

    def wait_for(self, pred, timeout):
        """The first line satisfying `pred` within `timeout` seconds, or None."""
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                for line in self.lines:
                    if pred(line):
                        return line
                left = deadline - time.monotonic()
                if left <= 0 or self.closed:
                    return None
                self.cond.wait(left)

    def text(self):
        with self.cond:
            return "\n".join(self.lines)


class Sim:
    """`motionlink sim <family> --tcp 127.0.0.1:0 --events`: an emulated device whose events tests wait for."""

    def __init__(self, family, *args):
        self.proc = subprocess.Popen([str(BIN), "sim", family, "--tcp", "127.0.0.1:0", *args, "--events"],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.stderr = Lines(self.proc.stderr)
        first = self.proc.stdout.readline().decode().strip()
        assert first.startswith("listening on "), f"{first!r}: {self.stderr.text()}"
        self.address = first[len("listening on "):]

    def wait_event(self, pred, timeout=10.0, after=0.0):
        """(time, text) of the first event after Unix time `after` whose text satisfies `pred`, or None."""
        def match(line):
            m = re.match(r"event (\d+\.\d+) (.*)", line)
            return m is not None and float(m.group(1)) >= after and pred(m.group(2))
        line = self.stderr.wait_for(match, timeout)
        if line is None:
            return None
        m = re.match(r"event (\d+\.\d+) (.*)", line)
        return float(m.group(1)), m.group(2)

    def events(self):
        return [l for l in self.stderr.text().splitlines() if l.startswith("event ")]

    def stop(self):
        self.proc.kill()
        self.proc.wait()


class Console:
    """`motionlink console <args>` and the address it printed."""

    def __init__(self, *args):
        self.proc = subprocess.Popen([str(BIN), "console", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.stderr = Lines(self.proc.stderr)
        line = self.proc.stdout.readline().decode().strip()
        m = re.fullmatch(r"console on (http://127\.0\.0\.1:\d+)/\?token=([0-9a-f]{32})", line)
        assert m, f"{line!r}: {self.stderr.text()}"
        self.base, self.token = m.group(1), m.group(2)
        self.url = f"{self.base}/?token={self.token}"

    def stop(self):
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def _missing_browser():
    """Why no browser can run here, or None."""
    for what, path, var in (("browser", CHROMIUM, "MOTIONLINK_CHROMIUM"),
                            ("driver", CHROMEDRIVER, "MOTIONLINK_CHROMEDRIVER")):
        if not path.strip():
            return f"missing {what}: ${var} is empty"
        # A program file, or a name on PATH (Path("").exists() and a directory would pass a plain exists()).
        found = Path(path).is_file() or shutil.which(path) is not None
        if not found:
            return f"missing {what}: nothing at {path!r}"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "the selenium package is not installed"
    return None


@pytest.fixture
def browser(request):
    """A headless Chromium; the test is skipped by name (or fails under MOTIONLINK_REQUIRE_BROWSER=1) without one."""
    missing = _missing_browser()
    if missing:
        message = f"{request.node.name}: {missing}"
        if REQUIRE_BROWSER:
            pytest.fail(f"{message} (MOTIONLINK_REQUIRE_BROWSER=1)")
        pytest.skip(f"{message}; skipped")
    from selenium import webdriver
    from selenium.common.exceptions import SessionNotCreatedException
    from selenium.webdriver.chrome.service import Service

    profile = tempfile.mkdtemp(prefix="motionlink-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which(CHROMIUM) or CHROMIUM
    # A profile of its own: a Chromium still closing from the test before holds the default one.
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                "--window-size=1400,1200", "--no-proxy-server", f"--user-data-dir={profile}"):
        options.add_argument(arg)
    # Chromium sometimes exits as it starts on a loaded machine ("Chrome instance exited"): that is the
    # browser's start, not the console under test, so it is tried again (three times at most).
    for attempt in range(3):
        try:
            driver = webdriver.Chrome(service=Service(shutil.which(CHROMEDRIVER) or CHROMEDRIVER), options=options)
            break
        except SessionNotCreatedException:
            if attempt == 2:
                raise
            time.sleep(1.0)
    yield driver
    driver.quit()
    shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture
def compax_sim():
    if not BIN.exists():
        pytest.fail(f"{BIN} not found: build it with `cargo build -p motionlink` (or set MOTIONLINK_BIN)")
    sim = Sim("compax", "--drives", "1")
    yield sim
    sim.stop()


@pytest.fixture
def compax_console(compax_sim):
    console = Console("compax", "--port", compax_sim.address, "--drives", "1")
    yield console
    console.stop()
