"""Fixtures of the suite, in the pattern the README documents for users' own tests: an emulator per test,
closed (with its clients) when the test ends."""

from __future__ import annotations

from typing import Iterator

import pytest

import motionlink


@pytest.fixture
def powercube_emulator() -> Iterator[motionlink.Emulator]:
    """One PowerCube module (address 1, rotary) in this process."""
    with motionlink.Emulator("powercube") as emu:
        yield emu


@pytest.fixture
def cube(powercube_emulator: motionlink.Emulator) -> Iterator[motionlink.PowerCube]:
    """A client of ``powercube_emulator``; closed (halting what it started) after the test."""
    with motionlink.PowerCube(powercube_emulator) as client:
        yield client


@pytest.fixture
def scu_emulator() -> Iterator[motionlink.Emulator]:
    """An SCU with the scp11 preset (actuator n on function Fn) in this process."""
    with motionlink.Emulator("scu", preset="scp11") as emu:
        yield emu


@pytest.fixture
def scu(scu_emulator: motionlink.Emulator) -> Iterator[motionlink.Scu]:
    with motionlink.Scu(scu_emulator, functions=["scp11"]) as client:
        yield client


@pytest.fixture
def compax_emulator() -> Iterator[motionlink.Emulator]:
    """COMPAX drives 1 and 2 on one bus, in this process."""
    with motionlink.Emulator("compax", drives=[1, 2]) as emu:
        yield emu


@pytest.fixture
def compax(compax_emulator: motionlink.Emulator) -> Iterator[motionlink.Compax]:
    with motionlink.Compax(compax_emulator) as client:
        yield client


@pytest.fixture(params=["powercube", "scu", "compax"])
def served(request: pytest.FixtureRequest) -> Iterator[motionlink.Emulator]:
    """Each family's emulator served on a free TCP port (its events carry their time)."""
    with motionlink.Emulator(request.param, serve="tcp") as emu:
        yield emu
