"""Typed results. Each is a read-only record whose attributes are named as the command line's ``--json``
names them: snake_case, with the unit in the name of every number that has one (``position_counts``,
``position_rad``, ``position_m``, ``position_units``, ``current_amps``, ``time_s``, ``t_s`` ...).

A PowerCube module's positions are named after its kind: ``position_rad`` on a rotary module,
``position_m`` on a linear one, and ``unit`` says which (``"rad"`` or ``"m"``); asking a rotary module's
record for ``position_m`` raises ``AttributeError`` naming the fields it has. A module whose kind the
session has not read yet reports ``position`` with ``unit == "module"``.

Every record has :meth:`Record.to_dict`: the command line's JSON object for the same operation, with
exactly its keys, nested the same way (``family`` and ``port`` aside: the command line adds them, a
record has ``family``). Some records carry a few more attributes than that object (a move's
``start_counts`` / ``start_rad`` / ``start_units``, a PowerCube module's ``unit``, a COMPAX status value's
``drive`` and ``id``): they are attributes only, never in ``to_dict()``. Records compare equal to a record
of the same type with the same fields.
"""

from __future__ import annotations

from typing import Any, Dict, List

from ._record import ErrorBit, ErrorCode, FlagWord, Parameter, Record

__all__ = [
    "Record",
    "ErrorBit",
    "ErrorCode",
    "FlagWord",
    "Parameter",
    "ModuleInfo",
    "ModuleState",
    "ModulePosition",
    "PowerCubeMove",
    "PowerCubeMotion",
    "PowerCubeSetpoint",
    "PowerCubeHome",
    "PowerCubeStop",
    "PowerCubeSample",
    "ActuatorState",
    "ActuatorPosition",
    "ScuInfo",
    "ActuatorOutcome",
    "ScuMove",
    "ActuatorRest",
    "ScuRun",
    "ActuatorSample",
    "ScuSample",
    "DriveFound",
    "DrivePosition",
    "StatusValue",
    "CompaxStarted",
    "CompaxMove",
    "CompaxHome",
    "DriveStopped",
    "CompaxStop",
    "CompaxOutput",
    "CompaxSample",
]


# ----------------------------------------------------------------------------------------------- PowerCube


class ModuleState(Record):
    """A PowerCube module's state word (CubeState), as ``state`` and ``wait`` give it.

    Attributes:
        family: ``"powercube"``.
        module: The address, 1..31.
        word: The raw state word.
        flags: Every flag set, as the manual spells it (``"STATE_HALTED"``).
        faults: The flags set that are errors.
        unknown_bits: Bits set that no flag names (only when nonzero).
    """

    family: str
    module: int
    word: int
    flags: List[str]
    faults: List[str]
    unknown_bits: int


class _WithState(Record):
    """A PowerCube result with the module's state word nested as ``state`` (a :class:`FlagWord` with
    ``faults``)."""

    family: str
    module: int
    state: FlagWord


class ModuleInfo(_WithState):
    """What a scan or ``info`` found about a module: its state (``state``), and:

    Attributes:
        kind: ``"rotary"`` or ``"linear"``.
        unit: ``"rad"`` or ``"m"`` (an attribute; not in ``to_dict()``).
        version: The firmware version.
        serial: The serial number.
        error: ``scan`` only: why a module that answered the scan could not be read (the other fields are
            then missing).
        min_position_rad, max_position_rad, max_velocity_rad_per_s, max_acceleration_rad_per_s2,
        position_rad: ``info`` on a rotary module: its limits and position (``_m``, ``_m_per_s``,
        ``_m_per_s2`` on a linear one).
    """

    kind: str
    unit: str
    version: str
    serial: int
    error: str
    min_position_rad: float
    max_position_rad: float
    max_velocity_rad_per_s: float
    max_acceleration_rad_per_s2: float
    position_rad: float
    min_position_m: float
    max_position_m: float
    max_velocity_m_per_s: float
    max_acceleration_m_per_s2: float
    position_m: float


