"""The asyncio clients of the SCU and COMPAX (the PowerCube's are in test_powercube.py): a move awaited
while positions are read, cancellation stops the motion, `async with` closes."""

from __future__ import annotations

import asyncio
import time
from typing import Any, Awaitable, Callable, Tuple

import pytest
from _events import EVENTS
from _slow_link import SlowLink

import motionlink

FAMILIES = ["scu", "powercube", "compax"]
TWO_AXES = {"scu": {"preset": "scp11"}, "powercube": {"modules": [1, 2]}, "compax": {"drives": [1, 2]}}
"""Emulators with two axes: SCU actuators 1 and 2 on F1 and F2, PowerCube modules 1 and 2, COMPAX drives 1 and 2."""


def async_client(family: str, port: object) -> Tuple[Any, Callable[[int], Awaitable[Any]]]:
    """FAMILY's asyncio client of port (a TWO_AXES emulator), and a long move (30 s and more) of its axis n."""
    if family == "scu":
        scu = motionlink.AsyncScu(port, functions=["scp11"])
        return scu, lambda n: scu.move_to(n, 800, speed=5)
    if family == "powercube":
        cube = motionlink.AsyncPowerCube(port)
        return cube, lambda n: cube.move_to(3.0, module=n, velocity=0.1)
    drive = motionlink.AsyncCompax(port)
    return drive, lambda n: drive.move_to(100000.0, drive=n, speed_percent=1)


async def in_thread(fn):  # type: ignore[no-untyped-def]
    return await asyncio.get_running_loop().run_in_executor(None, fn)


def test_async_scu_moves_while_positions_are_read_and_cancel_stops() -> None:
    with motionlink.Emulator("scu", serve="tcp") as emu:

        async def main() -> None:
            async with motionlink.AsyncScu(emu.port) as scu:
                move = asyncio.create_task(scu.move_to(1, 200))
                seen = []
                while not move.done():
                    seen.append(await scu.position(1))
                    await asyncio.sleep(0.1)
                report = await move
                assert abs(report.reached_counts - 200) <= 5
                assert any(0 < p.position_counts < 200 for p in seen), seen
                run = await scu.run(2, "out", seconds=0.2)
                assert run.actuators[1].reached_counts > 0
                emu.take_events()
                slow = asyncio.create_task(scu.move_to(1, 800, speed=5))
                await in_thread(lambda: emu.wait_event(lambda t: t.startswith("F1 started direction 9")))
                cancelled_at = time.time()
                slow.cancel()
                with pytest.raises(asyncio.CancelledError):
                    await slow
                stop = emu.wait_event(lambda t: t.startswith("F1 stopped (RS"), 1.0)
                assert stop.at - cancelled_at < 0.1
                await scu.stop(1)

        asyncio.run(main())
        texts = [e.text for e in emu.take_events()]
        assert any("remote mode closed by RA" in t for t in texts), texts


def test_async_compax_moves_homes_waits_and_cancel_stops() -> None:
    with motionlink.Emulator("compax", serve="tcp") as emu:

        async def main() -> None:
            async with motionlink.AsyncCompax(emu.port) as drive:
                move = asyncio.create_task(drive.move_to(20.0))
                seen = []
                while not move.done():
                    seen.append(await drive.position())
                    await asyncio.sleep(0.03)
                report = await move
                assert report.reached_units == pytest.approx(20.0, abs=0.01)
                assert any(0 < p.position_units < 20 for p in seen), seen
                assert (await drive.home()).position_units == pytest.approx(0.0, abs=0.01)
                assert (await drive.wait()).position_units == pytest.approx(0.0, abs=0.01)
                emu.take_events()
                slow = asyncio.create_task(drive.move_to(100000.0, speed_percent=1))
                await in_thread(lambda: emu.wait_event(lambda t: "motion started" in t))
                cancelled_at = time.time()
                slow.cancel()
                with pytest.raises(asyncio.CancelledError):
                    await slow
                stop = emu.wait_event(lambda t: "switched off" in t, 1.0)
                assert stop.at - cancelled_at < 0.1
                with pytest.raises(motionlink.DeviceError, match="switched off"):
                    await drive.move_to(1.0)
                await drive.stop()

        asyncio.run(main())


