"""Every operation of motionlink.Compax against the emulator."""

from __future__ import annotations

import time
from typing import List

import pytest

import motionlink
from motionlink.records import (
    CompaxHome,
    CompaxMove,
    CompaxOutput,
    CompaxSample,
    CompaxStop,
    DriveFound,
    Parameter,
    StatusValue,
)


def test_scan_finds_both_drives(compax: motionlink.Compax) -> None:
    found = compax.scan()
    assert all(isinstance(d, DriveFound) for d in found)
    assert [(d.drive, d.position_units) for d in found] == [(1, 0.0), (2, 0.0)]


def test_info_and_status(compax: motionlink.Compax) -> None:
    info = compax.info()
    assert [s.status for s in info] == ["S1", "S2", "S3", "S16", "S17", "S18"]
    # No names: the main ones, as `motionlink compax status` reads them.
    assert [s.status for s in compax.status()] == [s.status for s in compax.status([])] == [s.status for s in info]
    s17 = compax.status(["S17"])[0]
    assert isinstance(s17, StatusValue) and (s17.status, s17.name) == ("S17", "status bits S17")
    assert s17.value.to_dict() == {"word": 2, "flags": ["RUN"], "pattern": "0000 0010"}
    s1 = compax.status([1], drive=2)[0]
    assert (s1.status, s1.value, s1.drive, s1.id) == ("S1", 0.0, 2, 1)
    assert s1.to_dict() == {"family": "compax", "status": "S1", "name": "actual position", "unit": "unit", "value": 0.0}


def test_get_and_set_read_back(compax: motionlink.Compax) -> None:
    got = compax.get("P194", drive=2)
    assert isinstance(got, Parameter) and (got.name, got.id, got.value, got.drive) == ("P194", 194, 2.0, 2)
    assert compax.get(194, drive=2) == got
    written = compax.set("P3", 5)
    # `read_back` is the value read from the drive after the write (the library compared it).
    assert written.verified is True and isinstance(written.read_back, float)
    assert written.read_back == compax.get("P3").value == 5.0


def test_move_home_wait_watch_stop(compax: motionlink.Compax, compax_emulator: motionlink.Emulator) -> None:
    moved = compax.move_to(10.0)
    assert isinstance(moved, CompaxMove)
    assert (moved.drive, moved.start_units, moved.target_units) == (1, 0.0, 10.0)
    assert abs(moved.difference_units) <= moved.tolerance_units and moved.reached_units == pytest.approx(10.0, abs=0.01)
    rel = compax.move_to(distance=-2.5)
    assert rel.target_units == pytest.approx(7.5) and rel.reached_units == pytest.approx(7.5, abs=0.01)
    assert compax.wait().position_units == pytest.approx(7.5, abs=0.01)
    assert compax.position().position_units == pytest.approx(7.5, abs=0.01)
    assert moved.start_units == 0.0 and "start_units" not in moved.to_dict() and moved.waited is True
    home = compax.home()
    assert isinstance(home, CompaxHome) and home.position_units == pytest.approx(0.0, abs=0.01)
    sample = next(compax.watch(interval_ms=10, count=1))
    assert isinstance(sample, CompaxSample) and sample.moving is False and sample.t_s >= 0
    assert sample.s17.pattern == "0000 0010" and "COMMAND_ACTIVE" not in sample.s17.flags
    compax.output(0, 0)
    texts = [e.text for e in compax_emulator.take_events()]
    assert "drive 1 switched off (O0=0)" in texts, texts
    with pytest.raises(motionlink.DeviceError, match="switched off"):
        compax.move_to(1.0)
    compax.output(0, 1)
    assert compax.move_to(1.0, speed_percent=50).reached_units == pytest.approx(1.0, abs=0.01)


def test_a_watch_ends_with_its_client(compax_emulator: motionlink.Emulator) -> None:
    """The library's watch runs on its own thread: closing the client ends it, and the iterator says so."""
    client = motionlink.Compax(compax_emulator)
    samples = client.watch(interval_ms=5)
    first = next(samples)
    assert first.drive == 1 and first.s17.word == first.s17.to_dict()["word"]
    client.close()
    with pytest.raises(motionlink.UsageError, match="the watch has ended"):
        next(samples)


def test_travel_limits_refuse_before_sending(compax: motionlink.Compax, compax_emulator: motionlink.Emulator) -> None:
    compax_emulator.take_events()
    with pytest.raises(motionlink.UsageError, match="max") as e:
        compax.move_to(50.0, max_units=20.0)
    assert (e.value.kind, e.value.family) == ("usage", "compax")
    assert not any("motion started" in e.text for e in compax_emulator.take_events())


def test_sim_url() -> None:
    with motionlink.Compax("sim") as c:
        assert c.scan()[0].drive == 1


def test_stop_is_the_command_lines_stop(compax: motionlink.Compax, compax_emulator: motionlink.Emulator) -> None:
    """`stop()` does what `motionlink compax stop` does and returns its record: a drive at rest is left
    switched on (nothing is sent but S17, S1 and S16); a drive that moves (here under another thread's move)
    gets OUTPUT O0=0, confirmed by S17, and the record says where it stands and that it is switched off.
    `output` reads O0 back from S16 (another output is not read back: said so)."""
    import threading

    rest = compax.stop()
    assert isinstance(rest, CompaxStop) and (rest.drive, rest.confirmed, rest.o0) == (1, True, 1), rest
    assert [(d.drive, d.outcome) for d in rest.drives] == [(1, "at_rest")] and rest.position_units == 0.0
    assert "o0_not_read" not in rest and "action" not in rest.to_dict()
    compax_emulator.take_events()
    failed: List[Exception] = []

    def far() -> None:
        try:
            compax.move_to(100000.0, speed_percent=1)
        except motionlink.MotionlinkError as e:
            failed.append(e)

    mover = threading.Thread(target=far)
    mover.start()
    compax_emulator.wait_event(lambda t: "motion started" in t)
    deadline = time.monotonic() + 10
    while compax.position().position_units <= 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    stopped = compax.stop()
    mover.join(30)
    assert [(d.drive, d.outcome) for d in stopped.drives] == [(1, "switched_off")] and stopped.o0 == 0, stopped
    assert 0 < stopped.position_units < 100000.0, stopped
    assert failed and not mover.is_alive(), "the move under way ended in an error"
    on = compax.output(0, 1)
    assert isinstance(on, CompaxOutput) and (on.drive, on.output, on.state, on.read_back) == (1, 0, 1, 1)
    assert on.verified and on.not_verifiable == []
    other = compax.output(3, 1)
    assert (other.read_back, other.verified) == (None, False) and "O0 only" in other.not_verifiable[0], other
    assert compax.stop(drive=2).drive == 2

    async def main() -> None:
        with motionlink.Emulator("compax") as emu:
            async with motionlink.AsyncCompax(emu) as drive:
                assert (await drive.stop()).drives[0].outcome == "at_rest"

    import asyncio

    asyncio.run(main())


def test_a_str_is_one_status_value(compax: motionlink.Compax) -> None:
    """`status("S1")` reads S1 (a str is one name, as `Scu(functions="tlt")` is one specification), not the
    letters "S" and "1"; an int is one number; a list holds several."""
    (s1,) = compax.status("S1")
    assert (s1.status, s1.value) == ("S1", 0.0)
    assert compax.status("actual_position") == [s1]
    assert compax.status(1) == [s1]
    assert [s.status for s in compax.status(("S1", 17))] == ["S1", "S17"]
    assert len(compax.status([])) == 6