class ModulePosition(Record):
    """A module's actual position.

    Attributes:
        family: ``"powercube"``.
        module: The address.
        unit: ``"rad"``, ``"m"``, or ``"module"`` while the module's kind is not known (an attribute;
            not in ``to_dict()``, whose key of the position names the unit).
        position_rad: The position of a rotary module.
        position_m: The position of a linear module.
        position: The position of a module whose kind is not known (its own unit).
    """

    family: str
    module: int
    unit: str
    position_rad: float
    position_m: float
    position: float

    @property
    def value(self) -> float:
        """The position in ``unit``, whatever the module's kind."""
        return float(self.get("position_rad", self.get("position_m", self.get("position"))))


class _Path(_WithState):
    """A PowerCube motion's end: its positions in the module's unit (``_rad`` or ``_m``) and its checks."""

    action: str
    unit: str
    homed: bool
    verified: bool
    not_verifiable: List[str]
    start_rad: float
    target_rad: float
    reached_rad: float
    difference_rad: float
    start_m: float
    target_m: float
    reached_m: float
    difference_m: float


class PowerCubeMove(_Path):
    """A checked move that ended at its target: the module's state at the end (``state``), and where it
    went, in its unit (``"rad"``: ``target_rad``, ``reached_rad``, ``difference_rad``; ``"m"``: the same
    with ``_m``).

    Attributes:
        action: ``"reached"``.
        unit: ``"rad"`` or ``"m"`` (an attribute; not in ``to_dict()``).
        start_rad: Where the module stood before (an attribute; not in ``to_dict()``).
        target_rad: The target.
        reached_rad: The final actual position, read twice from the module, both within the tolerance.
        difference_rad: ``reached - target``.
        homed: True when the module showed STATE_HOME_OK at the end; a module not homed has the
            coordinates it took at power-on, and its MinPos/MaxPos (the target's check) hold only after
            homing.
        verified: True when every check of what the module took could be made (the velocity and
            acceleration written, and the motion's target, read back through their Inc twins).
        not_verifiable: What could not be checked, and why (empty when ``verified``).
    """


class PowerCubeMotion(_Path):
    """A motion of one of the manual's modes run to its end, as ``motionlink powercube motion --json``
    reports it: the state at the end (``state``), how it ended (``ended``) and where the module went, in
    its unit (``_rad`` on a rotary module, ``_m`` on a linear one).

    Attributes:
        action: ``"ran"``.
        mode: The manual's name of the MotionID sent (``"FVEL_MODE"``, ``"FSTEP_ACK"``).
        ended: ``"reached"`` (a position mode, at rest within its tolerance), ``"velocity_zero"`` (a
            velocity mode after its hold: sent velocity 0, at rest) or ``"halted"`` (a current or loop mode
            after its hold: halted until :meth:`PowerCube.reset`).
        unit: ``"rad"`` or ``"m"`` (an attribute; not in ``to_dict()``).
        start_rad: Where the module stood before.
        target_rad: A position mode's target (an IRAMP / ISTEP target in the module's unit).
        reached_rad: Where the module came to rest at the end.
        difference_rad: A position mode's ``reached - target``.
        held_s: A velocity, current or loop mode: how long it ran before it was ended.
        ext_ack: An ``_ACK`` mode's extended acknowledge: ``position``, ``position_unit`` (``"rad"``,
            ``"m"`` or ``"ticks"``), ``short_state`` and ``dio`` (flag words as dicts).
        homed, verified, not_verifiable: As :class:`PowerCubeMove`'s (a velocity, current or loop command
            cannot be read back: ``verified`` is False and ``not_verifiable`` says so).
    """

    mode: str
    ended: str
    held_s: float
    ext_ack: Dict[str, Any]


