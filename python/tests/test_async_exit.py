"""The end of a program that used an asyncio client: every async class, over TCP and a pty (a ``motionlink
sim`` process) and over ``"sim"``, with the script ending idle, with a call in flight, and with a move in
flight (its ``async with`` block left, or its loop and client simply abandoned). The interpreter must end
normally (no "Fatal Python error" from a library thread calling into a finalising interpreter), and a
move in flight must have been stopped by the client before the process ended (the emulator's events say
when), its session closed.

The child is ``_async_exit.py``; each run takes about a second."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable, Tuple

import pytest
from _events import EVENTS
from _slow_link import SlowLink

StartSim = Callable[[str, str], Any]  # the sim_process fixture (conftest.py): starts a `motionlink sim`
CHILD = str(Path(__file__).with_name("_async_exit.py"))

FAMILIES = ["scu", "powercube", "compax"]

def run_child(family: str, port: str, state: str) -> Tuple[subprocess.CompletedProcess, float]:
    """Runs the child to its end; returns it and the time (Unix, s) it had ended by."""
    done = subprocess.run([sys.executable, CHILD, family, port, state], capture_output=True, text=True, timeout=60)
    return done, time.time()


def assert_ended_normally(done: subprocess.CompletedProcess) -> None:
    assert "Fatal Python error" not in done.stderr, done.stderr
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1:] == ["end"], done.stdout + done.stderr


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("transport", ["tcp", "pty", "sim"])
@pytest.mark.parametrize("state", ["idle", "mid-call"])
def test_a_script_ends_normally(sim_process: StartSim, family: str, transport: str, state: str) -> None:
    sim = None if transport == "sim" else sim_process(family, transport)
    done, ended_by = run_child(family, "sim" if sim is None else sim.port, state)
    assert_ended_normally(done)
    if family == "scu" and sim is not None:
        # Closed by `async with` (idle) or, never closed by the script, by the exit handler (mid-call).
        at, text = sim.wait_event(EVENTS["scu"][2])
        assert at < ended_by, (text, sim.events())


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("transport", ["tcp", "sim"])
def test_a_script_ends_normally_while_the_library_is_inside_a_callback(
    sim_process: StartSim, family: str, transport: str
) -> None:
    """The library's delivery thread is inside a callback (without the GIL) when the script ends: the exit
    waits for it; it is not ended by the finalising interpreter (which aborted the process, every time)."""
    port = "sim" if transport == "sim" else sim_process(family, transport).port
    done, _ = run_child(family, port, "in-callback")
    assert_ended_normally(done)


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("transport", ["tcp", "pty", "sim"])
@pytest.mark.parametrize("state", ["mid-move", "mid-move-open"])
def test_a_move_in_flight_is_stopped_when_the_script_ends(
    sim_process: StartSim, family: str, transport: str, state: str
) -> None:
    started, stopped, closed = EVENTS[family]
    sim = None if transport == "sim" else sim_process(family, transport)
    done, ended_by = run_child(family, "sim" if sim is None else sim.port, state)
    assert_ended_normally(done)
    assert "moving" in done.stdout.splitlines(), done.stdout + done.stderr
    if sim is None:
        return
    sim.wait_event(started)
    # Stopped by the client, before its process ended (not by a watchdog of the device afterwards).
    at, text = sim.wait_event(stopped)
    assert at < ended_by, (text, sim.events())
    if closed is not None:
        at, text = sim.wait_event(closed)
        assert at < ended_by, (text, sim.events())


@pytest.mark.parametrize("family", FAMILIES)
def test_the_session_of_an_async_client_nobody_closed_ends_before_the_script(
    sim_process: StartSim, family: str
) -> None:
    """A client opened with `await open()` and never closed has a move in flight when `asyncio.run` ends,
    over a line that takes 30 ms each way; the client is garbage, collected, before the script ends. The
    move is stopped and the session ended (SCU: RA; PowerCube: watchdog off) before the process ends. Was:
    the collected client's close ran in the background, cut off by the exit (the SCU and the PowerCube
    left to their watchdogs)."""
    started, stopped, closed = EVENTS[family]
    sim = sim_process(family, "tcp")
    with SlowLink(sim.port) as link:
        done, ended_by = run_child(family, link.port, "abandoned")
    assert_ended_normally(done)
    sim.wait_event(started)
    for event in (stopped, closed) if closed is not None else (stopped,):
        at, text = sim.wait_event(event, 3)
        assert at < ended_by, (text, sim.events())
