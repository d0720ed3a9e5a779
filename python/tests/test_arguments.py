"""Bad arguments are UsageErrors naming the argument and its range, before anything is sent (never an
OverflowError or a TypeError from the conversion), and an SCU error bit reaches Python as a DeviceError
with its code and named bits."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Callable, List

import pytest

import motionlink

SERVE = str(Path(__file__).with_name("_serve.py"))


@pytest.mark.parametrize(
    "call,named",
    [
        (lambda: motionlink.PowerCube("sim").position(300), r'module address "300": give a number 1\.\.31'),
        (lambda: motionlink.PowerCube("sim").position(-1), r'module address "-1": give a number 1\.\.31'),
        (lambda: motionlink.PowerCube("sim", module=2**70), r"module \d+: give a whole number 1\.\.=31"),
        (lambda: motionlink.PowerCube("sim").position("1"), r"module '1' \(a str, not an int\)"),
        (lambda: motionlink.Scu("sim").position(-1), r"actuator -1: give a whole number 1\.\.=6"),
        (lambda: motionlink.Scu("sim").move_to(1, 300, speed=-5), r"speed \(%\) -5: give a whole number 1\.\.=100"),
        (lambda: motionlink.Scu("sim").move_to(1, 2**40), r"target_counts \d+: give a whole number"),
        (lambda: motionlink.Scu("sim").move_to(1, 300, function=11), r"function \(a motion function\) 11"),
        (lambda: motionlink.Scu("sim", baud=-1), r"baud -1: give a whole number 1\.\.="),
        (lambda: motionlink.Scu("sim", safety=True), r"safety \(the Safety_ID\) True \(a bool\)"),
        (lambda: motionlink.Compax("sim").output(0, 300), r"state \(of the output\) 300: give a whole number 0\.\.=255"),
        (lambda: motionlink.Compax("sim").output(-1, 1), r"number \(the output\) -1"),
        (lambda: motionlink.Compax("sim").position(32), r"drive 32: give a whole number 1\.\.=31"),
        (lambda: motionlink.Compax("sim").move_to(1.0, ramp_ms=-1), r"ramp_ms -1"),
        (lambda: motionlink.Compax("sim", mode=-1), r"mode \(P196\) -1"),
        (lambda: motionlink.Emulator("compax", mode=-1), r"mode \(P196\) -1: give a whole number 0\.\.="),
        (lambda: motionlink.Emulator("powercube", modules=[1, 300]), r"modules: address 300: give a whole number 1\.\.=31"),
        (lambda: motionlink.Emulator("compax", drives=[-3]), r"drives: address -3"),
    ],
)
def test_a_bad_integer_is_a_usage_error_naming_it(call: Callable[[], object], named: str) -> None:
    with pytest.raises(motionlink.UsageError, match=named) as e:
        call()
    assert isinstance(e.value, ValueError) and e.value.kind == "usage"


#: A bad value of each PowerCube argument: the command line's words and Python's call that give it.
POWERCUBE_BAD_VALUES = [
    (["--module", "0", "info"], lambda: motionlink.PowerCube("sim", module=0)),
    (["--module", "300", "info"], lambda: motionlink.PowerCube("sim").position(300)),
    (["--baud", "7", "info"], lambda: motionlink.PowerCube("sim", baud=7)),
    (["--bitrate", "12345", "info"], lambda: motionlink.PowerCube("sim", bitrate=12345)),
    (["--timeout-ms", "0", "info"], lambda: motionlink.PowerCube("sim", timeout_ms=0)),
    (["--poll-ms", "10001", "info"], lambda: motionlink.PowerCube("sim", poll_ms=10001)),
    (["move", "nan"], lambda: motionlink.PowerCube("sim").move_to(float("nan"))),
    (["move", "1", "--vel", "-5"], lambda: motionlink.PowerCube("sim").move_to(1, velocity=-5)),
    (["move", "1", "--acc", "0"], lambda: motionlink.PowerCube("sim").move_to(1, acceleration=0)),
    (["move", "1", "--tolerance", "0.5"], lambda: motionlink.PowerCube("sim").move_to(1, tolerance=0.5)),
    (["move", "1", "--timeout-s", "0"], lambda: motionlink.PowerCube("sim").move_to(1, timeout_s=0)),
    (["home", "--timeout-s", "-1"], lambda: motionlink.PowerCube("sim").home(timeout_s=-1)),
]


@pytest.mark.parametrize("words,call", POWERCUBE_BAD_VALUES, ids=[" ".join(w) for w, _ in POWERCUBE_BAD_VALUES])
def test_a_bad_powercube_argument_gets_the_same_message_from_the_command_line_and_python(
    motionlink_bin: Path, words: List[str], call: Callable[[], object]
) -> None:
    """One rule per argument, in the library (motionlink_powercube::args): the binary refuses the value
    before opening anything (exit 2, clap naming the option) with the library's message, and Python raises a
    UsageError with the same message."""
    with pytest.raises(motionlink.UsageError) as e:
        call()
    message = str(e.value)
    done = subprocess.run(
        [str(motionlink_bin), "powercube", "--port", "tcp://127.0.0.1:1", *words],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2, done.stderr
    first = done.stderr.splitlines()[0]
    assert first.endswith(": " + message), f"python: {message!r}\ncli:    {first!r}"


def test_an_scu_error_bit_is_a_device_error_with_its_code_and_named_bits() -> None:
    """The emulated unit raises error bit 12 (over-temperature) 2 s after power-on, while A1 moves slowly:
    the unit stops every motion, and the move ends in a DeviceError whose code has that bit and whose bits
    name it, as the unit's Error_Code does. (The emulator runs in a child process: its power-on is that
    process's start.)"""
    config = "preset = \"scp11\"\n[[error]]\nbit = 12\nat_ms = 2000\n"
    server = subprocess.Popen(
        [sys.executable, SERVE, "scu", config], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert server.stdout is not None
        port = server.stdout.readline().strip()
        with motionlink.Scu(port, functions=["scp11"]) as scu:
            assert scu.errors()[0].code == 0, "the move starts before the error"
            with pytest.raises(motionlink.DeviceError) as e:
                scu.move_to(1, 800, speed=5)
            err = e.value
            assert err.code == 0x800, hex(err.code or 0)
            assert err.bits == [
                {"bit": 12, "name": "over_temperature", "cause": "overtemperature at rectifier or FET"}
            ]
            assert (err.kind, err.exit_code, err.family) == ("device", 1, "scu")
            assert "A1 ended at" in str(err) and scu.errors()[0].code == 0x800
    finally:
        server.communicate(input="", timeout=10)