def test_an_async_compax_homing_stopped_halfway_raises_rather_than_return_a_position() -> None:
    # Another task's stop switches the drive off halfway: the homing's positioning has ended (S17), but
    # the axis is not referenced, and home() says so (was: a position returned as if homed).
    async def main() -> None:
        async with motionlink.AsyncCompax("sim") as drive:
            await drive.move_to(500.0)

            async def stop_soon() -> None:
                await asyncio.sleep(0.3)
                await drive.stop()

            homed, stopped = await asyncio.gather(drive.home(), stop_soon(), return_exceptions=True)
            assert stopped is None, stopped
            assert isinstance(homed, motionlink.DeviceError), homed
            assert "not referenced" in str(homed) and "switched off" in str(homed), homed
            assert (await drive.position()).position_units > 100.0

    asyncio.run(main())


def test_an_async_client_must_be_opened() -> None:
    client = motionlink.AsyncCompax("sim")
    with pytest.raises(motionlink.UsageError, match="not open"):
        asyncio.run(client.position())

    async def opened() -> float:
        async with motionlink.AsyncCompax("sim") as c:
            return (await c.position()).position_units

    assert asyncio.run(opened()) == 0.0


@pytest.mark.parametrize("family", ["scu", "powercube", "compax"])
def test_closing_an_async_client_cancels_its_calls_under_way(family: str) -> None:
    """Leaving `async with` while a move's task is still under way stops the move and ends the session
    (not only once that task is cancelled by someone else, or never); the move's awaiter gets Cancelled.
    `aclose()` (what leaving the block calls) returns what it stopped: the function, module or drive the
    move had set in motion; closing again returns []."""
    started, stopped, closed = EVENTS[family]
    with motionlink.Emulator(family, serve="tcp") as emu:

        async def main() -> None:
            client: Any
            if family == "scu":
                client = motionlink.AsyncScu(emu.port)
                moving = lambda: client.move_to(1, 800, speed=5)  # noqa: E731
            elif family == "powercube":
                client = motionlink.AsyncPowerCube(emu.port)
                moving = lambda: client.move_to(3.0, velocity=0.1)  # noqa: E731
            else:
                client = motionlink.AsyncCompax(emu.port)
                moving = lambda: client.move_to(100000.0, speed_percent=1)  # noqa: E731
            async with client:
                move = asyncio.create_task(moving())
                await in_thread(lambda: emu.wait_event(started, 10))
                assert client.started() == [1]
                assert await client.aclose() == [1]
            left_at = time.time()
            assert await client.aclose() == []
            # Stopped, and the session ended, by the time the block was left.
            assert emu.wait_event(stopped, 0).at <= left_at
            if closed is not None:
                assert emu.wait_event(closed, 0).at <= left_at
            with pytest.raises(motionlink.Cancelled, match="closed while this operation was under way") as e:
                await move
            assert e.value.family == family

        asyncio.run(main())


@pytest.mark.parametrize(
    "cls, blocking_only",
    [
        (motionlink.AsyncScu, {"info", "get", "set", "errors"}),
        (motionlink.AsyncPowerCube, {"scan", "info", "get", "set", "reset"}),
        (motionlink.AsyncCompax, {"scan", "status", "get", "set", "output"}),
    ],
)
def test_dir_of_an_async_client_lists_only_what_it_has(cls: Any, blocking_only: "set[str]") -> None:
    """`dir()` of the class and of an instance leaves out the operations only the blocking client has
    (asking for one raises AttributeError), and lists every one it has."""
    client = cls("sim")
    for names in (set(dir(cls)), set(dir(client))):
        assert not names & blocking_only, sorted(names & blocking_only)
        assert {"move_to", "position", "stop", "aclose", "open"} <= names
        for name in names:
            if not name.startswith("_"):
                assert hasattr(cls, name) or name in vars(client), name
    for name in blocking_only:
        assert not hasattr(client, name) and not hasattr(cls, name)


