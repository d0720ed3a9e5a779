"""Which device a client opens: the port it is given, else the one ``MOTIONLINK_PORT`` names, else a
UsageError saying so, as the command line does (never an emulator nobody asked for)."""

from __future__ import annotations

import asyncio
from typing import Any, Callable

import pytest

import motionlink

NO_PORT = r'^no port: give port=PORT \(such as "/dev/ttyUSB0", "tcp://HOST:PORT" or "sim"\), or set MOTIONLINK_PORT$'
MISSING = "/dev/motionlink-no-such-port"

CLIENTS = [motionlink.Scu, motionlink.PowerCube, motionlink.Compax]
ASYNC_CLIENTS = [motionlink.AsyncScu, motionlink.AsyncPowerCube, motionlink.AsyncCompax]


@pytest.mark.parametrize("cls", CLIENTS + ASYNC_CLIENTS, ids=lambda c: c.__name__)
@pytest.mark.parametrize("env", [None, "", "  "])
def test_no_port_and_no_environment_variable_is_a_usage_error(
    monkeypatch: pytest.MonkeyPatch, cls: Callable[..., Any], env: Any
) -> None:
    if env is None:
        monkeypatch.delenv("MOTIONLINK_PORT", raising=False)
    else:
        monkeypatch.setenv("MOTIONLINK_PORT", env)
    with pytest.raises(motionlink.UsageError, match=NO_PORT) as e:
        cls()
    assert (e.value.family, e.value.exit_code) == (cls.family, 2)


@pytest.mark.parametrize("cls", CLIENTS, ids=lambda c: c.__name__)
def test_without_a_port_the_environment_variable_names_the_device(
    monkeypatch: pytest.MonkeyPatch, cls: Callable[..., Any]
) -> None:
    """The device MOTIONLINK_PORT names is opened (here: it is not there), not an emulator."""
    monkeypatch.setenv("MOTIONLINK_PORT", MISSING)
    with pytest.raises(motionlink.TransportError, match=MISSING):
        cls()


@pytest.mark.parametrize("cls", ASYNC_CLIENTS, ids=lambda c: c.__name__)
def test_without_a_port_the_environment_variable_names_the_device_async(
    monkeypatch: pytest.MonkeyPatch, cls: Callable[..., Any]
) -> None:
    monkeypatch.setenv("MOTIONLINK_PORT", MISSING)

    async def main() -> None:
        async with cls():
            pass

    with pytest.raises(motionlink.TransportError, match=MISSING):
        asyncio.run(main())


def test_the_scu_of_the_environment_variable_is_the_one_that_moves(monkeypatch: pytest.MonkeyPatch) -> None:
    with motionlink.Emulator("scu", serve="tcp") as emu:
        monkeypatch.setenv("MOTIONLINK_PORT", emu.port)
        with motionlink.Scu() as scu:
            assert scu.port == emu.port
            assert abs(scu.move_to(1, 50).reached_counts - 50) <= 5
        texts = [e.text for e in emu.take_events()]
        assert any(t.startswith("F1 started") for t in texts), texts


def test_a_port_given_wins_over_the_environment_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MOTIONLINK_PORT", MISSING)
    with motionlink.Scu("sim") as scu:
        assert abs(scu.move_to(1, 50).reached_counts - 50) <= 5
    with motionlink.PowerCube("sim") as cube:
        assert cube.position().position_rad is not None
    with motionlink.Compax("sim") as drive:
        assert drive.position().position_units == 0.0

    async def main() -> float:
        async with motionlink.AsyncCompax("sim") as c:
            return (await c.position()).position_units

    assert asyncio.run(main()) == 0.0
