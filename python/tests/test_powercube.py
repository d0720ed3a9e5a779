"""Every operation of motionlink.PowerCube (and the async twin) against the emulator."""

from __future__ import annotations

import asyncio
import math
import time
from pathlib import Path

import pytest

import motionlink
from motionlink.records import (
    ModuleInfo,
    ModulePosition,
    ModuleState,
    Parameter,
    PowerCubeHome,
    PowerCubeMotion,
    PowerCubeMove,
    PowerCubeSetpoint,
    PowerCubeStop,
)


def test_info_names_the_kind_and_its_units(cube: motionlink.PowerCube) -> None:
    info = cube.info()
    assert isinstance(info, ModuleInfo)
    assert (info.family, info.module, info.kind, info.unit) == ("powercube", 1, "rotary", "rad")
    assert info.max_position_rad > info.min_position_rad
    assert info.max_velocity_rad_per_s > 0 and info.max_acceleration_rad_per_s2 > 0
    assert "position_rad" in info and "position_m" not in info
    with pytest.raises(AttributeError, match="position_m"):
        info.position_m  # noqa: B018 - a rotary module has no metres
    assert info.to_dict()["kind"] == "rotary"


def test_position_get_and_set_read_back(cube: motionlink.PowerCube) -> None:
    p = cube.position()
    assert isinstance(p, ModulePosition) and p.unit == "rad"
    got = cube.get("ActPos")
    assert isinstance(got, Parameter) and got.name == "ActPos" and got.id == 60 and got.unit == "rad"
    assert got.value == pytest.approx(p.position_rad)
    assert cube.get("0x3c").name == "ActPos"
    written = cube.set("MaxVel", 0.5)
    assert written.value == 0.5 and written.verified is True and written.access == "rw"
    assert written.read_back == cube.get("MaxVel").value == pytest.approx(0.5)
    assert written.not_verifiable == []


def test_home_move_wait_and_watch(cube: motionlink.PowerCube, powercube_emulator: motionlink.Emulator) -> None:
    home = cube.home()
    assert isinstance(home, PowerCubeHome) and "STATE_HOME_OK" in home.state.flags
    assert home.action == "homed" and home.reached_rad == pytest.approx(0.0, abs=1e-3)
    moved = cube.move_to(0.3, velocity=1.0)
    assert isinstance(moved, PowerCubeMove)
    assert (moved.unit, moved.target_rad) == ("rad", 0.3)
    assert moved.reached_rad == pytest.approx(0.3, abs=1e-3)
    assert moved.difference_rad == pytest.approx(moved.reached_rad - 0.3, abs=1e-6)
    assert moved.start_rad == pytest.approx(0.0, abs=1e-3) and "start_rad" not in moved.to_dict()
    assert moved.action == "reached" and "STATE_RAMP_END" in moved.state.flags
    texts = [e.text for e in powercube_emulator.take_events()]
    assert any("motion started" in t for t in texts) and any("at rest 0.3" in t for t in texts), texts
    state = cube.wait()
    assert isinstance(state, ModuleState) and "STATE_MOTION" not in state.flags
    samples = list(cube.watch(interval_ms=5, count=3))
    assert [round(s.position_rad, 3) for s in samples] == [0.3, 0.3, 0.3]
    assert "STATE_MOTION" not in samples[0].state.flags
    assert samples[0].t_s <= samples[1].t_s <= samples[2].t_s


def test_motion_runs_the_manuals_modes_checked_and_ended(cube: motionlink.PowerCube) -> None:
    cube.home()
    held = cube.motion("fvel", 0.2, for_s=0.3)
    assert isinstance(held, PowerCubeMotion)
    assert (held.action, held.mode, held.ended, held.unit) == ("ran", "FVEL_MODE", "velocity_zero", "rad")
    assert held.reached_rad - held.start_rad > 0.04 and held.held_s >= 0.3
    assert held.verified is False and "velocity" in held.not_verifiable[0]
    assert "STATE_HALTED" not in held.state.flags and "target_rad" not in held
    step = cube.motion("FSTEP_ACK", 0.3, time_ms=400)
    assert (step.ended, step.target_rad) == ("reached", 0.3)
    assert step.reached_rad == pytest.approx(0.3, abs=1e-3) and step.ext_ack["position_unit"] == "rad"
    halted = cube.motion("fcur", -0.5, for_s=0.2)
    assert halted.ended == "halted" and "STATE_HALTED" in halted.state.flags
    cube.reset()
    # Refused before anything moves, with the command line's messages.
    before = cube.position().position_rad
    for args, kwargs, message in [
        (("fstep", 0.3), {}, "FSTEP_MODE takes a target position"),
        (("velocity", 0.3), {}, 'unknown motion mode "velocity"'),
        (("fvel", 1.5), {"for_s": 1.0}, "MaxVel"),
        (("icur", 600), {"for_s": 1.0}, "600 is outside -500..500"),
        (("fvel", 0.1), {"tolerance": 0.01}, "the tolerance"),
        (("fvel", 0.1), {"time_ms": 70000}, "time_ms 70000"),
    ]:
        with pytest.raises(motionlink.UsageError, match=message):
            cube.motion(*args, **kwargs)
    assert cube.position().position_rad == before


