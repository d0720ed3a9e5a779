"""Every operation of motionlink.Scu against the emulator, and its function map."""

from __future__ import annotations

import threading
import time
from typing import Any, List

import pytest

import motionlink
from motionlink.records import ErrorCode, Parameter, ScuInfo, ScuMove, ScuRun, ScuSample


def test_info_lists_the_connected_actuators(scu: motionlink.Scu) -> None:
    info = scu.info()
    assert isinstance(info, ScuInfo) and info.family == "scu"
    assert [a.actuator for a in info.actuators] == [1, 2]
    assert all(a.position_counts == 0 and a.moving is False and "available" in a.flags for a in info.actuators)
    assert isinstance(info.last_error, ErrorCode) and info.last_error.code == 0
    assert info.firmware and info.configuration
    assert info.battery_mains.to_dict() == {"word": 1, "flags": ["mains_connected"]}
    assert info.battery_mains.word == 1


def test_get_entries_and_groups_and_set_reads_back(scu: motionlink.Scu) -> None:
    entry = scu.get("actual_position_a1")
    assert isinstance(entry, Parameter)
    assert (entry.name, entry.id, entry.value, entry.unit, entry.access) == ("actual_position_a1", 0x11, 0, "counts", "r")
    assert scu.get("0x0011") == entry
    group = scu.get("actual_positions")
    assert group.value["actual_position_a2"] == 0
    written = scu.set("remote_speed_f1", 80)
    # `read_back` is what the unit holds after the write (read from it), and the library compared it.
    assert written.verified is True and written.read_back == 80
    assert scu.get("remote_speed_f1").value == written.read_back
    again = scu.set("remote_speed_f1", 55)
    assert (again.value, again.read_back, again.verified) == (55, 55, True)
    assert set(again.to_dict()) == {
        "family", "name", "id", "value", "unit", "access", "read_back", "verified", "not_verifiable"
    }
    assert again.not_verifiable == []
    flags = scu.get("battery_mains")
    assert flags.value == {"word": 1, "flags": ["mains_connected"]}


def test_move_is_verified_and_watch_samples_it(scu: motionlink.Scu, scu_emulator: motionlink.Emulator) -> None:
    moved = scu.move_to(1, 300, speed=100)
    assert isinstance(moved, ScuMove)
    assert (moved.function, moved.actuator, moved.target_counts) == (1, 1, 300)
    assert abs(moved.reached_counts - 300) <= 5 and moved.time_s > 0
    assert [(a.actuator, a.moved) for a in moved.actuators] == [(1, True)]
    assert (moved.verified, moved.not_verifiable) == (True, [])
    assert moved.actuators[0].start_counts == 0 and "start_counts" not in moved.to_dict()["actuators"][0]
    where = scu.position(1)
    assert (where.actuator, where.family) == (1, "scu") and abs(where.position_counts - 300) <= 5
    texts = [e.text for e in scu_emulator.take_events()]
    assert any(t.startswith("F1 started direction 9") for t in texts), texts
    samples = list(scu.watch(interval_ms=10, count=2))
    assert all(isinstance(s, ScuSample) for s in samples)
    assert [a.actuator for a in samples[0].actuators] == [1, 2]
    assert samples[0].actuators[0].current_amps == 0.0 and samples[0].actuators[0].moving is False
    assert scu.started() == []


def test_run_and_stop(scu: motionlink.Scu, scu_emulator: motionlink.Emulator) -> None:
    run = scu.run(2, "out", seconds=0.2)
    assert isinstance(run, ScuRun) and run.function == 2
    assert (run.stopped, run.interrupted) == (True, False)
    assert [r.actuator for r in run.actuators] == [1, 2] and run.actuators[1].reached_counts > 0
    scu.stop(2, soft=True)
    texts = [e.text for e in scu_emulator.take_events()]
    assert any("stopped (RS" in t for t in texts), texts


def test_stop_without_a_function_stops_every_motion_function_and_says_where_they_rest(
    scu: motionlink.Scu, scu_emulator: motionlink.Emulator
) -> None:
    """``stop()`` is ``motionlink scu stop``: RS to F1..F10, the status read back until nothing moves, and
    the library's report (the command line's JSON without what only the command knows)."""
    from motionlink.scu import ScuStop

    outcome: List[BaseException] = []

    def move() -> None:
        try:
            scu.move_to(2, 800, speed=20)
        except motionlink.MotionlinkError as e:
            outcome.append(e)

    mover = threading.Thread(target=move)
    mover.start()
    deadline = time.monotonic() + 10
    while scu.position(2).position_counts < 20 and time.monotonic() < deadline:
        time.sleep(0.02)
    stopped = scu.stop()
    mover.join(timeout=10)
    assert isinstance(stopped, ScuStop) and stopped.family == "scu"
    assert (stopped.functions, stopped.mode, stopped.refused) == (list(range(1, 11)), "fast", [])
    rest = {r.actuator: r.position_counts for r in stopped.at_rest}
    assert set(rest) == {1, 2} and rest[1] == 0 and 20 <= rest[2] < 800, rest
    assert scu.position(2).position_counts == rest[2], "it rests where the report says"
    assert set(stopped.to_dict()) == {"family", "functions", "mode", "refused", "at_rest"}
    assert len(outcome) == 1, "the move stopped by someone else does not end as a success"
    assert any("F2 stopped" in e.text for e in scu_emulator.take_events())
    assert scu.stop(soft=True).mode == "soft"
    # A function named: its RS, then the status until nothing moves, as `motionlink scu stop 1`.
    one = scu.stop(1)
    assert (one.function, one.functions, one.mode, len(one.at_rest)) == (1, [1], "fast", 2), one
    assert set(one.to_dict()) == {"family", "function", "functions", "mode", "refused", "at_rest"}
    # A switching function: RS, then its status read back (the buzzer's bit 0 shows it off).
    switched = scu.stop("F11")
    expected = {"family": "scu", "function": 11, "mode": "off", "verified": True, "not_verifiable": []}
    assert switched.to_dict() == expected, switched


