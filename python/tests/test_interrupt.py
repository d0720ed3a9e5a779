"""Ctrl-C during the long calls besides a move (a scan, homing, a wait, an SCU run) and asyncio
cancellation of homing and waits: each reacts within 100 ms. Every wait is on an emulator event, a byte
count of a proxy, or a line the child prints."""

from __future__ import annotations

import asyncio
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable

import pytest

import motionlink

CHILD = str(Path(__file__).with_name("_long_call.py"))
LIMIT_S = 0.100


class CountingProxy:
    """A TCP proxy in front of a served emulator that counts the requests (frames) the client sends:
    ``wait_requests(n)`` returns once the n-th has passed."""

    def __init__(self, upstream: str, frame_end: bytes) -> None:
        host, port = upstream[len("tcp://") :].rsplit(":", 1)
        self._up = (host, int(port))
        self._end = frame_end
        self._count = 0
        self._cv = threading.Condition()
        self._srv = socket.socket()
        self._srv.bind(("127.0.0.1", 0))
        self._srv.listen(1)
        self.port = f"tcp://127.0.0.1:{self._srv.getsockname()[1]}"
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        try:
            conn, _ = self._srv.accept()
        except OSError:
            return
        up = socket.create_connection(self._up)

        def down() -> None:
            try:
                while data := up.recv(4096):
                    conn.sendall(data)
            except OSError:
                pass

        threading.Thread(target=down, daemon=True).start()
        try:
            while data := conn.recv(4096):
                with self._cv:
                    self._count += data.count(self._end)
                    self._cv.notify_all()
                up.sendall(data)
        except OSError:
            pass
        up.close()

    def wait_requests(self, n: int, timeout_s: float = 10.0) -> None:
        with self._cv:
            assert self._cv.wait_for(lambda: self._count >= n, timeout_s), f"{self._count} requests, not {n}"

    def close(self) -> None:
        self._srv.close()


