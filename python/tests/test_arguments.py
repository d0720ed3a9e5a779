"""Bad arguments are UsageErrors naming the argument and its range, before anything is sent (never an
OverflowError or a TypeError from the conversion), and an SCU error bit reaches Python as a DeviceError
with its code and named bits."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any, Callable, Dict, List

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
        (lambda: motionlink.Scu("sim").position(-1), r"actuator -1: the actuator must be a whole number from 1 to 6"),
        (lambda: motionlink.Scu("sim").move_to(1, 300, speed=-5), r"speed -5: a motion needs a whole number from 1 to 100 %"),
        (lambda: motionlink.Scu("sim").move_to(1, 2**40), r"target_counts \d+: a position must be a whole number of counts"),
        (lambda: motionlink.Scu("sim").move_to(1, 300, function=11), r"function 11: the motion function must be a whole"),
        (lambda: motionlink.Scu("sim", baud=-1), r"baud -1: an SCU runs at 9600, 19200 or 38400 baud"),
        (lambda: motionlink.Scu("sim", safety=True), r"safety True \(a bool\): the Safety_ID must be a whole number from 0 to 2"),
        (lambda: motionlink.Compax("sim").output(0, 300), r"output state 300 is out of range \(0 or 1"),
        (lambda: motionlink.Compax("sim").output(-1, 1), r"output number -1 is out of range \(0\.\.=65535\)"),
        (lambda: motionlink.Compax("sim").output(1, "1"), r"state \(of the output\) '1' \(a str, not an int\)"),
        (lambda: motionlink.Compax("sim").position(32), r"drive address 32 is out of range \(1\.\.=31\)"),
        (lambda: motionlink.Compax("sim").position(2**70), r"drive \d+: give a whole number 1\.\.=31"),
        (lambda: motionlink.Compax("sim").move_to(1.0, ramp_ms=-1), r"ramp time -1 ms is out of range"),
        (lambda: motionlink.Compax("sim", mode=-1), r"P196 -1 is out of range"),
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


# ------------------------------------------------------------------------------------------------ SCU
# One rule, one message: the library's argument types check every SCU argument, so the same bad value gets
# the same message from the command line and from Python (each front end names the argument its own way).

SCU_BAD = [
    # (the Python call on an open client, or None to open one; the command line; what Python puts first)
    (lambda s: motionlink.Scu("sim", baud=5), ["--baud", "5", "info"], "baud 5: "),
    (lambda s: motionlink.Scu("sim", safety=3), ["--safety", "3", "info"], "safety 3: "),
    (lambda s: motionlink.Scu("sim", tolerance_counts=101), ["--tolerance", "101", "info"], "tolerance_counts 101: "),
    (lambda s: motionlink.Scu("sim", reply_timeout_ms=0), ["--timeout-ms", "0", "info"], "reply_timeout_ms 0: "),
    (lambda s: motionlink.Scu("sim", poll_ms=4), ["--poll-ms", "4", "info"], "poll_ms 4: "),
    (lambda s: motionlink.Scu("sim", functions="F11=1"), ["--functions", "F11=1", "info"], "functions: "),
    (lambda s: motionlink.Scu("sim", strokes="1=9:1"), ["--stroke", "1=9:1", "info"], "strokes: "),
    (lambda s: s.position(7), ["move", "7", "100"], "actuator 7: "),
    (lambda s: s.move_to(1, 100, speed=0), ["move", "1", "100", "--speed", "0"], "speed 0: "),
    (lambda s: s.move_to(1, 100, speed=101), ["move", "1", "100", "--speed", "101"], "speed 101: "),
    (lambda s: s.move_to(1, 100, function=11), ["move", "1", "100", "--function", "11"], "function 11: "),
    (lambda s: s.move_to(1, 2**40), ["move", "1", str(2**40)], f"target_counts {2**40}: "),
    (lambda s: s.run("F30", "on"), ["run", "F30", "on"], ""),
    (lambda s: s.run(1, "sidewayz"), ["run", "F1", "sidewayz"], ""),
    (lambda s: s.run(11, "off"), ["run", "F11", "off"], ""),
    (lambda s: s.run(1, "out", seconds=-1), ["run", "F1", "out", "--seconds", "-1"], "seconds -1: "),
    (lambda s: s.stop("F30"), ["stop", "F30"], ""),
    (lambda s: s.get("actual_positoin_a1"), ["get", "actual_positoin_a1"], ""),
    (lambda s: s.set("actual_positions", 1), ["set", "actual_positions", "1"], ""),
    (lambda s: s.set("actual_position_a1", 1), ["set", "actual_position_a1", "1"], ""),
    (lambda s: s.set("remote_speed_f1", "fast"), ["set", "remote_speed_f1", "fast"], ""),
]


@pytest.mark.parametrize("call,cli,named", SCU_BAD)
def test_an_scu_argument_gets_the_same_message_from_the_command_line_and_python(
    motionlink_bin: Path, call: Callable[[motionlink.Scu], object], cli: List[str], named: str
) -> None:
    with motionlink.Scu("sim") as scu:
        with pytest.raises(motionlink.UsageError) as e:
            call(scu)
    message = str(e.value)
    assert message.startswith(named), message
    rule = message[len(named):]
    assert len(rule) > 10, message
    done = subprocess.run(
        [str(motionlink_bin), "scu", "--port", "sim", *cli], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2, done.stderr
    assert rule in done.stderr, f"python: {message}\ncli:    {done.stderr}"


# The same bad value through the command line and through Python: the same words, from the COMPAX crate's
# one rule (motionlink_compax::model::args). Each case: the command line's arguments after
# `compax --port sim`, Python's call on a client (or its constructor's keyword arguments), and the message.
COMPAX_SAME: List[Any] = [
    (["--drive", "32", "status"], {"drive": 32}, "drive address 32 is out of range (1..=31)"),
    (["--mode", "200", "status"], {"mode": 200}, "P196 200 is out of range"),
    (["--baud", "1234", "status"], {"baud": 1234}, "baud rate 1234 is out of range (one P195 accepts: 150,"),
    (["--timeout-ms", "0", "status"], {"timeout_ms": 0}, "reply timeout 0 ms is out of range (1..=60000 ms)"),
    (["move", "1", "--poll-ms", "0"], {"poll_ms": 0}, "poll interval 0 ms is out of range (1..=10000 ms)"),
    (["move", "1", "--tolerance", "0"], {"tolerance_units": 0.0}, "in-position tolerance 0 is out of range"),
    (["move", "1", "--accel", "0"], lambda c: c.move_to(1.0, ramp_ms=0), "ramp time 0 ms is out of range"),
    (["move", "1", "--speed", "0"], lambda c: c.move_to(1.0, speed_percent=0), "speed 0 % is out of range"),
    (["move", "1", "--speed", "101"], lambda c: c.move_to(1.0, speed_percent=101), "speed 101 % is out of range"),
    (["move", "1e9"], lambda c: c.move_to(1e9), "position 1000000000 is out of range"),
    (["move", "1", "--timeout-s", "0"], lambda c: c.move_to(1.0, timeout_s=0), "time limit 0 s is out of range"),
    (["output", "3", "2"], lambda c: c.output(3, 2), "output state 2 is out of range (0 or 1 (O0: 0, 1 or 2))"),
    (["output", "70000", "1"], lambda c: c.output(70000, 1), "output number 70000 is out of range (0..=65535)"),
    (["set", "P196", "200"], lambda c: c.set("P196", 200), "parameter value P196=200 is out of range"),
    (["get", "devce_address"], lambda c: c.get("devce_address"), "did you mean device_address?"),
    (["status", "S99"], lambda c: c.status(["S99"]), "status value S99 is out of range (S1..=S40)"),
]


@pytest.mark.parametrize("cli_args,python,message", COMPAX_SAME, ids=[" ".join(c[0]) for c in COMPAX_SAME])
def test_compax_refuses_a_bad_value_with_the_same_words_as_the_command_line(
    motionlink_bin: Path, cli_args: List[str], python: Any, message: str
) -> None:
    done = subprocess.run(
        [str(motionlink_bin), "--json", "compax", "--port", "sim", *cli_args], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2, done
    cli_message = json.loads(done.stderr.splitlines()[-1])["message"]
    with pytest.raises(motionlink.UsageError) as e:
        if isinstance(python, dict):
            settings: Dict[str, Any] = python
            motionlink.Compax("sim", **settings)
        else:
            with motionlink.Compax("sim") as drive:
                python(drive)
    python_message = str(e.value)
    assert message in python_message, python_message
    # The command line says which option or argument it was, then the crate's words, as Python says them.
    assert python_message in cli_message, (python_message, cli_message)


# ------------------------------------------------------------------------------------- values of another type
# A value of the wrong type is a UsageError naming the argument and the value, never a TypeError, a ValueError
# from a conversion, an OverflowError, or a bool taken as a number (True moved a PowerCube to 1.0 rad).


def _on_scu(call: Callable[[motionlink.Scu], object]) -> Callable[[], object]:
    def run() -> object:
        with motionlink.Scu("sim") as scu:
            return call(scu)

    return run


def _on_cube(call: Callable[[motionlink.PowerCube], object]) -> Callable[[], object]:
    def run() -> object:
        with motionlink.PowerCube("sim") as cube:
            return call(cube)

    return run


def _on_drive(call: Callable[[motionlink.Compax], object]) -> Callable[[], object]:
    def run() -> object:
        with motionlink.Compax("sim") as drive:
            return call(drive)

    return run


WRONG_TYPES = [
    # A bool or a str where a number goes (motion targets included).
    (_on_cube(lambda c: c.move_to(True)), r"^target True \(a bool\): give a number$"),
    (_on_cube(lambda c: c.move_to("0.5")), r"^target '0\.5' \(a str, not a number\): give a number$"),
    (_on_cube(lambda c: c.move_to(0.5, velocity=True)), r"^velocity True \(a bool\)"),
    (_on_cube(lambda c: c.move_to(0.5, acceleration="1")), r"^acceleration '1' \(a str, not a number\)"),
    (_on_cube(lambda c: c.move_to(0.5, tolerance=False)), r"^tolerance False \(a bool\)"),
    (_on_cube(lambda c: c.move_to(0.5, timeout_s=True)), r"^timeout_s True \(a bool\)"),
    (_on_cube(lambda c: c.home(timeout_s="60")), r"^timeout_s '60' \(a str, not a number\)"),
    (_on_cube(lambda c: c.wait(timeout_s=None)), r"^timeout_s None \(a NoneType, not a number\)"),
    (_on_cube(lambda c: c.set("TargetVel", True)), r"^value True \(a bool\): give a number$"),
    (_on_drive(lambda d: d.move_to(True)), r"^target True \(a bool\): give a number$"),
    (_on_drive(lambda d: d.move_to(distance=True)), r"^distance True \(a bool\)"),
    (_on_drive(lambda d: d.move_to(1.0, speed_percent=True)), r"^speed_percent True \(a bool\)"),
    (_on_drive(lambda d: d.move_to(1.0, timeout_s=True)), r"^timeout_s True \(a bool\)"),
    (_on_drive(lambda d: d.move_to(1.0, min_units="0")), r"^min_units '0' \(a str, not a number\)"),
    (_on_drive(lambda d: d.home(timeout_s=True)), r"^timeout_s True \(a bool\)"),
    (_on_drive(lambda d: d.set("P194", True)), r"^value True \(a bool\): give a number$"),
    (_on_drive(lambda d: d.set("P194", "x")), r"^value 'x' \(a str, not a number\): give a number$"),
    (lambda: motionlink.Compax("sim", tolerance_units=True), r"^tolerance_units True \(a bool\)"),
    (lambda: motionlink.Compax("sim", tolerance_units="x"), r"^tolerance_units 'x' \(a str, not a number\)"),
    (_on_scu(lambda s: s.run(1, "out", seconds=True)), r"^seconds True \(a bool\): give a number$"),
    (_on_scu(lambda s: s.run(1, 5)), r"^direction 5 \(an int, not a str\): give a str$"),
    # Something else where a bool goes.
    (lambda: motionlink.PowerCube("sim", watchdog="no"), r"^watchdog 'no' \(a str, not a bool\): give True or False$"),
    (_on_scu(lambda s: s.stop(1, soft="yes")), r"^soft 'yes' \(a str, not a bool\): give True or False$"),
    (lambda: motionlink.Emulator("powercube", strict="x"), r"^strict 'x' \(a str, not a bool\)"),
    (lambda: motionlink.Emulator("powercube", can=1), r"^can 1 \(an int, not a bool\)"),
    (lambda: motionlink.probe("scu", "sim", low_latency="x"), r"^low_latency 'x' \(a str, not a bool\)"),
    # A number (or None) where a text or a list goes.
    (lambda: motionlink.Scu("sim", functions=5), r"^functions 5 \(an int\): give a str or a list of str$"),
    (lambda: motionlink.Scu("sim", functions=None), r"^functions None \(a NoneType\): give a str or a list"),
    (lambda: motionlink.Scu("sim", functions=["tlt", 5]), r"^functions 5 \(an int\): give a str$"),
    (lambda: motionlink.Scu("sim", strokes=5), r"^strokes 5 \(an int\): give a str or a list of str$"),
    (lambda: motionlink.Scu("sim", speed_mode=1), r"^speed_mode 1 \(an int, not a str\)"),
    (lambda: motionlink.Emulator("compax", drives=5), r"^drives 5 \(an int\): give a list$"),
    (lambda: motionlink.Emulator("powercube", modules="12"), r"^modules '12' \(a str\): give a list$"),
    (lambda: motionlink.Emulator("compax", variant=5), r"^variant 5 \(an int\): give a str or a list of str$"),
    (lambda: motionlink.Emulator("compax", params=5), r"^params 5 \(an int\): give a dict$"),
    (lambda: motionlink.Emulator("compax", params={"P12": "x"}), r"^params P12 'x' \(a str, not a number\)"),
    (lambda: motionlink.Emulator("compax", params={"P12": True}), r"^params P12 True \(a bool\)"),
    (lambda: motionlink.Emulator("scu", preset=5), r"^preset 5 \(an int, not a str\)"),
    (lambda: motionlink.Emulator(5), r"^family 5 \(an int, not a str\)"),
    (lambda: motionlink.Scu("sim", profile=5), r"^profile 5 \(an int\)"),
    (lambda: motionlink.probe("scu", "sim", save=5), r"^save 5 \(an int\)"),
    (_on_drive(lambda d: d.status(None)), r"^names None \(a NoneType\)"),
    (_on_drive(lambda d: d.status([True])), r"^names True \(a bool\)"),
    # probe(exchanges=): the command line's rule, 1..=1000 (`--exchanges 0` exits 2).
    (lambda: motionlink.probe("scu", "sim", exchanges=-1), r"^exchanges -1: give a whole number 1\.\.=1000$"),
    (lambda: motionlink.probe("scu", "sim", exchanges=0), r"^exchanges 0: give a whole number 1\.\.=1000$"),
    (lambda: motionlink.probe("powercube", "sim", exchanges=1001), r"^exchanges 1001: give a whole number 1\.\.=1000$"),
    (lambda: motionlink.probe("compax", "sim", exchanges=100_000), r"^exchanges 100000: give a whole number"),
    (lambda: motionlink.probe("scu", "sim", exchanges=True), r"^exchanges True \(a bool\): give a whole number"),
    (lambda: motionlink.probe("scu", "sim", exchanges=2**70), rf"^exchanges {2**70}: give a whole number 1\.\.=1000$"),
]


def _case(named: str) -> str:
    """A case's id: what the message starts with (the argument and the value), without the regex's escapes."""
    return named.replace("\\", "").lstrip("^").split(" (")[0].split(":")[0]


@pytest.mark.parametrize("call,named", WRONG_TYPES, ids=[_case(n) for _, n in WRONG_TYPES])
def test_a_value_of_another_type_is_a_usage_error_naming_the_argument_and_the_value(
    call: Callable[[], object], named: str
) -> None:
    with pytest.raises(motionlink.UsageError, match=named) as e:
        call()
    assert isinstance(e.value, ValueError) and e.value.kind == "usage" and e.value.exit_code == 2


def test_a_number_of_either_type_is_taken_where_a_float_goes() -> None:
    """An int is a number wherever a float goes (and a float that is a whole number writes as an int does)."""
    with motionlink.PowerCube("sim") as cube:
        assert cube.move_to(1, velocity=1, timeout_s=30).reached_rad == pytest.approx(1.0, abs=1e-3)
        assert cube.set("TargetVel", 1).value == cube.set("TargetVel", 1.0).value
    with motionlink.Compax("sim", tolerance_units=1) as drive:
        assert drive.move_to(2, speed_percent=50, timeout_s=60).reached_units == pytest.approx(2.0, abs=0.01)
        assert drive.set("P3", 5).read_back == 5.0
    with motionlink.Scu("sim") as scu:
        assert scu.run(1, "out", seconds=0).function == 1


def test_probe_takes_the_command_lines_range_of_exchanges(motionlink_bin: Path) -> None:
    """1..=1000, as `motionlink probe --exchanges` takes it: the ends are taken, and the binary refuses what
    Python refuses."""
    assert motionlink.probe("scu", "sim", exchanges=1).link["exchanges"] == 1
    assert motionlink.probe("scu", "sim", exchanges=1000).link["exchanges"] == 1000
    for n in (0, 1001):
        with pytest.raises(motionlink.UsageError):
            motionlink.probe("scu", "sim", exchanges=n)
        done = subprocess.run(
            [str(motionlink_bin), "probe", "scu", "--port", "sim", "--exchanges", str(n)],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode == 2 and "1..=1000" in done.stderr, done.stderr
