"""Fixtures of the suite, in the pattern the README documents for users' own tests: an emulator per test,
closed (with its clients) when the test ends; and the ``motionlink`` binary, for the tests that run it.

The binary is ``$MOTIONLINK_BIN``, else ``debug/motionlink`` in ``$CARGO_TARGET_DIR`` or
``<repository>/target`` (``cargo build -p motionlink``). Without it the tests that need it are skipped, or
fail when ``MOTIONLINK_REQUIRE_CLI=1``.
"""

from __future__ import annotations

import os
import subprocess
import threading
import time
from pathlib import Path
from typing import Callable, Iterator, List, Optional, Tuple

import pytest

import motionlink

REPO = Path(__file__).resolve().parents[2]
_TARGET = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
BIN = Path(
    os.environ.get("MOTIONLINK_BIN", (_TARGET if _TARGET.is_absolute() else REPO / _TARGET) / "debug" / "motionlink")
)


@pytest.fixture(scope="session")
def motionlink_bin() -> Path:
    """The ``motionlink`` binary (the test is skipped without it, or fails with MOTIONLINK_REQUIRE_CLI=1)."""
    if not BIN.is_file():
        message = f"the motionlink binary is not at {BIN} (build it: cargo build -p motionlink, or set MOTIONLINK_BIN)"
        if os.environ.get("MOTIONLINK_REQUIRE_CLI") == "1":
            pytest.fail(message)
        pytest.skip(message)
    return BIN


class SimProcess:
    """``motionlink sim FAMILY --tcp 127.0.0.1:0 --events`` (or ``--pty``) in a process of its own:
    :attr:`port` is what it listens on, :meth:`wait_event` what the emulated device reported (its
    ``event <unix time> <what>`` lines on stderr)."""

    def __init__(self, binary: Path, family: str, transport: str) -> None:
        where = ["--tcp", "127.0.0.1:0"] if transport == "tcp" else ["--pty"]
        self._proc = subprocess.Popen(
            [str(binary), "sim", family, *where, "--events", "--color", "never"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self._events: List[Tuple[float, str]] = []
        self._cv = threading.Condition()
        assert self._proc.stdout is not None
        line = self._proc.stdout.readline()
        if not line.startswith("listening on "):
            self.close()
            raise AssertionError(f"motionlink sim {family} printed {line!r}, not `listening on ...`")
        # "listening on tcp://127.0.0.1:PORT" or "listening on pty /dev/pts/N".
        self.port = line.split()[-1]
        threading.Thread(target=self._read_events, daemon=True).start()

    def _read_events(self) -> None:
        assert self._proc.stderr is not None
        for line in self._proc.stderr:
            parts = line.rstrip("\n").split(" ", 2)
            if len(parts) == 3 and parts[0] == "event":
                with self._cv:
                    self._events.append((float(parts[1]), parts[2]))
                    self._cv.notify_all()

    def events(self) -> List[Tuple[float, str]]:
        """Every event so far: ``(unix time, text)``."""
        with self._cv:
            return list(self._events)

    def wait_event(self, match: Callable[[str], bool], timeout_s: float = 10.0) -> Tuple[float, str]:
        """The first event whose text ``match`` accepts, waiting for it at most ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        with self._cv:
            while True:
                found: Optional[Tuple[float, str]] = next((e for e in self._events if match(e[1])), None)
                if found is not None:
                    return found
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"no such event within {timeout_s} s; the events: {self._events}")
                self._cv.wait(left)

    def close(self) -> None:
        if self._proc.poll() is None:
            self._proc.terminate()
        try:
            self._proc.wait(10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()


@pytest.fixture
def sim_process(motionlink_bin: Path) -> Iterator[Callable[[str, str], SimProcess]]:
    """Starts ``motionlink sim`` processes (``sim_process(family, "tcp" | "pty")``), ended after the test."""
    started: List[SimProcess] = []

    def start(family: str, transport: str) -> SimProcess:
        sim = SimProcess(motionlink_bin, family, transport)
        started.append(sim)
        return sim

    yield start
    for sim in started:
        sim.close()


@pytest.fixture
def powercube_emulator() -> Iterator[motionlink.Emulator]:
    """One PowerCube module (address 1, rotary) in this process."""
    with motionlink.Emulator("powercube") as emu:
        yield emu


@pytest.fixture
def cube(powercube_emulator: motionlink.Emulator) -> Iterator[motionlink.PowerCube]:
    """A client of ``powercube_emulator``; closed (halting what it started) after the test."""
    with motionlink.PowerCube(powercube_emulator) as client:
        yield client


@pytest.fixture
def scu_emulator() -> Iterator[motionlink.Emulator]:
    """An SCU with the scp11 preset (actuator n on function Fn) in this process."""
    with motionlink.Emulator("scu", preset="scp11") as emu:
        yield emu


@pytest.fixture
def scu(scu_emulator: motionlink.Emulator) -> Iterator[motionlink.Scu]:
    with motionlink.Scu(scu_emulator, functions=["scp11"]) as client:
        yield client


@pytest.fixture
def compax_emulator() -> Iterator[motionlink.Emulator]:
    """COMPAX drives 1 and 2 on one bus, in this process."""
    with motionlink.Emulator("compax", drives=[1, 2]) as emu:
        yield emu


@pytest.fixture
def compax(compax_emulator: motionlink.Emulator) -> Iterator[motionlink.Compax]:
    with motionlink.Compax(compax_emulator) as client:
        yield client


@pytest.fixture(params=["powercube", "scu", "compax"])
def served(request: pytest.FixtureRequest) -> Iterator[motionlink.Emulator]:
    """Each family's emulator served on a free TCP port (its events carry their time)."""
    with motionlink.Emulator(request.param, serve="tcp") as emu:
        yield emu
