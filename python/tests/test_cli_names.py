"""Python's results carry the command line's JSON names (naming.md, "Decisions of 2026-11-25"): for each
family's info, get, set, move, status or scan, watch and stop (and COMPAX's output), ``to_dict()`` has
exactly the keys, nested the same way, that ``motionlink <family> --port sim --json ...`` prints
(``family``, ``port`` and ``profile`` aside; of a stop, what only the command knows: ``holder``, and
the SCU's and COMPAX's ``action``, the SCU's ``stopped``).

The binary is the ``motionlink_bin`` fixture's (conftest.py): without it these tests are skipped, or fail
when ``MOTIONLINK_REQUIRE_CLI=1``.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any, Callable, List

import pytest

import motionlink

# `profile`: the device profile the command's session took (Python's clients name it in `client.profile`).
IDENTITY = {"family", "port", "profile"}


@pytest.fixture(scope="module")
def cli(motionlink_bin: Path) -> Callable[..., List[Any]]:
    def run(*args: str) -> List[Any]:
        done = subprocess.run([str(motionlink_bin), *args], capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, f"motionlink {' '.join(args)}: {done.stderr}"
        return [json.loads(line) for line in done.stdout.splitlines() if line.strip()]

    return run


def shape(value: Any) -> Any:
    """The keys of a JSON value, recursively (a list of objects by its first element), without family /
    port."""
    if isinstance(value, dict):
        return {k: shape(v) for k, v in value.items() if k not in IDENTITY}
    if isinstance(value, list) and value and isinstance(value[0], dict):
        return [shape(value[0])]
    return None


def without(value: Any, *keys: str) -> Any:
    """A command's JSON object without the keys only the command has (a stop's ``holder``)."""
    return {k: v for k, v in value.items() if k not in keys}


class Names:
    """Collects every operation whose names differ, so that one run shows them all."""

    def __init__(self) -> None:
        self.differ: List[str] = []

    def __call__(self, what: str, python: Any, cli: Any) -> None:
        ours, theirs = shape(python), shape(cli)
        if ours != theirs:
            self.differ.append(f"{what}:\n  python {ours}\n  cli    {theirs}")

    def check(self) -> None:
        assert not self.differ, "\n".join(self.differ)


# ------------------------------------------------------------------------------------------------ SCU


def test_scu_names(cli: Callable[..., List[Any]]) -> None:
    same_names = Names()
    with motionlink.Scu("sim") as scu:
        same_names("info", scu.info().to_dict(), cli("scu", "--port", "sim", "--json", "info")[0])
        same_names(
            "get",
            scu.get("actual_position_a1").to_dict(),
            cli("scu", "--port", "sim", "--json", "get", "actual_position_a1")[0],
        )
        # A flag word's value: {word, flags}.
        same_names("get battery_mains", scu.get("battery_mains").to_dict(), cli("scu", "--port", "sim", "--json", "get", "battery_mains")[0])
        same_names(
            "set",
            scu.set("remote_speed_f1", 80).to_dict(),
            cli("scu", "--port", "sim", "--json", "set", "remote_speed_f1", "80")[0],
        )
        same_names("move_to", scu.move_to(1, 300).to_dict(), cli("scu", "--port", "sim", "--json", "move", "1", "300")[0])
        ran = cli("scu", "--port", "sim", "--json", "run", "2", "out", "--seconds", "0.2")
        same_names("run", scu.run(2, "out", seconds=0.2).to_dict(), ran[-1])
        sample = next(scu.watch(interval_ms=10, count=1))
        same_names("watch", sample.to_dict(), cli("scu", "--port", "sim", "--json", "watch", "--count", "1")[0])
        for named in ([], ["2"], ["F11"]):
            theirs = without(cli("scu", "--port", "sim", "--json", "stop", *named)[0], "action", "stopped", "holder")
            same_names(f"stop {named}", scu.stop(*named).to_dict(), theirs)
    same_names.check()


# ------------------------------------------------------------------------------------------ PowerCube


def test_powercube_names(cli: Callable[..., List[Any]]) -> None:
    pc = ("powercube", "--port", "sim", "--json")
    same_names = Names()
    with motionlink.PowerCube("sim") as cube:
        # Listings are JSON Lines: one object per module.
        same_names("scan", [m.to_dict() for m in cube.scan()], cli(*pc, "scan"))
        same_names("info", cube.info().to_dict(), cli(*pc, "info")[0])
        same_names("state", cube.state().to_dict(), cli(*pc, "state")[0])
        same_names("get", cube.get("ActPos").to_dict(), cli(*pc, "get", "ActPos")[0])
        same_names("set", cube.set("MaxVel", 0.5).to_dict(), cli(*pc, "set", "MaxVel", "0.5")[0])
        same_names("home", cube.home().to_dict(), cli(*pc, "home")[0])
        same_names("move_to", cube.move_to(0.3).to_dict(), cli(*pc, "move", "0.3")[0])
        for mode, value, given, option in (
            ("fvel", 0.1, {"for_s": 0.1}, ("--for-s", "0.1")),
            ("fstep_ack", 0.2, {"time_ms": 800}, ("--time-ms", "800")),
        ):
            ours = cube.motion(mode, value, **given).to_dict()
            same_names(f"motion {mode}", ours, cli(*pc, "motion", mode, str(value), *option)[0])
        sample = next(cube.watch(interval_ms=10, count=1))
        same_names("watch", sample.to_dict(), cli(*pc, "watch", "--count", "1")[0])
        same_names("stop", cube.stop().to_dict(), without(cli(*pc, "stop")[0], "holder"))
    same_names.check()


# --------------------------------------------------------------------------------------------- COMPAX


def test_compax_names(cli: Callable[..., List[Any]]) -> None:
    cx = ("compax", "--port", "sim", "--json")
    same_names = Names()
    with motionlink.Compax("sim") as drive:
        # Listings are JSON Lines: one object per drive.
        scanned = cli(*cx, "scan")
        same_names("scan", [d.to_dict() for d in drive.scan()], scanned)
        status = cli(*cx, "status")[0]
        assert set(status) - IDENTITY == {"drive", "status"}
        # Entry by entry: S1 (a number), S16 and S17 (flag words with their pattern).
        for ours, theirs in zip(drive.info(), status["status"]):
            assert ours.status == theirs["status"]
            same_names(f"status {ours.status}", ours.to_dict(), theirs)
        same_names("get", drive.get("P194").to_dict(), cli(*cx, "get", "P194")[0])
        same_names("set", drive.set("P3", 5).to_dict(), cli(*cx, "set", "P3", "5")[0])
        same_names("move_to", drive.move_to(10.0).to_dict(), cli(*cx, "move", "--abs", "10")[0])
        sample = next(drive.watch(interval_ms=10, count=1))
        same_names("watch", sample.to_dict(), cli(*cx, "watch", "--count", "1")[0])
        same_names("stop", drive.stop().to_dict(), without(cli(*cx, "stop")[0], "action", "holder"))
        same_names("output", drive.output(3, 1).to_dict(), cli(*cx, "output", "3", "1")[0])
    same_names.check()


# ------------------------------------------------------------------------------------- values, not only names


def same_values(python: Any, cli: Any) -> bool:
    """Equal JSON values (``family``, ``port`` and ``profile`` aside); a float of the wire (f32) as Python
    gives it (the shortest decimal, 0.05) against the command line's widened one (0.05000000074505806)."""
    if isinstance(python, dict) and isinstance(cli, dict):
        ours = {k: v for k, v in python.items() if k not in IDENTITY}
        theirs = {k: v for k, v in cli.items() if k not in IDENTITY}
        return ours.keys() == theirs.keys() and all(same_values(ours[k], theirs[k]) for k in ours)
    if isinstance(python, list) and isinstance(cli, list):
        return len(python) == len(cli) and all(same_values(a, b) for a, b in zip(python, cli))
    if isinstance(python, float) or isinstance(cli, float):
        return python == pytest.approx(cli, rel=1e-6)
    return bool(python == cli)