class PowerCubeSetpoint(Record):
    """A streamed setpoint's acknowledge (:meth:`PowerCube.setpoint`): the command was taken.

    Attributes:
        family: ``"powercube"``.
        module: The address, 1..31.
        mode: The manual's name of the MotionID sent (``"FVEL_ACK"``).
        ext_ack: An ``_ACK`` mode's extended acknowledge, where the module stood as it took the command:
            ``position``, ``position_unit`` (``"rad"``, ``"m"`` or ``"ticks"``), ``short_state`` and ``dio``
            (flag words as dicts); absent for a simple acknowledge.
        watchdog: True when the module's watchdog is armed and refreshed by this client (until it closes).
        unit: ``"rad"`` or ``"m"`` (an attribute; not in ``to_dict()``).
    """

    family: str
    module: int
    mode: str
    ext_ack: Dict[str, Any]
    watchdog: bool
    unit: str


class PowerCubeHome(_WithState):
    """The end of homing: the state (``state``) and where the module stands (``reached_rad`` or
    ``reached_m``).

    Attributes:
        action: ``"homed"``.
        unit: ``"rad"`` or ``"m"`` (an attribute; not in ``to_dict()``).
        reached_rad: The position after homing (rotary).
        reached_m: The position after homing (linear).
    """

    action: str
    unit: str
    reached_rad: float
    reached_m: float


class PowerCubeStop(_WithState):
    """A halt confirmed by the module's state read back until it was at rest, as ``motionlink powercube
    stop --json`` reports it (without ``holder``, which only the command knows): the state (``state``,
    STATE_HALTED set) and where the module stands.

    Attributes:
        ok: True.
        action: ``"halted"``.
        unit: ``"rad"`` or ``"m"`` (an attribute; not in ``to_dict()``).
        position_rad: The position read after the halt (rotary).
        position_m: The position read after the halt (linear).
    """

    ok: bool
    action: str
    unit: str
    position_rad: float
    position_m: float


class PowerCubeSample(_WithState):
    """One sample of ``watch``: the state (``state``) and the position.

    Attributes:
        t_s: Seconds since the start of the watch.
        unit: ``"rad"`` or ``"m"`` (an attribute; not in ``to_dict()``).
        position_rad: The position (rotary).
        position_m: The position (linear).
    """

    t_s: float
    unit: str
    position_rad: float
    position_m: float


# ------------------------------------------------------------------------------------------------------ SCU


class ActuatorState(Record):
    """An actuator of an SCU as ``info`` reports it.

    Attributes:
        actuator: 1..6.
        position_counts: Its position in encoder counts.
        flags: Its status 1 flags, as the manual names them.
        moving: True while it moves.
    """

    actuator: int
    position_counts: int
    flags: List[str]
    moving: bool


class ActuatorPosition(Record):
    """An SCU actuator's position (``Scu.position``).

    Attributes:
        family: ``"scu"``.
        actuator: 1..6.
        position_counts: Its position in encoder counts.
    """

    family: str
    actuator: int
    position_counts: int

    def __int__(self) -> int:
        return int(self.position_counts)


class ScuInfo(Record):
    """What ``info`` reads from an SCU.

    Attributes:
        family: ``"scu"``.
        port: The port.
        firmware: The firmware info text.
        configuration: The configuration info text.
        battery_mains: The battery/mains word (a :class:`FlagWord`).
        last_error: Error_Code 1 with its named bits.
        actuators: The connected actuators.
    """

    family: str
    port: str
    firmware: str
    configuration: str
    battery_mains: FlagWord
    last_error: ErrorCode
    actuators: List[ActuatorState]


class ActuatorOutcome(Record):
    """Where one actuator of a move ended.

    Attributes:
        actuator: 1..6.
        target_counts: Its target.
        reached_counts: Where it ended.
        difference_counts: ``reached - target``.
        moved: False for an actuator whose remote position was written but which its function does not
            drive.
        start_counts: Where it stood before (an attribute; not in ``to_dict()``).
    """

    actuator: int
    target_counts: int
    reached_counts: int
    start_counts: int
    difference_counts: int
    moved: bool


