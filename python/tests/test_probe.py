"""`motionlink.probe`: the report of `motionlink probe <family> --json` as a record, and the device profile
it saves, which a client then loads (`profile=`) and names (`client.profile`); a profile of another device
is left alone with a warning."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import pytest

import motionlink


def test_probe_returns_the_report_with_every_check() -> None:
    report = motionlink.probe("scu", "sim")
    assert isinstance(report, motionlink.ProbeReport)
    assert (report.family, report.port) == ("scu", "sim")
    assert report.devices[0]["firmware"] == "SCU V2B3 motionlink-sim"
    assert report.check("grouping_indices").result == "ok"
    assert report.check("baud").result == "skipped"
    assert report.link["exchanges"] == 20
    assert {c.result for c in report.checks} <= {"ok", "unsupported", "failed", "skipped"}
    with motionlink.Emulator("compax", variant="no-echo", serve="tcp") as emu:
        report = motionlink.probe("compax", emu.port, drives="1-2")
        assert [d["address"] for d in report.devices] == [1]
        assert report.check("echo_form", 1).result == "unsupported"
        assert report.check("echo_form", 1).variant == "no-echo"
    with pytest.raises(motionlink.UsageError):
        motionlink.probe("lathe", "sim")


def test_a_saved_profile_is_loaded_by_a_later_client_and_another_devices_is_ignored(tmp_path: Path) -> None:
    profiles = tmp_path / "profiles.toml"
    with motionlink.Emulator("scu", variant="no-groups", serve="tcp") as emu:
        report = motionlink.probe("scu", emu.port, save=profiles)
        assert report.check("grouping_indices").result == "unsupported"
        assert len(report.saved) == 1 and report.saved[0].startswith(f"{profiles}#scu:{emu.port}:")
        with motionlink.Scu(emu.port, profile=profiles) as scu:
            assert scu.profile == report.saved[0]
            assert scu.info().actuators
        with motionlink.Scu(emu.port, profile=False) as scu:
            assert scu.profile is None
    # Another unit on that port (another firmware text in the file): not used, with a warning.
    text = profiles.read_text()
    profiles.write_text(text.replace("SCU V2B3 motionlink-sim", "SCU V9 elsewhere"))
    with motionlink.Emulator("scu", serve="tcp") as emu:
        other = profiles.read_text().replace(report.port, emu.port)
        profiles.write_text(other)
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            with motionlink.Scu(emu.port, profile=profiles) as scu:
                assert scu.profile is None
        assert any("not used" in str(w.message) and "SCU V9 elsewhere" in str(w.message) for w in seen), seen


@pytest.mark.parametrize(
    "family, cls, options",
    [
        ("scu", motionlink.AsyncScu, {}),
        ("powercube", motionlink.AsyncPowerCube, {}),
        ("compax", motionlink.AsyncCompax, {"drives": "1"}),
    ],
)
def test_async_clients_load_the_saved_profile_and_warn_of_anothers(
    tmp_path: Path, family: str, cls: type, options: dict
) -> None:
    import asyncio

    profiles = tmp_path / "profiles.toml"

    async def opened(port: str) -> "tuple[object, list]":
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            async with cls(port, profile=profiles) as client:
                taken = client.profile
        return taken, [str(w.message) for w in seen]

    with motionlink.Emulator(family, serve="tcp") as emu:
        report = motionlink.probe(family, emu.port, save=profiles, **options)
        assert len(report.saved) == 1, report.saved
        taken, seen = asyncio.run(opened(emu.port))
        assert taken == report.saved[0]
        assert not [m for m in seen if "not used" in m], seen
    # The same port, another device (another identity in the file): left alone, with a warning.
    with motionlink.Emulator(family, serve="tcp") as emu:
        text = profiles.read_text().replace(report.port, emu.port)
        identity = report.devices[0].get("identity") or ""
        assert identity and identity in text, (identity, text)
        profiles.write_text(text.replace(identity, "another device"))
        taken, seen = asyncio.run(opened(emu.port))
        assert taken is None
        assert any("not used" in m for m in seen), seen


@pytest.mark.parametrize("family, blocking, asynchronous", [
    ("scu", motionlink.Scu, motionlink.AsyncScu),
    ("powercube", motionlink.PowerCube, motionlink.AsyncPowerCube),
    ("compax", motionlink.Compax, motionlink.AsyncCompax),
])
def test_a_profile_warning_points_at_the_users_line(
    tmp_path: Path, family: str, blocking: type, asynchronous: type
) -> None:
    """A profile the client did not take is a UserWarning whose filename and line are the user's (this file),
    not the package's: from the blocking constructor, `async with`, and `await client.open()`."""
    import asyncio

    broken = tmp_path / "profiles.toml"
    broken.write_text("this is [[ not TOML\n")

    def warned(seen: "list[warnings.WarningMessage]") -> "warnings.WarningMessage":
        notices = [w for w in seen if "device profiles not used" in str(w.message)]
        assert len(notices) == 1, [str(w.message) for w in seen]
        return notices[0]

    async def with_block(port: str) -> None:
        async with asynchronous(port, profile=broken):
            pass

    async def opened(port: str) -> None:
        client = await asynchronous(port, profile=broken).open()
        await client.aclose()

    with motionlink.Emulator(family, serve="tcp") as emu:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            line = sys._getframe().f_lineno + 1
            client = blocking(emu.port, profile=broken)
        client.close()
        w = warned(seen)
        assert (w.filename, w.lineno) == (__file__, line), (w.filename, w.lineno)
        for run in (with_block, opened):
            with warnings.catch_warnings(record=True) as seen:
                warnings.simplefilter("always")
                asyncio.run(run(emu.port))
            assert warned(seen).filename == __file__, (run.__name__, warned(seen).filename)


@pytest.mark.parametrize("family, cls, options", [
    ("scu", motionlink.Scu, {}),
    ("powercube", motionlink.PowerCube, {}),
    ("compax", motionlink.Compax, {"drives": "1"}),
])
def test_a_profile_of_port_sim_is_loaded_as_the_command_line_loads_it(
    tmp_path: Path, family: str, cls: type, options: dict
) -> None:
    """Every family keys `port="sim"` as the command line does (`motionlink probe <family> --port sim --save`
    and then `--port sim`), and names it alike; an Emulator object has no port to key a profile by."""
    profiles = tmp_path / "profiles.toml"
    report = motionlink.probe(family, "sim", save=profiles, **options)
    assert len(report.saved) == 1 and report.saved[0].startswith(f"{profiles}#{family}:sim:"), report.saved
    with cls("sim", profile=profiles) as client:
        assert client.profile == report.saved[0]
        assert client.port == "sim (in-process emulator)"
    with motionlink.Emulator(family) as emu:
        with pytest.raises(motionlink.UsageError, match="no port to key a profile by"):
            motionlink.probe(family, emu, save=profiles, **options)
