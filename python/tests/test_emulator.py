"""motionlink.Emulator: families, settings, served ports, events."""

from __future__ import annotations

from typing import Any

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


def test_firmware_variants_and_what_a_result_could_not_verify() -> None:
    # A module that keeps TargetVelInc apart from TargetVel: the write is made, and said to be unverified.
    with motionlink.Emulator("powercube", variant="no-twin-mirror") as emu, motionlink.PowerCube(emu) as c:
        r = c.set("TargetVel", 0.8)
        assert r.verified is False and r.read_back is None
        assert "keeps TargetVelInc apart" in r.not_verifiable[0]
        c.home()
        m = c.move_to(0.3, velocity=0.7)
        assert abs(m.reached_rad - 0.3) <= 0.001 and m.verified is False and len(m.not_verifiable) == 2
        assert m.to_dict()["not_verifiable"] == m.not_verifiable
    with motionlink.Emulator("powercube") as emu, motionlink.PowerCube(emu) as c:
        assert c.set("TargetVel", 0.8).verified is True
        assert c.set("TargetVel", 0.8).not_verifiable == []
    # Names in a list, or separated by commas.
    for variant in (["echo-bare", "status-value-only"], "echo-bare, status-value-only"):
        with motionlink.Emulator("compax", variant=variant) as emu, motionlink.Compax(emu) as c:
            m = c.move_to(3.0)
            assert m.reached_units == 3.0 and m.verified is False
            assert any("without the flag characters" in w for w in m.not_verifiable)
    with motionlink.Emulator("compax") as emu, motionlink.Compax(emu) as c:
        m = c.move_to(3.0)
        assert (m.verified, m.not_verifiable) == (True, [])
    with pytest.raises(motionlink.UsageError, match="no-twin-mirror"):
        motionlink.Emulator("powercube", variant="nope")
    with pytest.raises(motionlink.UsageError, match="echo-without-address"):
        motionlink.Emulator("compax", variant=["echo-bare", "nope"])


def test_bad_settings_are_usage_errors() -> None:
    with pytest.raises(motionlink.UsageError, match="family"):
        motionlink.Emulator("lift")
    with pytest.raises(motionlink.UsageError, match="preset"):
        motionlink.Emulator("scu", preset="nope")
    with pytest.raises(motionlink.UsageError, match="drives="):
        motionlink.Emulator("powercube", drives=[1])
    with pytest.raises(motionlink.UsageError, match="serve="):
        motionlink.Emulator("compax", serve="udp")


def test_an_scu_preset_is_where_the_configuration_starts() -> None:
    """`preset=` with `config=` is `motionlink sim scu --preset P --config FILE`: the preset is the starting
    point of the text (a comment that mentions the word changes nothing); a text that names another preset is
    refused naming both (which one was meant is not known), one that names the same is fine."""

    def configuration(**settings: str) -> str:
        with motionlink.Emulator("scu", **settings) as emu, motionlink.Scu(emu, functions="tlt") as lift:
            return str(lift.info().configuration)

    tlt = configuration(preset="tlt")
    assert configuration(preset="tlt", config="# no preset here\ndefault_speed = 80\n") == tlt
    assert configuration(preset="tlt", config='preset = "tlt"\n') == tlt
    assert configuration(config='preset = "liftkit"\n') == configuration(preset="liftkit") != tlt
    differs = r"preset = \"liftkit\" in the configuration differs from the preset \"tlt\""
    with pytest.raises(motionlink.UsageError, match=differs):
        motionlink.Emulator("scu", preset="tlt", config='preset = "liftkit"\n')
    with pytest.raises(motionlink.UsageError, match=r"unknown preset \"nope\""):
        motionlink.Emulator("scu", preset="nope", config="default_speed = 80\n")


def test_a_client_of_another_family_is_refused() -> None:
    with motionlink.Emulator("scu") as emu, pytest.raises(motionlink.UsageError, match="scu emulator"):
        motionlink.PowerCube(emu)


def test_wait_event_times_out_naming_what_it_saw(powercube_emulator: motionlink.Emulator) -> None:
    with pytest.raises(TimeoutError, match="no matching event"):
        powercube_emulator.wait_event(lambda t: "never" in t, 0.05)


@pytest.mark.parametrize(
    "family, client, call",
    [
        ("powercube", motionlink.PowerCube, lambda c: c.move_to(0.7)),
        ("powercube-can", motionlink.PowerCube, lambda c: c.position()),
        ("scu", motionlink.Scu, lambda c: c.position(1)),
        ("compax", motionlink.Compax, lambda c: c.move_to(1.0)),
    ],
)
def test_closing_an_emulator_ends_it_for_its_clients(family: str, client: type, call: Any) -> None:
    """`close()` stops the emulator for the clients connected to it too: their next call raises
    Disconnected (it moved the module before), and a client that reconnects (an SCU session does) finds
    it gone."""
    emu = motionlink.Emulator(family.split("-")[0], can=True) if family.endswith("can") else motionlink.Emulator(family)
    c = client(emu)
    assert c.position(1) if family == "scu" else c.position()
    emu.close()
    assert not emu.running
    with pytest.raises(motionlink.Disconnected):
        call(c)
    with pytest.raises(motionlink.Disconnected):
        call(c)
    try:
        c.close()
    except motionlink.TransportError:
        pass  # the close's stop could not reach the device either
    assert not c.is_open
    with pytest.raises(motionlink.UsageError, match="closed"):
        client(emu)
    emu.close()  # closing twice does nothing