class ScuMove(Record):
    """A verified SCU move: every actuator the function drives ended within the tolerance.

    Attributes:
        family: ``"scu"``.
        function: The motion function (1..10).
        actuator: The actuator asked for.
        target_counts: Its target.
        reached_counts: Where it ended.
        time_s: How long the move took.
        actuators: Every actuator whose remote position the move wrote.
        verified: True if every check was made (targets against the strokes, writes read back); where the
            actuators ended is checked in any case.
        not_verifiable: What the unit in use could not be asked to verify, and why (empty when verified).
    """

    family: str
    function: int
    actuator: int
    target_counts: int
    reached_counts: int
    time_s: float
    actuators: List[ActuatorOutcome]
    verified: bool
    not_verifiable: List[str]


class ActuatorRest(Record):
    """Where an actuator came to rest.

    Attributes:
        actuator: 1..6.
        reached_counts: Its position.
    """

    actuator: int
    reached_counts: int


class ScuRun(Record):
    """A function run until it ended (or its time limit), then stopped (the unit confirmed the stop).

    Attributes:
        family: ``"scu"``.
        function: The function's number (1..22).
        stopped: True.
        interrupted: False (Ctrl-C raises ``KeyboardInterrupt`` instead of returning).
        actuators: Where the actuators came to rest.
        verified: A switching function (F11..F22): the status entry that shows it showed it on after the RE
            and off after the RS (absent for a motion function).
        not_verifiable: A switching function: why that could not be verified (empty when ``verified``).
        time_s: How long it ran (an attribute; not in ``to_dict()``).
    """

    family: str
    function: int
    stopped: bool
    interrupted: bool
    actuators: List[ActuatorRest]
    verified: bool
    not_verifiable: List[str]
    time_s: float


class ActuatorSample(Record):
    """One actuator in a sample of ``watch``.

    Attributes:
        actuator: 1..6.
        position_counts: Its position.
        moving: True while it moves.
        flags: Its status 1 flags.
        current_amps: Its motor current in A.
    """

    actuator: int
    position_counts: int
    moving: bool
    flags: List[str]
    current_amps: float


class ScuSample(Record):
    """One sample of an SCU's ``watch``.

    Attributes:
        family: ``"scu"``.
        t_s: Seconds since the start of the watch.
        actuators: The connected actuators.
        last_error: Error_Code 1.
    """

    family: str
    t_s: float
    actuators: List[ActuatorSample]
    last_error: ErrorCode


# --------------------------------------------------------------------------------------------------- COMPAX


class DriveFound(Record):
    """A drive that answered a scan.

    Attributes:
        family: ``"compax"``.
        drive: Its address (1..31).
        position_units: Its actual position S1, in the drive's unit.
    """

    family: str
    drive: int
    position_units: float


class DrivePosition(Record):
    """Where a COMPAX drive stands: S1, in the drive's unit (``position``, ``wait``, ``home``).

    Attributes:
        family: ``"compax"``.
        drive: The drive.
        position_units: S1.
    """

    family: str
    drive: int
    position_units: float

    def __float__(self) -> float:
        return float(self.position_units)


class StatusValue(Record):
    """A COMPAX status value (S1 .. S40), as an entry of the command line's ``status``.

    Attributes:
        family: ``"compax"``.
        status: ``"S1"`` ...
        name: What it is, where the manuals say (the title).
        unit: Its unit (``""`` when none).
        value: A number; for the status bit words S16 and S17 a :class:`FlagWord` with ``pattern``.
        drive: The drive (an attribute; not in ``to_dict()``).
        id: Its number, 1 for S1 (an attribute; not in ``to_dict()``).
    """

    _nested = {"value": FlagWord}
    family: str
    status: str
    name: str
    unit: str
    value: Any
    drive: int
    id: int


