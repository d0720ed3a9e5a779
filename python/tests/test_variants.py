"""The core operations of every family through Python against every firmware variant of its emulator (issue
21, item 3), as crates/*/tests/variants.rs does through the library and crates/motionlink/tests/*_cli/
variants.rs through the command line: each operation works and says in ``verified`` / ``not_verifiable``
what it could not check, or raises a specific exception whose message names what the device did not do.
Never a hang, never a success on a move that did not end at its target.

Each case runs in a process of its own (``_variant_case.py``, which prints what every operation gave), under
a time limit: a case that hangs is killed and fails, naming the last operation that ended. The cases run a
few at a time (the emulated devices move in real time); each test waits for its own.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple

import pytest

import motionlink

CHILD = str(Path(__file__).with_name("_variant_case.py"))
#: How long one case may take before it counts as hung (each takes a few seconds).
CASE_LIMIT_S = 60.0
#: How many cases run side by side.
WORKERS = 6

#: Every variant each family's emulator knows (the emulators' own list: a new one fails
#: test_the_matrix_covers_every_variant until it is added here, with what it changes below).
VARIANTS: Dict[str, Tuple[str, ...]] = {
    "scu": (
        "no-groups",
        "no-user-positions",
        "no-cyclic-objects",
        "no-remote-readback",
        "rc-empty-data",
        "sleepy",
        "sticky-errors",
        "in-end-undershoot",
        "re-needs-rs",
        "late-motion-bit",
        "switch-status-unshown",
        "ack-without-motion",
        "rc-rearms-watchdog",
        "low-power",
    ),
    "powercube": (
        "no-twin-mirror",
        "no-broadcast-pair",
        "ack-length-6",
        "ext-ack-on-put-id",
        "no-pos-state-dio",
        "life-sign-unacknowledged",
        "no-config-word",
        "reset-clears-watchdog",
        "no-extended-ack",
        "late-motion-start",
    ),
    "compax": (
        "echo-without-address",
        "echo-bare",
        "no-echo",
        "echo-without-store",
        "status-value-only",
        "no-position-message",
        "slow-replies",
        "buffer-queues",
        "no-command-bit",
        "echo-executes",
    ),
}

#: Variants the matrix leaves out, each with the reason (and where it is tested instead).
NOT_IN_MATRIX: Dict[str, Dict[str, str]] = {
    "scu": {
        "low-power": "it answers nothing until a break wakes it, which a served emulator cannot carry (it is "
        "refused there): test_a_unit_in_low_power_mode_answers_once_woken runs it in this process with wake=True",
    },
    "compax": {
        "slow-replies": "its replies come 300 ms late: the suite's 50 ms reply timeout takes none of them, and with "
        "the 600 ms one such a drive needs a scan of 31 addresses takes over half a minute; the Rust tests run it "
        "(crates/motionlink-compax/tests/variants.rs, crates/motionlink/tests/compax_cli/variants.rs)",
    },
}

#: The variants the matrix runs, each alone and all together.
MATRIX: Dict[str, Tuple[str, ...]] = {
    family: tuple(v for v in names if v not in NOT_IN_MATRIX.get(family, {})) for family, names in VARIANTS.items()
}


@dataclass(frozen=True)
class Case:
    """One family's emulator with some variants, and the client that runs the core operations on it."""

    family: str
    variants: Tuple[str, ...] = ()
    client: str = "sync"
    #: None: the emulator in this process (a PowerCube then arms no watchdog); "tcp": served on a port.
    serve: Optional[str] = None
    can: bool = False
    #: COMPAX: P196 (64: replies carry the address).
    mode: int = 0

    @property
    def id(self) -> str:
        every = set(self.variants) == set(MATRIX[self.family])
        names = "all" if every else "+".join(self.variants) or "manual"
        where = [self.client, self.serve or ("can" if self.can else "in-process")]
        if self.mode:
            where.append(f"P196={self.mode}")
        return f"{self.family}-{names}-{'-'.join(where)}"

    def spec(self) -> str:
        return json.dumps(
            {
                "family": self.family,
                "variant": list(self.variants),
                "client": self.client,
                "serve": self.serve,
                "can": self.can,
                "mode": self.mode,
            }
        )