@pytest.mark.parametrize("family", FAMILIES)
def test_a_cancelled_move_raises_cancelled_error_once_its_stop_has_ended(family: str) -> None:
    """Over a line that takes 30 ms each way the stop takes a while (its command, then its confirmation):
    CancelledError reaches the awaiter only after the device stopped (its event came first) and the
    session saw it stop (started() is [] by then). Was: 1-2 ms after cancel(), the axis still moving."""
    started, stopped, _ = EVENTS[family]
    with motionlink.Emulator(family, serve="tcp", **TWO_AXES[family]) as emu, SlowLink(emu.port) as link:

        async def main() -> None:
            client, move = async_client(family, link.port)
            async with client:
                task = asyncio.create_task(move(1))
                await in_thread(lambda: emu.wait_event(started, 10))
                task.cancel()
                with pytest.raises(asyncio.CancelledError):
                    await task
                raised_at = time.time()
                assert client.started() == []
                assert emu.wait_event(stopped, 0).at <= raised_at

        asyncio.run(main())


@pytest.mark.parametrize("family", FAMILIES)
def test_a_cancelled_move_whose_stop_is_not_confirmed_raises_that(family: str) -> None:
    """The line goes dead, then the move's task is cancelled: the stop cannot be confirmed, and the awaiter
    gets the library's error saying so (stop_unconfirmed, the cancellation its cause) instead of a
    CancelledError that would say nothing of an axis that may still move. Was: CancelledError at once."""
    started, _, _ = EVENTS[family]
    with motionlink.Emulator(family, serve="tcp", **TWO_AXES[family]) as emu, SlowLink(emu.port, 0.0) as link:

        async def main() -> None:
            client, move = async_client(family, link.port)
            await client.open()
            task = asyncio.create_task(move(1))
            await in_thread(lambda: emu.wait_event(started, 10))
            link.cut()
            task.cancel()
            with pytest.raises(motionlink.MotionlinkError) as e:
                await task
            assert e.value.stop_unconfirmed, e.value
            assert isinstance(e.value.__cause__, asyncio.CancelledError)
            with pytest.raises(motionlink.MotionlinkError):
                await client.aclose()

        asyncio.run(main())


@pytest.mark.parametrize("family", FAMILIES)
def test_a_call_made_while_the_client_closes_is_refused(family: str) -> None:
    """aclose() runs as a task; while it cancels the first move, a second move on another axis is asked
    for: it is refused (UsageError), and nothing moves after aclose() returned. Was: the second move
    started and ran on (SCU: 8 s; PowerCube: to its target, verified)."""
    started, _, _ = EVENTS[family]
    with motionlink.Emulator(family, **TWO_AXES[family]) as emu:

        async def main() -> None:
            client, move = async_client(family, emu)
            await client.open()
            first = asyncio.create_task(move(1))
            await in_thread(lambda: emu.wait_event(started, 10))
            closing = asyncio.create_task(client.aclose())
            await asyncio.sleep(0)  # aclose() has begun: it awaits the cancel of the first move
            second = asyncio.create_task(move(2))
            assert await closing == [1]
            with pytest.raises(motionlink.UsageError, match="closed"):
                await asyncio.wait_for(second, 5)
            with pytest.raises(motionlink.Cancelled):
                await first

        emu.take_events()
        asyncio.run(main())
        second = ("F2 started", "module 2 motion started", "drive 2 motion started")
        assert not [e.text for e in emu.take_events() if e.text.startswith(second)]