def start_child(family: str, port: str, op: str) -> subprocess.Popen:
    child = subprocess.Popen(
        [sys.executable, CHILD, family, port, op], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert child.stdout is not None
    line = child.stdout.readline()
    assert line == "ready\n", line + (child.stderr.read() if child.stderr else "")
    return child


def interrupted_at(child: subprocess.Popen) -> float:
    """The time the child's KeyboardInterrupt reached Python (it prints it), once it has ended."""
    return child_output(child)[0]


def child_output(child: subprocess.Popen) -> tuple[float, list[str]]:
    """As interrupted_at, with the lines the child printed after it."""
    try:
        out, err = child.communicate(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
    lines = out.splitlines()
    at = [i for i, line in enumerate(lines) if line.startswith("interrupted ")]
    assert child.returncode == 130 and at, out + err
    return float(lines[at[0]].split()[1]), lines[at[0] + 1 :]


# family -> (the frame end the proxy counts, how many requests mean "scanning absent addresses")
SCAN = {"powercube": (b"\x03", 4), "compax": (b"\r", 4)}


@pytest.mark.parametrize("family", ["powercube", "compax"])
def test_ctrl_c_ends_a_scan_within_100_ms(family: str) -> None:
    """Only address 1 answers: the scan spends its time on absent addresses (a reply timeout each); SIGINT
    once it is among them raises KeyboardInterrupt within 100 ms, not at the end of the scan."""
    end, requests = SCAN[family]
    with motionlink.Emulator(family, serve="tcp") as emu:
        proxy = CountingProxy(emu.port, end)
        try:
            child = start_child(family, proxy.port, "scan")
            proxy.wait_requests(requests)
            signal_at = time.time()
            os.kill(child.pid, signal.SIGINT)
            at, after = child_output(child)
            took = at - signal_at
        finally:
            proxy.close()
    next_call = [float(line.split()[2]) for line in after if line.startswith("next call ")]
    print(f"{family} scan: KeyboardInterrupt {1000 * took:.1f} ms after SIGINT, next call {next_call}")
    assert took < LIMIT_S, f"KeyboardInterrupt {took:.3f} s after SIGINT"
    # The scan's thread stopped asking too: about 27 absent addresses were left, a reply timeout each (1.6 s
    # for PowerCube, more for COMPAX); a call right after the interrupt waits only for the address in flight.
    assert next_call and next_call[0] < 1.0, f"the call after the interrupt: {after}"


# family, op -> (emulator configuration, event: the long call is under way, event: the axis was stopped)
LONG = {
    ("powercube", "home"): (
        "[[module]]\naddress = 1\nstart_position = 3.0\nhome_vel = 0.1\n",
        lambda t: t == "module 1 motion started: homing",
        lambda t: t == "module 1 halted",
    ),
    ("compax", "home"): (
        "max_speed_units_per_s = 1.0\n[[drive]]\naddress = 1\nposition = 1000.0\n",
        lambda t: t.startswith("drive 1 homing started"),
        lambda t: "switched off" in t,
    ),
    ("powercube", "wait"): (
        None,
        lambda t: "motion started" in t,
        lambda t: t == "module 1 halted",
    ),
    ("compax", "wait"): (
        None,
        lambda t: "motion started" in t,
        lambda t: "switched off" in t,
    ),
    ("scu", "run"): (
        None,
        lambda t: t.startswith("F1 started direction"),
        lambda t: t.startswith("F1 stopped (RS"),
    ),
}


@pytest.mark.parametrize("family,op", list(LONG))
def test_ctrl_c_during_home_wait_and_run_stops_within_100_ms(family: str, op: str) -> None:
    config, started, stopped = LONG[(family, op)]
    with motionlink.Emulator(family, serve="tcp", config=config) as emu:
        child = start_child(family, emu.port, op)
        emu.wait_event(started, 10)
        signal_at = time.time()
        os.kill(child.pid, signal.SIGINT)
        stop = emu.wait_event(stopped, 2)
        raised = interrupted_at(child)
    print(f"{family} {op}: stopped {1000 * (stop.at - signal_at):.1f} ms after SIGINT ({stop.text})")
    assert stop.at - signal_at < LIMIT_S, f"stopped {stop.at - signal_at:.3f} s after SIGINT"
    assert raised - signal_at < 2.0


async def in_thread(fn: Callable[[], object]) -> object:
    return await asyncio.get_running_loop().run_in_executor(None, fn)


async def cancel_and_time(task: "asyncio.Task[object]", emu: motionlink.Emulator, stopped: Callable[[str], bool]) -> float:
    """Cancels `task` (whose operation is under way) and returns how long after that the emulated device
    reported the stop."""
    await asyncio.sleep(0)  # one step of the loop: the task has started its native operation
    cancelled_at = time.time()
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    stop = await in_thread(lambda: emu.wait_event(stopped, 1.0))
    return stop.at - cancelled_at  # type: ignore[attr-defined]


POWERCUBE_FAR = "[[module]]\naddress = 1\nstart_position = 3.0\nhome_vel = 0.1\n"
COMPAX_FAR = "max_speed_units_per_s = 1.0\n[[drive]]\naddress = 1\nposition = 1000.0\n"


@pytest.mark.parametrize("op", ["home", "wait"])
def test_async_powercube_cancelled_home_or_wait_halts_within_100_ms(op: str) -> None:
    with motionlink.Emulator("powercube", serve="tcp", config=POWERCUBE_FAR) as emu:

        async def main() -> float:
            async with motionlink.AsyncPowerCube(emu.port) as c:
                if op == "home":
                    task = asyncio.create_task(c.home())
                    await in_thread(lambda: emu.wait_event(lambda t: t == "module 1 motion started: homing", 10))
                    return await cancel_and_time(task, emu, lambda t: t == "module 1 halted")
                # A wait for a move another task runs: cancelling the wait halts the module.
                mover = asyncio.create_task(c.move_to(0.0, velocity=0.1))
                await in_thread(lambda: emu.wait_event(lambda t: "motion started: ramp" in t, 10))
                task = asyncio.create_task(c.wait())
                took = await cancel_and_time(task, emu, lambda t: t == "module 1 halted")
                assert "STATE_HALTED" in (await c.state()).flags
                mover.cancel()
                with pytest.raises((asyncio.CancelledError, motionlink.MotionlinkError)):
                    await mover
                return took

        took = asyncio.run(main())
    print(f"AsyncPowerCube.{op} cancelled: halted {1000 * took:.1f} ms later")
    assert took < LIMIT_S


@pytest.mark.parametrize("op", ["home", "wait"])
def test_async_compax_cancelled_home_or_wait_stops_the_drive(op: str) -> None:
    with motionlink.Emulator("compax", serve="tcp", config=COMPAX_FAR) as emu:

        async def main() -> float:
            async with motionlink.AsyncCompax(emu.port) as drive:
                if op == "home":
                    task = asyncio.create_task(drive.home())
                    await in_thread(lambda: emu.wait_event(lambda t: t.startswith("drive 1 homing started"), 10))
                    return await cancel_and_time(task, emu, lambda t: "switched off" in t)
                mover = asyncio.create_task(drive.move_to(0.0, speed_percent=1))
                await in_thread(lambda: emu.wait_event(lambda t: "motion started" in t, 10))
                task = asyncio.create_task(drive.wait())
                took = await cancel_and_time(task, emu, lambda t: "switched off" in t)
                mover.cancel()
                with pytest.raises((asyncio.CancelledError, motionlink.MotionlinkError)):
                    await mover
                return took

        took = asyncio.run(main())
    print(f"AsyncCompax.{op} cancelled: stopped {1000 * took:.1f} ms later")
    assert took < LIMIT_S