def each(family: str, **how: Any) -> List[Case]:
    """The manual's firmware, each variant of the matrix alone, and all of them together."""
    alone = [Case(family, (v,), **how) for v in MATRIX[family]]
    return [Case(family, (), **how), *alone, Case(family, MATRIX[family], **how)]


ALL_PC = VARIANTS["powercube"]
CASES: List[Case] = [
    *each("scu"),
    Case("scu", (), client="async"),
    Case("scu", MATRIX["scu"], client="async"),
    Case("scu", MATRIX["scu"], serve="tcp"),
    *each("powercube"),
    Case("powercube", ("ext-ack-on-put-id",), can=True),
    Case("powercube", ALL_PC, can=True),
    # Served, the client arms the modules' watchdog: the variants about it show only here.
    Case("powercube", (), serve="tcp"),
    Case("powercube", ("no-broadcast-pair",), serve="tcp"),
    Case("powercube", ("life-sign-unacknowledged",), serve="tcp"),
    Case("powercube", ("no-config-word",), serve="tcp"),
    Case("powercube", tuple(v for v in ALL_PC if v not in ("life-sign-unacknowledged", "no-config-word")), serve="tcp"),
    Case("powercube", ALL_PC, serve="tcp"),
    Case("powercube", (), client="async"),
    Case("powercube", ALL_PC, client="async"),
    Case("powercube", ("no-broadcast-pair",), client="async", serve="tcp"),
    *each("compax"),
    Case("compax", ("echo-without-address",), mode=64),
    Case("compax", ("echo-bare",), mode=8),
    Case("compax", (), client="async"),
    Case("compax", MATRIX["compax"], client="async"),
    Case("compax", MATRIX["compax"], serve="tcp"),
]


# ------------------------------------------------------------------------------------------- the runner


@dataclass
class Outcome:
    """What a case's process printed: each operation's line, by name; and how the process ended."""

    ops: Dict[str, Dict[str, Any]]
    order: List[str]
    returncode: Optional[int]
    stderr: str
    hung: bool

    def __str__(self) -> str:
        lines = [f"{name}: {json.dumps(self.ops[name])[:600]}" for name in self.order]
        return "\n".join(lines + [f"exit {self.returncode}; stderr:\n{self.stderr[-3000:]}"])