def test_error_history(scu: motionlink.Scu) -> None:
    history = scu.errors()
    assert len(history) == 5 and all(isinstance(e, ErrorCode) and e.code == 0 for e in history)


def test_a_target_outside_the_stroke_moves_nothing(scu: motionlink.Scu, scu_emulator: motionlink.Emulator) -> None:
    scu_emulator.take_events()
    with pytest.raises(motionlink.UsageError, match="stroke"):
        scu.move_to(1, 100_000)
    assert not any("started" in e.text for e in scu_emulator.take_events())


def test_sim_url() -> None:
    with motionlink.Scu("sim") as s:
        assert len(s.info().actuators) == 2


# ----------------------------------------------------------------------------------------- function map
# As the command line's --functions takes it: a str is one specification, a list several; "sim" emulates
# the unit the map describes.


def test_a_str_is_one_function_map_specification() -> None:
    """``functions="tlt"``: the TLT preset (F1 drives both columns), against an emulated TLT."""
    with motionlink.Emulator("scu", preset="tlt") as emu, motionlink.Scu(emu, functions="tlt") as scu:
        moved = scu.move_to(1, 100)
        assert [(a.actuator, abs(a.reached_counts - 100) <= 5) for a in moved.actuators] == [(1, True), (2, True)]


def test_sim_emulates_the_unit_the_function_map_describes() -> None:
    """``"sim"`` with a TLT map is a TLT (F1 moves both columns); with SCP11 (the default) F1 moves A1 alone;
    a function given one by one on top of a preset is emulated too."""
    with motionlink.Scu("sim", functions="tlt") as scu:
        assert scu.info().configuration == "TLT motionlink emulator"
        moved = scu.move_to(1, 400)
        assert [a.actuator for a in moved.actuators] == [1, 2]
        assert [abs(p.position_counts - 400) <= 5 for p in (scu.position(1), scu.position(2))] == [True, True]
    with motionlink.Scu("sim", functions="scp11") as scu:
        assert [a.actuator for a in scu.move_to(1, 100).actuators] == [1]
        assert scu.position(2).position_counts == 0
    with motionlink.Scu("sim", functions=["scp11", "F7=1,2"]) as scu:
        moved = scu.move_to(1, 100, function=7)
        assert [(a.actuator, abs(a.reached_counts - 100) <= 5) for a in moved.actuators] == [(1, True), (2, True)]


@pytest.mark.parametrize("functions", ["tlx", ["scp11", "nonsense"], "unknownx"])
def test_a_bad_function_map_names_the_presets(functions: Any) -> None:
    with pytest.raises(motionlink.UsageError, match=r"give a preset \(scp11, tlt, liftkit\) or a function") as e:
        motionlink.Scu("sim", functions=functions)
    assert "unknown" not in str(e.value).replace("unknownx", "")


def test_a_bad_function_specification_names_what_is_wrong() -> None:
    with pytest.raises(motionlink.UsageError, match=r'"F11=1": "F11" is not a motion function F1..F10'):
        motionlink.Scu("sim", functions="F11=1")


def test_a_str_is_one_stroke_specification() -> None:
    with motionlink.Scu("sim", strokes="1=0:50") as scu:
        with pytest.raises(motionlink.UsageError, match=r"outside A1.s stroke 0\.\.50 counts"):
            scu.move_to(1, 60)
        assert abs(scu.move_to(1, 40).reached_counts - 40) <= 5


def test_a_unit_that_refuses_what_the_manual_leaves_open_still_moves_and_says_what_it_could_not_verify() -> None:
    with motionlink.Emulator("scu", variant=["no-user-positions", "no-remote-readback"]) as unit:
        with motionlink.Scu(unit, functions=["scp11"]) as scu:
            moved = scu.move_to(1, 150)
            assert abs(moved.reached_counts - 150) <= 5 and moved.verified is False
            assert any("UserPositionData (0x2001, PDE)" in why for why in moved.not_verifiable), moved.not_verifiable
            assert any("not read back" in why for why in moved.not_verifiable), moved.not_verifiable
            written = scu.set("remote_speed_f1", 40)
            assert (written.verified, written.read_back) == (False, None)
            assert "remote_speed_f1 (0x3011)" in written.not_verifiable[0]
    # A unit that refuses grouping indices and cyclic objects: read entry by entry, nothing lost.
    with motionlink.Emulator("scu", variant="no-groups,no-cyclic-objects") as unit:
        with motionlink.Scu(unit, functions=["scp11"]) as scu:
            moved = scu.move_to(2, 100)
            assert (moved.verified, moved.reached_counts) == (True, 100)
            sample = next(iter(scu.watch(count=1)))
            assert [(a.actuator, a.position_counts) for a in sample.actuators] == [(1, 0), (2, 100)]
            assert scu.get("actual_positions").value["actual_position_a2"] == 100


def test_an_unknown_variant_is_a_usage_error_naming_the_known_ones() -> None:
    with pytest.raises(motionlink.UsageError, match="no-cyclic-objects"):
        motionlink.Emulator("scu", variant="no-cyclic-object")
    # An SCU variant is no COMPAX variant: the message lists the family's own.
    unknown = "\"no-groups\" is not a variant of the COMPAX emulator \\(known: .*echo-bare"
    with pytest.raises(motionlink.UsageError, match=unknown):
        motionlink.Emulator("compax", variant="no-groups")
