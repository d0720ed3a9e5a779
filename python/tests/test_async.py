"""The asyncio clients of the SCU and COMPAX (the PowerCube's are in test_powercube.py): a move awaited
while positions are read, cancellation stops the motion, `async with` closes."""

from __future__ import annotations

import asyncio
import time
from typing import Any

import pytest
from _events import EVENTS

import motionlink


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
