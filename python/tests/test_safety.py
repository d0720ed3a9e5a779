"""The stop-on-exit rule and Ctrl-C: leaving a client's block (normally, by an exception, by
KeyboardInterrupt), a dropped client, the end of the program, and SIGINT during a long call all stop the
motion the client started. Every wait is on an emulator event or a line the child prints."""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable, Iterator, Tuple

import pytest
from _events import EVENTS

import motionlink

CHILD = str(Path(__file__).with_name("_long_move.py"))


@contextlib.contextmanager
def moving_child(emu: motionlink.Emulator, family: str, how: str) -> Iterator["subprocess.Popen[str]"]:
    """``_long_move.py`` run as ``how`` against ``emu``, once its move has started on the device; killed at
    the end if still running."""
    child = subprocess.Popen(
        [sys.executable, CHILD, family, emu.port, how], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None and child.stdout.readline() == "moving\n"
        emu.wait_event(EVENTS[family][0], 10)
        yield child
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate(timeout=10)

def open_client(family: str, port: object) -> Tuple[motionlink.PowerCube, Callable[[], object]]:
    if family == "powercube":
        c = motionlink.PowerCube(port)
        return c, lambda: c.move_to(3.0, velocity=0.1)
    if family == "scu":
        c = motionlink.Scu(port)
        return c, lambda: c.move_to(1, 800, speed=5)
    c = motionlink.Compax(port)
    return c, lambda: c.move_to(100000.0, speed_percent=1)


def run_in_thread(op: Callable[[], object]) -> threading.Thread:
    outcome = []

    def target() -> None:
        try:
            op()
        except BaseException as e:  # noqa: BLE001 - the test looks at what ended it
            outcome.append(e)

    t = threading.Thread(target=target, daemon=True)
    t.outcome = outcome  # type: ignore[attr-defined]
    t.start()
    return t


@pytest.mark.parametrize("family", ["powercube", "scu", "compax"])
@pytest.mark.parametrize("leave_by", [RuntimeError, KeyboardInterrupt, None])
def test_leaving_the_block_stops_the_motion(family: str, leave_by: object) -> None:
    started, stopped, _ = EVENTS[family]
    with motionlink.Emulator(family) as emu:
        client, op = open_client(family, emu)
        mover = None

        def body() -> None:
            nonlocal mover
            with client:
                mover = run_in_thread(op)
                emu.wait_event(started, 10)
                # The session knows what it set in motion (the function F1, module 1, drive 1).
                assert client.started() == [1]
                if leave_by is not None:
                    raise leave_by("leaving")  # type: ignore[operator]

        if leave_by is None:
            body()
        else:
            with pytest.raises(leave_by):  # type: ignore[call-overload]
                body()
        emu.wait_event(stopped, 2)
        assert mover is not None
        mover.join(5)
        assert not mover.is_alive()
        # The move in the other thread was cancelled by the close: it says so.
        assert isinstance(mover.outcome[0], motionlink.Cancelled), mover.outcome  # type: ignore[attr-defined]
        assert not client.is_open


@pytest.mark.parametrize("family", ["powercube", "scu", "compax"])
def test_close_returns_what_it_stopped(family: str) -> None:
    """close() stops the motion another thread's call set going (cancelling that call) and returns what it
    stopped, as started() names it; closing again returns []."""
    started, stopped, _ = EVENTS[family]
    with motionlink.Emulator(family) as emu:
        client, op = open_client(family, emu)
        assert client.started() == []
        mover = run_in_thread(op)
        emu.wait_event(started, 10)
        assert client.started() == [1]
        assert client.close() == [1]
        emu.wait_event(stopped, 0)
        mover.join(5)
        assert isinstance(mover.outcome[0], motionlink.Cancelled), mover.outcome  # type: ignore[attr-defined]
        assert client.close() == []
        with pytest.raises(motionlink.UsageError, match="closed"):
            client.started()


@pytest.mark.parametrize("family", ["powercube", "scu", "compax"])
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_stops_the_motion_within_100_ms_and_raises_keyboard_interrupt(family: str, signum: int) -> None:
    """SIGINT raises KeyboardInterrupt; SIGTERM with the README's handler raises SystemExit(143). Both stop
    the motion first."""
    _, stopped, _ = EVENTS[family]
    how = "wait" if signum == signal.SIGINT else "term"
    with motionlink.Emulator(family, serve="tcp") as emu, moving_child(emu, family, how) as child:
        signal_at = time.time()
        os.kill(child.pid, signum)
        stop = emu.wait_event(stopped, 2)
        _, err = child.communicate(timeout=10)
        print(f"{family}: stopped {1000 * (stop.at - signal_at):.1f} ms after signal {signum} ({stop.text})")
        assert stop.at - signal_at < 0.100, f"stopped {stop.at - signal_at:.3f} s after SIGINT: {stop.text}"
        if signum == signal.SIGINT:
            assert child.returncode != 0
            assert "KeyboardInterrupt" in err, err
            # The interrupt's cause is the library's account of the stop.
            assert "motionlink.errors.Cancelled" in err and "direct cause" in err, err
        else:
            assert child.returncode == 143, err


@pytest.mark.parametrize("family", ["powercube", "scu", "compax"])
def test_the_end_of_the_program_stops_the_motion_of_an_open_client(family: str) -> None:
    started, stopped, _ = EVENTS[family]
    with motionlink.Emulator(family, serve="tcp") as emu:
        done = subprocess.run(
            [sys.executable, CHILD, family, emu.port, "thread-exit"], capture_output=True, text=True, timeout=30
        )
        assert done.returncode == 0, done.stderr
        emu.wait_event(started, 5)
        emu.wait_event(stopped, 2)


@pytest.mark.parametrize("family", ["powercube", "scu", "compax"])
def test_ctrl_c_in_the_main_thread_stops_the_move_of_a_thread_that_is_no_daemon(family: str) -> None:
    """A move runs in a thread that is no daemon; Ctrl-C ends the main thread (asleep, in no call of the
    client's): the client is closed before Python waits for that thread, which stops the move and ends the
    thread's call (Cancelled), and the program. Was: the move ran to its end (atexit comes after the wait)."""
    _, stopped, _ = EVENTS[family]
    with motionlink.Emulator(family, serve="tcp") as emu, moving_child(emu, family, "thread-sleep") as child:
        signal_at = time.time()
        os.kill(child.pid, signal.SIGINT)
        stop = emu.wait_event(stopped, 2)
        _, err = child.communicate(timeout=10)
    assert stop.at - signal_at < 1.0, f"stopped {stop.at - signal_at:.3f} s after SIGINT: {stop.text}"
    assert "KeyboardInterrupt" in err and "motionlink.errors.Cancelled" in err, err


def test_a_main_thread_that_returns_leaves_the_move_of_a_thread_that_is_no_daemon_to_go_on() -> None:
    """The main thread returns at once while a thread that is no daemon moves: Python waits for that thread,
    and the client is not closed under it (its move is not stopped)."""
    _, stopped, _ = EVENTS["compax"]
    with motionlink.Emulator("compax", serve="tcp") as emu, moving_child(emu, "compax", "thread-return") as child:
        time.sleep(1.0)
        assert child.poll() is None, "Python waits for the moving thread"
        assert not any(stopped(e.text) for e in emu.take_events()), "the move goes on"


def test_a_garbage_collected_client_ends_its_session(scu_emulator: motionlink.Emulator) -> None:
    """A client nobody closed ends its session when it is collected (SCU: RA, which the unit reports)."""
    client = motionlink.Scu(scu_emulator)
    client.position(1)
    scu_emulator.take_events()
    del client
    gc.collect()
    scu_emulator.wait_event(lambda t: t == "remote mode closed by RA", 2)