def run_case(case: Case) -> Outcome:
    proc = subprocess.Popen(
        [sys.executable, CHILD, case.spec()], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    hung = False
    try:
        out, err = proc.communicate(timeout=CASE_LIMIT_S)
    except subprocess.TimeoutExpired:
        hung = True
        proc.kill()
        out, err = proc.communicate()
    lines = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    return Outcome({d["op"]: d for d in lines}, [d["op"] for d in lines], proc.returncode, err, hung)


@pytest.fixture(scope="module")
def outcomes(request: pytest.FixtureRequest) -> Iterator[Dict[Case, "Future[Outcome]"]]:
    """Starts every selected case of this module at once (at most WORKERS at a time)."""
    selected = [
        item.callspec.params["case"]
        for item in request.session.items
        if item.module is request.module and hasattr(item, "callspec") and "case" in item.callspec.params
    ]
    with ThreadPoolExecutor(max_workers=WORKERS) as pool:
        futures = {case: pool.submit(run_case, case) for case in dict.fromkeys(selected)}
        yield futures
        for f in futures.values():
            f.cancel()


def outcome_of(case: Case, outcomes: Dict[Case, "Future[Outcome]"]) -> Outcome:
    o = outcomes[case].result()
    assert not o.hung, f"{case.id} hung: killed after {CASE_LIMIT_S} s; it had done:\n{o}"
    assert o.returncode == 0, f"{case.id}: the process failed:\n{o}"
    return o


# ------------------------------------------------------------------------------------------ assertions


def succeeded(o: Outcome, op: str, record: Optional[str] = None) -> Any:
    """The value of ``op``, which must have succeeded (with a result of class ``record``)."""
    line = o.ops.get(op)
    assert line is not None, f"{op} did not run:\n{o}"
    assert line["ok"], f"{op} failed: {line.get('error')}: {line.get('message')}"
    if record is not None:
        assert line["type"] == record, f"{op}: {line['type']}, not {record}"
    return line["value"]


def raised(o: Outcome, op: str, error: type, *phrases: str) -> str:
    """``op`` must have raised ``error`` (exactly that class) with each of ``phrases`` in its message."""
    line = o.ops.get(op)
    assert line is not None, f"{op} did not run:\n{o}"
    assert not line["ok"], f"{op} succeeded, but should have raised {error.__name__}: {line['value']}"
    assert line["error"] == error.__name__, f"{op}: {line['error']}, not {error.__name__}: {line['message']}"
    message = str(line["message"])
    for phrase in phrases:
        assert phrase in message, f"{op}: {phrase!r} is not in {message!r}"
    return message


def says_what_it_could_not_verify(result: Dict[str, Any], reasons: Sequence[Sequence[str]], what: str) -> None:
    """``verified`` is True exactly when ``reasons`` is empty; ``not_verifiable`` is a list of str, one per
    expected reason (in any order), each naming the behaviour (every phrase of one entry of ``reasons``)."""
    why = result["not_verifiable"]
    assert isinstance(why, list) and all(isinstance(w, str) and w for w in why), f"{what}: {why!r}"
    assert result["verified"] is (not reasons), f"{what}: verified {result['verified']}: {why}"
    assert len(why) == len(reasons), f"{what}: {len(why)} reasons, not {len(reasons)}: {why}"
    for phrases in reasons:
        hits = [w for w in why if all(p in w for p in phrases)]
        assert len(hits) == 1, f"{what}: no single reason says {list(phrases)}: {why}"


def without_reason(result: Dict[str, Any], phrase: str) -> Dict[str, Any]:
    """``result`` without the one reason of ``not_verifiable`` that says ``phrase`` (if it has it), and
    ``verified`` as the other reasons make it."""
    why = result["not_verifiable"]
    left = [w for w in why if phrase not in w]
    if len(left) == len(why):
        return result
    assert len(left) == len(why) - 1 and result["verified"] is False, f"{phrase!r}: {result}"
    return {**result, "not_verifiable": left, "verified": not left}


def reached(result: Dict[str, Any], suffix: str, target: float, tolerance: float, what: str) -> None:
    """A move that succeeded ended within ``tolerance`` of ``target``, and says so consistently."""
    assert result[f"target_{suffix}"] == pytest.approx(target), f"{what}: {result}"
    end = result[f"reached_{suffix}"]
    assert abs(end - target) <= tolerance, f"{what}: succeeded at {end}, not within {tolerance} of {target}"
    assert result[f"difference_{suffix}"] == pytest.approx(end - target, abs=1e-6), f"{what}: {result}"


# ------------------------------------------------------------------------------------------------- SCU


def scu_move_reasons(variants: Sequence[str], actuator: int) -> List[Tuple[str, ...]]:
    """What an SCU move says it could not verify on a unit with ``variants``."""
    reasons: List[Tuple[str, ...]] = []
    if "no-user-positions" in variants:
        reasons.append((f"A{actuator}'s target was not checked against a stroke", "refuses UserPositionData"))
    if "no-remote-readback" in variants:
        written = f"remote_position_a{actuator} (0x302{actuator}), remote_speed_f{actuator} (0x301{actuator})"
        reasons.append((written, "not read back"))
    return reasons


def check_scu(case: Case, o: Outcome) -> None:
    v = case.variants
    rest = -3 if "in-end-undershoot" in v else 0  # where A1 comes to rest at its In end
    succeeded(o, "open")
    for op, target in (("move_with_speed", (1, 400)), ("move_without_speed", (2, 300))):
        moved = succeeded(o, op, "ScuMove")
        actuator, counts = target
        assert (moved["actuator"], moved["function"]) == (actuator, actuator), f"{op}: {moved}"
        reached(moved, "counts", counts, 5, f"{case.id} {op}")
        says_what_it_could_not_verify(moved, scu_move_reasons(v, actuator), f"{case.id} {op}")
    home = succeeded(o, "home", "ScuRun")
    assert home["stopped"] is True and home["interrupted"] is False, home
    assert [(a["actuator"], a["reached_counts"]) for a in home["actuators"]] == [(1, rest), (2, 300)], home
    succeeded(o, "stop")
    # A target beyond the stroke (865 counts) never ends in success: refused before anything moves where the
    # unit gives its stroke, else the actuator stops at its end and the move fails saying where.
    if "no-user-positions" in v:
        raised(o, "move_outside_stroke", motionlink.DeviceError, "A1 ended at 865 counts", "target 900")
        at = 865
    else:
        raised(o, "move_outside_stroke", motionlink.UsageError, "outside A1's stroke 0..865", "nothing was moved")
        at = rest
    succeeded(o, "close")
    if case.client == "async":
        assert succeeded(o, "position", "ActuatorPosition")["position_counts"] == rest
        return
    assert at == succeeded(o, "position_after", "ActuatorPosition")["position_counts"]
    assert len(succeeded(o, "info", "ScuInfo")["actuators"]) == 2
    group = succeeded(o, "get_group", "Parameter")["value"]
    assert len(group) == 6 and succeeded(o, "get_entry")["value"] == group["actual_position_a1"], group
    written = succeeded(o, "set", "Parameter")
    read_back = "no-remote-readback" not in v
    assert written["read_back"] == (60 if read_back else None), written
    reasons = [] if read_back else [("remote_speed_f2 (0x3012)", "not read back", "refuses to read remote data")]
    says_what_it_could_not_verify(written, reasons, f"{case.id} set")
    assert succeeded(o, "started") == [], "stopped: nothing left started"
    samples = succeeded(o, "watch", "ScuSample")
    assert len(samples) == 3 and [s["t_s"] for s in samples] == sorted(s["t_s"] for s in samples)
    for s in samples:
        where = [(a["actuator"], a["position_counts"], a["moving"]) for a in s["actuators"]]
        assert where == [(1, rest, False), (2, 300, False)], s
    # A tolerance below the undershoot: the move to the In end did not end at its target, and fails.
    succeeded(o, "open_strict")
    reached(succeeded(o, "strict_move_out", "ScuMove"), "counts", 200, 2, "strict_move_out")
    if "in-end-undershoot" in v:
        raised(o, "strict_move_in_end", motionlink.DeviceError, "A1 ended at -3 counts", "tolerance of 2")
    else:
        reached(succeeded(o, "strict_move_in_end", "ScuMove"), "counts", 0, 2, "strict_move_in_end")
    succeeded(o, "close_strict")


# ------------------------------------------------------------------------------------------- PowerCube


def check_powercube(case: Case, o: Outcome) -> None:
    v = case.variants
    twins_apart = "no-twin-mirror" in v
    # Only a served module gets a watchdog (an in-process emulator dies with the program anyway).
    watchdog = case.serve is not None
    # Without the Config word the arming fails at its first read, before any life sign.
    no_config_word = watchdog and "no-config-word" in v
    no_life_sign_ack = watchdog and "life-sign-unacknowledged" in v and not no_config_word
    broadcast_ignored = watchdog and "no-broadcast-pair" in v
    no_config_word_refusal = ("cannot arm the watchdog of module 1", "before version 3.5.00 has no Config word")
    succeeded(o, "open")
    if no_config_word:
        # Its type is read from DefConfig; the arming's read of the Config word times out: refused, nothing moves.
        for op in ("home", "move_with_speed", "move_without_speed"):
            raised(o, op, motionlink.TimeoutError, *no_config_word_refusal)
        at = 0.05  # the emulated module's start
    elif no_life_sign_ack:
        # Whether the watchdog went online is not known: the guarded motions are refused, nothing moves; the
        # watchdog the life sign switched on all the same is switched off again and the module left as it was.
        raised(o, "home", motionlink.DeviceError, "cannot arm the watchdog of module 1", "not acknowledged")
        for op in ("move_with_speed", "move_without_speed"):
            raised(o, op, motionlink.DeviceError, "cannot arm the watchdog of module 1", "left as it was")
        at = 0.05  # the emulated module's start
    else:
        homed = succeeded(o, "home", "PowerCubeHome")
        assert homed["reached_rad"] == pytest.approx(0.0, abs=1e-3), homed
        watchdog_reason = [("watchdog could not be armed", "ignores the watchdog refresh broadcast on RS232")]
        # Homing that ran without the watchdog asked for says so, as a move does.
        says_what_it_could_not_verify(homed, watchdog_reason if broadcast_ignored else [], f"{case.id} home")
        target_reason = [("the motion's target could not be read back", "keeps TargetPosInc apart")]
        moves = (("move_with_speed", 0.3, ("TargetVel", "TargetAcc")), ("move_without_speed", 0.1, ()))
        for op, target, written in moves:
            moved = succeeded(o, op, "PowerCubeMove")
            assert moved["action"] == "reached" and "STATE_MOTION" not in moved["state"]["flags"], moved
            reached(moved, "rad", target, 1e-3, f"{case.id} {op}")
            reasons: List[Sequence[str]] = []
            if twins_apart:
                reasons += [(f"{w} could not be read back", f"keeps {w}Inc apart") for w in written]
                reasons += target_reason
            if broadcast_ignored:
                reasons += watchdog_reason
            says_what_it_could_not_verify(moved, reasons, f"{case.id} {op}")
        at = 0.1
    # The limits are checked before the guard arms the watchdog: a target beyond MaxPos is refused as such,
    # also by a module whose watchdog cannot be armed.
    message = raised(o, "move_outside_limit", motionlink.UsageError, "target position 100", "outside MinPos..MaxPos")
    assert "watchdog" not in message, message
    succeeded(o, "stop")
    assert "STATE_HALTED" in succeeded(o, "state_after_stop", "ModuleState")["flags"]
    # A refused arming leaves nothing for the close to find out (its watchdog already switched off again).
    succeeded(o, "close")
    if case.client == "async":
        assert succeeded(o, "position", "ModulePosition")["position_rad"] == pytest.approx(0.05, abs=1e-3)
        assert "STATE_MOTION" not in succeeded(o, "wait", "ModuleState")["flags"]
        return
    (module,) = succeeded(o, "scan", "ModuleInfo")
    assert (module["module"], module["serial"], module["kind"]) == (1, 1001, "rotary"), module
    got = succeeded(o, "get", "Parameter")
    assert (got["name"], got["unit"]) == ("ActPos", "rad"), got
    written = succeeded(o, "set", "Parameter")
    reasons = [("TargetVel could not be read back", "keeps TargetVelInc apart")] if twins_apart else []
    says_what_it_could_not_verify(written, reasons, f"{case.id} set")
    assert (written["read_back"] is None) is twins_apart, written
    samples = succeeded(o, "watch", "PowerCubeSample")
    assert len(samples) == 3 and all(s["position_rad"] == pytest.approx(at, abs=1e-3) for s in samples), samples
    # The refused armings before left no expired watchdog: the halted module is refused as halted.
    raised(o, "move_halted", motionlink.DeviceError, "halted (STATE_HALTED)", "send a reset")
    assert succeeded(o, "reset") is False
    if no_config_word:
        raised(o, "move_after_reset", motionlink.TimeoutError, *no_config_word_refusal)
    elif no_life_sign_ack:
        raised(o, "move_after_reset", motionlink.DeviceError, "cannot arm the watchdog of module 1", "left as it was")
    else:
        reached(succeeded(o, "move_after_reset", "PowerCubeMove"), "rad", 0.2, 1e-3, "move_after_reset")
    assert succeeded(o, "started") == []


# ---------------------------------------------------------------------------------------------- COMPAX


def compax_echo(case: Case) -> Tuple[Optional[List[Tuple[str, ...]]], Optional[str]]:
    """What a COMPAX move says it could not verify (None: it is refused), and the refusal's phrase."""
    v, prefixed = case.variants, bool(case.mode & 64)
    address = ("drive 1 echoes without its address", "could not be checked")
    if "no-echo" in v:
        return [("drive 1 does not echo a telegram sent with '?'", "read back after, from S2")], None
    if "echo-without-store" in v:
        # The '!' after the echo is refused: nothing ran, so the move goes out as a command of its own.
        refused = "drive 1 refused the '!' after echoing a move sent with ',?'"
        return [(refused, "without being checked before it started")], None
    if "echo-bare" in v:
        bare = ("drive 1 echoes without the flag characters", "could not be checked")
        return ([] if prefixed else [address]) + [bare], None
    if "echo-without-address" in v and not prefixed:
        return [address], None
    return [], None


def check_compax(case: Case, o: Outcome) -> None:
    reasons, refusal = compax_echo(case)
    succeeded(o, "open")
    assert succeeded(o, "home", "CompaxHome")["position_units"] == 0.0
    at = 0.0
    for op, target in (("move_with_speed", 20.0), ("move_without_speed", 15.0)):
        if reasons is None:
            raised(o, op, motionlink.DeviceRefused, "not executed", str(refusal), "so nothing ran")
            continue
        moved = succeeded(o, op, "CompaxMove")
        reached(moved, "units", target, moved["tolerance_units"], f"{case.id} {op}")
        assert moved["waited"] is True
        if "no-command-bit" in case.variants:
            # Seen (S1 moving while S17 shows no command) only if the move still runs at its first poll,
            # which the timing decides: a reason more if so (crates/motionlink-compax/tests/variants.rs
            # shows it on the manual clock).
            moved = without_reason(moved, "S17 did not show the positioning")
        says_what_it_could_not_verify(moved, reasons, f"{case.id} {op}")
        at = target
    raised(o, "move_outside_limits", motionlink.UsageError, "target 50 is outside the travel limits", "maximum 30")
    # At rest: `stop` (as `compax stop`) sends nothing but its reads and leaves the drive switched on.
    stopped = succeeded(o, "stop", "CompaxStop")
    assert stopped["confirmed"] and [d["outcome"] for d in stopped["drives"]] == ["at_rest"], stopped
    assert stopped["position_units"] == at, stopped
    succeeded(o, "close")
    if case.client == "async":
        assert succeeded(o, "position", "DrivePosition")["position_units"] == 0.0
        assert succeeded(o, "wait", "DrivePosition")["position_units"] == at
        return
    assert [(d["drive"], d["position_units"]) for d in succeeded(o, "scan", "DriveFound")] == [(1, 0.0), (3, 0.0)]
    status = succeeded(o, "status", "StatusValue")
    assert [(s["status"], s["name"]) for s in status][0] == ("S1", "actual position") and status[0]["value"] == 0.0
    assert "READY_FOR_START" in status[1]["value"]["flags"], status
    assert succeeded(o, "get", "Parameter")["value"] == 0.0
    written = succeeded(o, "set", "Parameter")
    assert written["read_back"] == 2.5, written
    says_what_it_could_not_verify(written, [], f"{case.id} set")
    samples = succeeded(o, "watch", "CompaxSample")
    assert len(samples) == 3 and all((s["position_units"], s["moving"]) == (at, False) for s in samples), samples
    assert stopped["o0"] == 1, stopped
    succeeded(o, "switch_off")
    raised(o, "move_switched_off", motionlink.DeviceError, "drive 1 is switched off (O0=0", "OUTPUT O0=1")
    succeeded(o, "switch_on")
    if reasons is None:
        raised(o, "move_after_switch_on", motionlink.DeviceRefused, str(refusal))
    else:
        reached(succeeded(o, "move_after_switch_on", "CompaxMove"), "units", 10.0, 0.01, "move_after_switch_on")
        at = 10.0
    assert succeeded(o, "position_after", "DrivePosition")["position_units"] == at
    assert succeeded(o, "started") == []


CHECKS = {"scu": check_scu, "powercube": check_powercube, "compax": check_compax}


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_core_operations(case: Case, outcomes: Dict[Case, "Future[Outcome]"]) -> None:
    o = outcome_of(case, outcomes)
    try:
        CHECKS[case.family](case, o)
    except AssertionError as e:
        raise AssertionError(f"{case.id}: {e}\n--- what each operation gave:\n{o}") from None
    # No operation came near its own time limit (a move's is 20 s; these take well under a second or two).
    slow = [(name, line["elapsed_s"]) for name, line in o.ops.items() if line["elapsed_s"] > 15]
    assert not slow, f"{case.id}: {slow}"


def test_the_matrix_covers_every_variant() -> None:
    """The lists above are the emulators' own (from the message that refuses an unknown name), and every
    variant runs alone and with the others in the matrix, but those it leaves out with a reason."""
    for family, ours in VARIANTS.items():
        with pytest.raises(motionlink.UsageError) as e:
            motionlink.Emulator(family, variant="not-a-variant")
        listed = re.search(r"(?:known: |the variants are )([a-z0-9, -]+)", str(e.value))
        assert listed is not None, str(e.value)
        assert tuple(n.strip() for n in listed.group(1).split(",")) == ours, str(e.value)
        left_out = NOT_IN_MATRIX.get(family, {})
        assert set(left_out) <= set(ours) and all(left_out.values()), family
        alone = {c.variants[0] for c in CASES if c.family == family and len(c.variants) == 1}
        assert alone == set(ours) - set(left_out), family
        assert any(c.variants == MATRIX[family] for c in CASES if c.family == family), family


def test_a_unit_in_low_power_mode_answers_once_woken() -> None:
    """A battery SCU in low-power mode (``low-power``) answers nothing until its RxD is held at space (a
    break): ``Scu(..., wake=True)`` sends one before opening; without it the opening fails on the line. A
    served emulator of that variant is refused (no break crosses TCP)."""
    emulator = motionlink.Emulator("scu", variant="low-power")
    try:
        with pytest.raises(motionlink.MotionlinkError) as e:
            motionlink.Scu(emulator, reply_timeout_ms=200)
        assert e.value.kind in ("timeout", "io", "disconnected"), e.value
        with motionlink.Scu(emulator, reply_timeout_ms=200, wake=True) as scu:
            assert scu.position(1).position_counts == 0
        events = [text for _, text in emulator.take_events()]
        assert "woken from low-power mode by a break of 150 ms" in events, events
        # The probe takes the client's options, `wake` among them.
        report = motionlink.probe("scu", emulator, wake=True)
        assert report.devices[0]["firmware"] == "SCU V2B3 motionlink-sim", report
    finally:
        emulator.close()
    with pytest.raises(motionlink.UsageError) as e:
        motionlink.Emulator("scu", variant="low-power", serve="tcp")
    assert "woken only by a break" in str(e.value)
