"""motionlink.Emulator: families, settings, served ports, events."""

from __future__ import annotations

import pytest

import motionlink


def test_each_family_in_process_and_served() -> None:
    for family in ("scu", "powercube", "compax"):
        with motionlink.Emulator(family) as emu:
            assert (emu.family, emu.port, emu.running) == (family, "", True)
        assert not emu.running
        with motionlink.Emulator(family, serve="tcp") as emu:
            assert emu.port.startswith("tcp://127.0.0.1:")


def test_presets_modules_drives_and_params() -> None:
    with motionlink.Emulator("scu", preset="tlt") as emu, motionlink.Scu(emu, functions=["tlt"]) as c:
        assert [a.actuator for a in c.info().actuators] == [1, 2]
    with motionlink.Emulator("powercube", modules=[2, 7]) as emu, motionlink.PowerCube(emu, module=2) as c:
        assert [m.module for m in c.scan()] == [2, 7]
    with motionlink.Emulator("compax", drives=[4], params={"P3": 7}) as emu, motionlink.Compax(emu, drive=4) as c:
        assert c.get("P3").value == 7.0


def test_bad_settings_are_usage_errors() -> None:
    with pytest.raises(motionlink.UsageError, match="family"):
        motionlink.Emulator("lift")
    with pytest.raises(motionlink.UsageError, match="preset"):
        motionlink.Emulator("scu", preset="nope")
    with pytest.raises(motionlink.UsageError, match="drives="):
        motionlink.Emulator("powercube", drives=[1])
    with pytest.raises(motionlink.UsageError, match="serve="):
        motionlink.Emulator("compax", serve="udp")


def test_a_client_of_another_family_is_refused() -> None:
    with motionlink.Emulator("scu") as emu, pytest.raises(motionlink.UsageError, match="scu emulator"):
        motionlink.PowerCube(emu)


def test_wait_event_times_out_naming_what_it_saw(powercube_emulator: motionlink.Emulator) -> None:
    with pytest.raises(TimeoutError, match="no matching event"):
        powercube_emulator.wait_event(lambda t: "never" in t, 0.05)