def test_python_gives_the_values_the_command_line_prints(cli: Callable[..., List[Any]]) -> None:
    """One conversion of the library's reports: a fresh emulator's records equal the command line's
    objects value for value (the emulators start the same way)."""
    pc = ("powercube", "--port", "sim", "--json")
    with motionlink.PowerCube("sim") as cube:
        for ours, args in [
            (cube.info(), ("info",)),
            (cube.state(), ("state",)),
            (cube.get("MaxVel"), ("get", "MaxVel")),
            (cube.get("ActFPosStateDio"), ("get", "ActFPosStateDio")),
        ]:
            theirs = cli(*pc, *args)[0]
            assert same_values(ours.to_dict(), theirs), f"{args}: {ours.to_dict()} != {theirs}"
        scanned = cli(*pc, "scan")
        assert same_values([m.to_dict() for m in cube.scan()], scanned)
    with motionlink.Compax("sim") as drive:
        theirs = cli("compax", "--port", "sim", "--json", "get", "P194")[0]
        assert same_values(drive.get("P194").to_dict(), theirs), theirs
    with motionlink.Scu("sim") as scu:
        theirs = cli("scu", "--port", "sim", "--json", "get", "actual_position_a1")[0]
        assert same_values(scu.get("actual_position_a1").to_dict(), theirs), theirs