class CompaxStarted(Record):
    """A move the drive took (its target read back from S2), not waited for.

    Attributes:
        family: ``"compax"``.
        drive: The drive.
        start_units: S1 before the move.
        target_units: The absolute target.
    """

    family: str
    drive: int
    start_units: float
    target_units: float


class CompaxMove(Record):
    """A checked COMPAX move that ended at its target.

    Attributes:
        family: ``"compax"``.
        drive: The drive.
        start_units: S1 before the move.
        target_units: The target.
        reached_units: S1 at rest.
        difference_units: ``reached - target``.
        tolerance_units: The in-position tolerance the move was checked against.
        waited: True (the move was waited for).
        verified: True when every check of what the drive took could be made (the echo of the stored move
            in full, and its target read back from S2).
        not_verifiable: What could not be checked, and why (empty when ``verified``): a drive that echoes
            without its address or flag characters, or not at all.
        start_units: S1 before the move (an attribute; not in ``to_dict()``).
    """

    family: str
    drive: int
    waited: bool
    verified: bool
    not_verifiable: List[str]
    start_units: float
    target_units: float
    reached_units: float
    difference_units: float
    tolerance_units: float


class CompaxHome(DrivePosition):
    """The end of homing (POSA HOME): S1 at rest (``position_units``)."""


class DriveStopped(Record):
    """How a stop ended for one drive.

    Attributes:
        drive: The drive.
        outcome: ``"at_rest"`` (S17 showed it at rest: nothing was sent, it stays switched on),
            ``"switched_off"`` (OUTPUT O0=0, confirmed by S17) or ``"not_confirmed"``.
        reason: Why it was not confirmed (only then).
    """

    drive: int
    outcome: str
    reason: str


class CompaxStop(Record):
    """A stop confirmed by S17, as ``motionlink compax stop --json`` reports it (without ``action`` and
    ``holder``, which only the command knows).

    Attributes:
        family: ``"compax"``.
        drive: The drive.
        drives: How the stop ended, per drive (:class:`DriveStopped`).
        confirmed: True (an unconfirmed stop raises).
        position_units: S1 read after the stop (``None`` if it could not be read; then
            ``position_not_read`` says why).
        o0: Output O0 from S16 read after the stop: 1 the drive is switched on, 0 off (``None`` if S16 could
            not be read; then ``o0_not_read`` says why). ``output(0, 1)`` switches it on again.
    """

    family: str
    drive: int
    drives: List[DriveStopped]
    confirmed: bool
    position_units: Any
    position_not_read: str
    o0: Any
    o0_not_read: str


class CompaxOutput(Record):
    """An output switched (OUTPUT Ox=y), as ``motionlink compax output --json`` reports it.

    Attributes:
        family: ``"compax"``.
        drive: The drive.
        output: The output's number (0: the drive itself, switched off, on, or 2).
        state: The state sent.
        read_back: O0 as S16 showed it afterwards (``None`` for another output, which is not read back, or
            when S16 could not be read). O0 read back as another state raises :class:`DeviceError`.
        verified: True when the state was read back and is the one sent.
        not_verifiable: Why it was not read back (empty when ``verified``).
    """

    family: str
    drive: int
    output: int
    state: int
    read_back: Any
    verified: bool
    not_verifiable: List[str]


class CompaxSample(Record):
    """One sample of a COMPAX ``watch`` (the library's watch): S1 and S17.

    Attributes:
        family: ``"compax"``.
        t_s: Seconds since the start of the watch.
        drive: The drive.
        position_units: S1.
        s17: S17 as a :class:`FlagWord` with ``pattern``.
        moving: True while a command is active (S17 COMMAND_ACTIVE), or while S1 changed beyond the
            in-position tolerance since the previous sample (a drive may move without S17's bit 3).
    """

    family: str
    t_s: float
    drive: int
    position_units: float
    s17: FlagWord
    moving: bool