def test_setpoints_stream_a_velocity_and_the_close_halts_what_still_moves() -> None:
    emulator = motionlink.Emulator("powercube")
    try:
        with motionlink.PowerCube(emulator) as cube:
            cube.home()
            positions = []
            for _ in range(20):
                sent = cube.setpoint("fvel_ack", 0.5)
                assert isinstance(sent, PowerCubeSetpoint)
                assert (sent.mode, sent.module, sent.ext_ack["position_unit"]) == ("FVEL_ACK", 1, "rad")
                positions.append(sent.ext_ack["position"])
                time.sleep(0.01)
            assert positions[-1] > positions[0], positions
            with pytest.raises(motionlink.UsageError, match="MaxVel"):
                cube.setpoint("fvel", 1.5)
            with pytest.raises(motionlink.UsageError, match='unknown motion mode "speed"'):
                cube.setpoint("speed", 0.1)
            assert "STATE_MOTION" in cube.state().flags
            # What happened so far (homing, the motion's start) is taken: only the close's doing follows.
            emulator.take_events()
        texts = [e.text for e in emulator.take_events()]
        assert texts[:1] == ["module 1 halted"] and any("at rest" in t for t in texts), texts
    finally:
        emulator.close()


def test_async_motion_cancelled_during_its_hold_halts_the_module() -> None:
    async def main() -> None:
        async with motionlink.AsyncPowerCube("sim") as c:
            await c.home()
            held = asyncio.create_task(c.motion("fvel", 0.3))
            while "STATE_MOTION" not in (await c.state()).flags:
                await asyncio.sleep(0.01)
            held.cancel()
            with pytest.raises(asyncio.CancelledError):
                await held
            state = await c.state()
            assert "STATE_HALTED" in state.flags and "STATE_MOTION" not in state.flags

    asyncio.run(main())


def test_stop_halts_and_reset_clears(cube: motionlink.PowerCube, powercube_emulator: motionlink.Emulator) -> None:
    cube.home()
    cube.stop()
    assert "STATE_HALTED" in cube.state().flags
    with pytest.raises(motionlink.DeviceError) as e:
        cube.move_to(0.1)
    assert e.value.code is not None and any(b["name"] == "STATE_HALTED" for b in e.value.bits)
    assert cube.reset() is False
    assert "STATE_HALTED" not in cube.state().flags
    assert cube.move_to(0.1).reached_rad == pytest.approx(0.1, abs=1e-3)


def test_scan_finds_every_module() -> None:
    with motionlink.Emulator("powercube", modules=[3, 5]) as emu, motionlink.PowerCube(emu, module=3) as c:
        found = c.scan()
        assert [m.module for m in found] == [3, 5]
        assert all(m.kind == "rotary" for m in found)
        assert c.position(5).module == 5


def test_can_bus_in_process() -> None:
    with motionlink.Emulator("powercube", can=True) as emu, motionlink.PowerCube(emu) as c:
        assert c.move_to(0.2).reached_rad == pytest.approx(0.2, abs=1e-3)


@pytest.mark.parametrize("can", [False, True], ids=["rs232", "can"])
def test_in_process_events_carry_the_time_they_happened(can: bool) -> None:
    """An in-process emulator's events are stamped when the device produced them, not when they are taken."""
    with motionlink.Emulator("powercube", can=can) as emu, motionlink.PowerCube(emu) as c:
        emu.take_events()
        before = time.time()
        c.move_to(0.5)
        after = time.time()
        time.sleep(0.3)
        events = emu.take_events()
        started = next(e for e in events if "motion started" in e.text)
        rest = next(e for e in events if "at rest" in e.text)
        assert before <= started.at < rest.at <= after + 0.005, (before, events, after)


def test_can_bus_behind_a_served_slcan_adapter() -> None:
    """A CAN URL: the served CAN emulator sits behind an emulated SLCAN adapter on a TCP port."""
    with motionlink.Emulator("powercube", can=True, serve="tcp", modules=[1, 4]) as emu:
        assert emu.port.startswith("slcan://tcp://127.0.0.1:")
        with motionlink.PowerCube(emu.port) as c:
            assert [m.module for m in c.scan()] == [1, 4]
            assert c.move_to(0.2).reached_rad == pytest.approx(0.2, abs=1e-3)
        texts = [e.text for e in emu.take_events()]
        assert "module 1 watchdog online" in texts and "module 1 at rest 0.2000 rad" in texts, texts


