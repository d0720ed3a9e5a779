"""Every operation of motionlink.Compax against the emulator."""

from __future__ import annotations

import pytest

import motionlink
from motionlink.records import CompaxHome, CompaxMove, CompaxSample, DriveFound, Parameter, StatusValue


def test_scan_finds_both_drives(compax: motionlink.Compax) -> None:
    found = compax.scan()
    assert all(isinstance(d, DriveFound) for d in found)
    assert [(d.drive, d.position_units) for d in found] == [(1, 0.0), (2, 0.0)]


def test_info_and_status(compax: motionlink.Compax) -> None:
    info = compax.info()
    assert [s.name for s in info] == ["S1", "S2", "S3", "S16", "S17", "S18"]
    s17 = compax.status(["S17"])[0]
    assert isinstance(s17, StatusValue) and "RUN" in s17.flags
    assert compax.status([1], drive=2)[0].value == 0.0


def test_get_and_set_read_back(compax: motionlink.Compax) -> None:
    got = compax.get("P194", drive=2)
    assert isinstance(got, Parameter) and (got.name, got.id, got.value, got.drive) == ("P194", 194, 2.0, 2)
    assert compax.get(194, drive=2) == got
    written = compax.set("P3", 5)
    assert (written.value, written.read_back) == (5.0, 5.0)
    assert compax.get("P3").value == 5.0


def test_move_home_wait_watch_stop(compax: motionlink.Compax, compax_emulator: motionlink.Emulator) -> None:
    moved = compax.move_to(10.0)
    assert isinstance(moved, CompaxMove)
    assert (moved.drive, moved.start_units, moved.target_units) == (1, 0.0, 10.0)
    assert abs(moved.difference_units) <= moved.tolerance_units and moved.reached_units == pytest.approx(10.0, abs=0.01)
    rel = compax.move_to(distance=-2.5)
    assert rel.target_units == pytest.approx(7.5) and rel.reached_units == pytest.approx(7.5, abs=0.01)
    assert compax.wait() == pytest.approx(7.5, abs=0.01)
    assert compax.position() == pytest.approx(7.5, abs=0.01)
    home = compax.home()
    assert isinstance(home, CompaxHome) and home.position_units == pytest.approx(0.0, abs=0.01)
    sample = next(compax.watch(interval_ms=10, count=1))
    assert isinstance(sample, CompaxSample) and sample.moving is False and sample.t_s >= 0
    compax.stop()
    texts = [e.text for e in compax_emulator.take_events()]
    assert "drive 1 switched off (O0=0)" in texts, texts
    with pytest.raises(motionlink.DeviceError, match="switched off"):
        compax.move_to(1.0)
    compax.output(0, 1)
    assert compax.move_to(1.0, speed_percent=50).reached_units == pytest.approx(1.0, abs=0.01)


def test_travel_limits_refuse_before_sending(compax: motionlink.Compax, compax_emulator: motionlink.Emulator) -> None:
    compax_emulator.take_events()
    with pytest.raises(motionlink.MotionlinkError):
        compax.move_to(50.0, max_units=20.0)
    assert not any("motion started" in e.text for e in compax_emulator.take_events())


def test_sim_url() -> None:
    with motionlink.Compax("sim") as c:
        assert c.scan()[0].drive == 1