def test_sim_url_and_served_tcp_port() -> None:
    with motionlink.PowerCube("sim") as c:
        assert c.info().kind == "rotary"
    with motionlink.Emulator("powercube", serve="tcp") as emu:
        assert emu.port.startswith("tcp://127.0.0.1:")
        with motionlink.PowerCube(emu.port) as c:
            assert c.move_to(0.2).reached_rad == pytest.approx(0.2, abs=1e-3)
        # Over a link the watchdog is armed for the motion and switched off after it.
        texts = [e.text for e in emu.take_events()]
        assert "module 1 watchdog online" in texts and "module 1 watchdog offline" in texts


def test_async_move_while_positions_are_watched(served_powercube_port: str) -> None:
    async def main() -> None:
        async with motionlink.AsyncPowerCube(served_powercube_port) as c:
            move = asyncio.create_task(c.move_to(0.6, velocity=1.0))
            seen = []
            while not move.done():
                seen.append((await c.position()).position_rad)
                await asyncio.sleep(0.02)
            report = await move
            assert report.reached_rad == pytest.approx(0.6, abs=1e-3)
            assert len(seen) >= 3 and any(0.05 < p < 0.6 for p in seen), seen
            assert "STATE_MOTION" not in (await c.wait()).flags
            home = await c.home()
            assert home.reached_rad == pytest.approx(0.0, abs=1e-3)
            assert "STATE_HOME_OK" in (await c.state()).flags

    asyncio.run(main())


def test_async_cancel_halts_the_module() -> None:
    with motionlink.Emulator("powercube", serve="tcp") as emu:

        async def main() -> None:
            async with motionlink.AsyncPowerCube(emu.port) as c:
                move = asyncio.create_task(c.move_to(3.0, velocity=0.2))
                await asyncio.get_running_loop().run_in_executor(
                    None, lambda: emu.wait_event(lambda t: "motion started" in t)
                )
                move.cancel()
                with pytest.raises(asyncio.CancelledError):
                    await move
                # The future was dropped before CancelledError reached us: the halt was sent.
                halted = emu.wait_event(lambda t: "halted" in t, 1.0)
                assert halted.text == "module 1 halted"
                assert "STATE_HALTED" in (await c.state()).flags
                await c.stop()

        asyncio.run(main())


@pytest.fixture
def served_powercube_port():
    with motionlink.Emulator("powercube", serve="tcp") as emu:
        yield emu.port


def test_results_compare_and_are_read_only(cube: motionlink.PowerCube) -> None:
    a, b = cube.position(), cube.position()
    assert a == b and math.isfinite(a.value)
    with pytest.raises(AttributeError):
        a.unit = "m"  # type: ignore[misc]


def test_stop_is_confirmed_and_reported(cube: motionlink.PowerCube) -> None:
    """`stop()` is `motionlink powercube stop`: the halt, confirmed by the state read back, and where the
    module stands (a record without the command's `holder`)."""
    halted = cube.stop()
    assert isinstance(halted, PowerCubeStop) and (halted.module, halted.action, halted.ok) == (1, "halted", True)
    assert "STATE_HALTED" in halted.state.flags and halted.unit == "rad" and math.isfinite(halted.position_rad)
    assert "holder" not in halted.to_dict() and "unit" not in halted.to_dict()
    assert cube.reset() is False

    async def main() -> None:
        with motionlink.Emulator("powercube") as emu:
            async with motionlink.AsyncPowerCube(emu) as c:
                assert "STATE_HALTED" in (await c.stop()).state.flags

    asyncio.run(main())


def test_a_positions_dict_is_the_command_lines_object_and_its_unit_an_attribute(motionlink_bin: Path) -> None:
    """`to_dict()` of a position has the command line's keys (it has no position command: a `watch --json`
    sample names the position `position_rad`, with no `unit`; `t_s` and `state` are the sample's); `unit`
    is an attribute only, as records.py and docs/python.md say of a PowerCube record's unit."""
    import json
    import subprocess

    done = subprocess.run(
        [str(motionlink_bin), "--json", "powercube", "--port", "sim", "watch", "--count", "1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    sample = json.loads(done.stdout.splitlines()[0])
    theirs = {k: v for k, v in sample.items() if k not in {"port", "profile", "t_s", "state"}}
    with motionlink.PowerCube("sim") as cube:
        p = cube.position()
    assert p.unit == "rad" and p.value == p.position_rad
    assert "unit" not in p.to_dict()
    assert p.to_dict().keys() == theirs.keys() == {"family", "module", "position_rad"}
    assert p.to_dict() == {**theirs, "position_rad": pytest.approx(theirs["position_rad"], rel=1e-6)}
