"""Typed results. Each is a read-only record whose attributes are named as the command line's ``--json``
names them: snake_case, with the unit in the name of every number that has one (``position_counts``,
``position_rad``, ``position_m``, ``position_units``, ``current_amps``, ``time_s``, ``t_s`` ...).

A PowerCube module's positions are named after its kind: ``position_rad`` on a rotary module,
``position_m`` on a linear one, and ``unit`` says which (``"rad"`` or ``"m"``); asking a rotary module's
record for ``position_m`` raises ``AttributeError`` naming the fields it has. A module whose kind the
session has not read yet reports ``position`` with ``unit == "module"``.

Every record has :meth:`Record.to_dict` (the JSON object) and compares equal to a record of the same type
with the same fields.
"""

from __future__ import annotations

from typing import Any, ClassVar, Dict, List, Mapping

__all__ = [
    "Record",
    "ErrorBit",
    "ErrorCode",
    "Parameter",
    "ModuleInfo",
    "ModuleState",
    "ModulePosition",
    "PowerCubeMove",
    "PowerCubeHome",
    "PowerCubeSample",
    "ActuatorState",
    "ScuInfo",
    "ActuatorOutcome",
    "ScuMove",
    "ActuatorRest",
    "ScuRun",
    "ActuatorSample",
    "ScuSample",
    "DriveFound",
    "StatusValue",
    "CompaxStarted",
    "CompaxMove",
    "CompaxHome",
    "CompaxSample",
]


class Record:
    """A read-only result with named fields (see the module documentation)."""

    __slots__ = ("_fields",)
    #: Fields whose values are records (or lists of records) of these types.
    _nested: ClassVar[Mapping[str, type]] = {}

    def __init__(self, fields: Mapping[str, Any]) -> None:
        own: Dict[str, Any] = dict(fields)
        for name, kind in self._nested.items():
            value = own.get(name)
            if isinstance(value, list):
                own[name] = [v if isinstance(v, Record) else kind(v) for v in value]
            elif isinstance(value, Mapping):
                own[name] = kind(value)
        object.__setattr__(self, "_fields", own)

    def __getattr__(self, name: str) -> Any:
        fields = object.__getattribute__(self, "_fields")
        try:
            return fields[name]
        except KeyError:
            have = ", ".join(fields)
            raise AttributeError(f"{type(self).__name__} has no field {name!r}; it has: {have}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"{type(self).__name__} is read-only")

    def __dir__(self) -> List[str]:
        return sorted(set(super().__dir__()) | set(self._fields))

    def __contains__(self, name: str) -> bool:
        return name in self._fields

    def get(self, name: str, default: Any = None) -> Any:
        """The field ``name``, or ``default`` when the record has no such field."""
        return self._fields.get(name, default)

    def to_dict(self) -> Dict[str, Any]:
        """The record as the command line's JSON object (nested records as dicts)."""

        def plain(v: Any) -> Any:
            if isinstance(v, Record):
                return v.to_dict()
            if isinstance(v, list):
                return [plain(x) for x in v]
            return v

        return {k: plain(v) for k, v in self._fields.items()}

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other._fields == self._fields

    def __hash__(self) -> int:
        return hash((type(self).__name__, repr(self._fields)))

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={v!r}" for k, v in self._fields.items())
        return f"{type(self).__name__}({inner})"


class ErrorBit(Record):
    """One named bit of an error code or state word.

    Attributes:
        bit: The bit's number as the manual counts it.
        name: The manual's name.
        cause: What it means.
    """

    __slots__ = ()
    bit: int
    name: str
    cause: str


class ErrorCode(Record):
    """An error code with its named bits (SCU Error_Code).

    Attributes:
        code: The raw code.
        bits: The bits set, named.
    """

    __slots__ = ()
    _nested = {"bits": ErrorBit}
    code: int
    bits: List[ErrorBit]


class Parameter(Record):
    """A parameter, data-list entry or status value read or written.

    Attributes:
        family: ``"scu"``, ``"powercube"`` or ``"compax"``.
        name: Its name (``ActPos``, ``actual_position_a1``, ``P194``).
        id: Its number on the wire (ParamID, data index, parameter number).
        value: The value (a number, a text, or for groups and compound values a dict).
        unit: Its unit (``""`` when none).
        access: ``"r"``, ``"w"`` or ``"rw"``.
        read_back: After a write: the value read back (``None`` if it cannot be read back; then
            ``not_verifiable`` says why). Only on the result of ``set``.
        module: PowerCube: the module (1..31).
        drive: COMPAX: the drive (1..31).
    """

    __slots__ = ()
    family: str
    name: str
    id: int
    value: Any
    unit: str
    access: str
    read_back: Any
    module: int
    drive: int


# ----------------------------------------------------------------------------------------------- PowerCube


class ModuleState(Record):
    """A PowerCube module's state word (CubeState).

    Attributes:
        family: ``"powercube"``.
        module: The address, 1..31.
        code: The raw state word.
        flags: Every flag set, as the manual spells it (``"STATE_HALTED"``).
        faults: The flags set that are errors.
        unknown_bits: Bits set that no flag names (only when nonzero).
    """

    __slots__ = ()
    family: str
    module: int
    code: int
    flags: List[str]
    faults: List[str]
    unknown_bits: int


class ModuleInfo(ModuleState):
    """What a scan or ``info`` found about a module: its state, and:

    Attributes:
        kind: ``"rotary"`` or ``"linear"``.
        unit: ``"rad"`` or ``"m"``.
        version: The firmware version.
        serial: The serial number.
        error: ``scan`` only: why a module that answered the scan could not be read (the other fields are
            then missing).
        min_position_rad, max_position_rad, max_velocity_rad_per_s, max_acceleration_rad_per_s2,
        position_rad: ``info`` on a rotary module: its limits and position (``_m``, ``_m_per_s``,
        ``_m_per_s2`` on a linear one).
    """

    __slots__ = ()
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
        unit: ``"rad"``, ``"m"``, or ``"module"`` while the module's kind is not known.
        position_rad: The position of a rotary module.
        position_m: The position of a linear module.
        position: The position of a module whose kind is not known (its own unit).
    """

    __slots__ = ()
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


class PowerCubeMove(ModuleState):
    """A checked move that ended at its target: the module's state at the end, and where it went, in its
    unit (``unit``: ``"rad"``: ``start_rad``, ``target_rad``, ``reached_rad``, ``difference_rad``; ``"m"``:
    the same with ``_m``).

    Attributes:
        unit: ``"rad"`` or ``"m"``.
        start_rad: Where the module stood before.
        target_rad: The target.
        reached_rad: The final actual position, read twice from the module, both within the tolerance.
        difference_rad: ``reached - target``.
    """

    __slots__ = ()
    unit: str
    start_rad: float
    target_rad: float
    reached_rad: float
    difference_rad: float
    start_m: float
    target_m: float
    reached_m: float
    difference_m: float


class PowerCubeHome(ModuleState):
    """The end of homing: the state and the position (``position_rad`` or ``position_m``).

    Attributes:
        unit: ``"rad"`` or ``"m"``.
        position_rad: The position after homing (rotary).
        position_m: The position after homing (linear).
    """

    __slots__ = ()
    unit: str
    position_rad: float
    position_m: float


class PowerCubeSample(ModuleState):
    """One sample of ``watch``: the state and the position.

    Attributes:
        t_s: Seconds since the start of the watch.
        unit: ``"rad"`` or ``"m"``.
        position_rad: The position (rotary).
        position_m: The position (linear).
    """

    __slots__ = ()
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

    __slots__ = ()
    actuator: int
    position_counts: int
    flags: List[str]
    moving: bool


class ScuInfo(Record):
    """What ``info`` reads from an SCU.

    Attributes:
        family: ``"scu"``.
        port: The port.
        firmware: The firmware info text.
        configuration: The configuration info text.
        battery_mains: The battery/mains word: ``{"code": int, "flags": [names], "unknown_bits": int}``
            (``unknown_bits`` only when nonzero).
        last_error: Error_Code 1 with its named bits.
        actuators: The connected actuators.
    """

    __slots__ = ()
    _nested = {"actuators": ActuatorState, "last_error": ErrorCode}
    family: str
    port: str
    firmware: str
    configuration: str
    battery_mains: Any
    last_error: ErrorCode
    actuators: List[ActuatorState]


class ActuatorOutcome(Record):
    """Where one actuator of a move ended.

    Attributes:
        actuator: 1..6.
        target_counts: Its target.
        position_counts: Where it ended.
        difference_counts: ``position - target``.
        moved: False for an actuator whose remote position was written but which its function does not
            drive.
    """

    __slots__ = ()
    actuator: int
    target_counts: int
    position_counts: int
    difference_counts: int
    moved: bool


class ScuMove(Record):
    """A verified SCU move: every actuator the function drives ended within the tolerance.

    Attributes:
        family: ``"scu"``.
        function: The motion function (1..10).
        actuator: The actuator asked for.
        target_counts: Its target.
        position_counts: Where it ended.
        time_s: How long the move took.
        actuators: Every actuator whose remote position the move wrote.
    """

    __slots__ = ()
    _nested = {"actuators": ActuatorOutcome}
    family: str
    function: int
    actuator: int
    target_counts: int
    position_counts: int
    time_s: float
    actuators: List[ActuatorOutcome]


class ActuatorRest(Record):
    """Where an actuator came to rest.

    Attributes:
        actuator: 1..6.
        position_counts: Its position.
    """

    __slots__ = ()
    actuator: int
    position_counts: int


class ScuRun(Record):
    """A function run until it ended (or its time limit), then stopped.

    Attributes:
        family: ``"scu"``.
        function: The function's number (1..22).
        rest: Where the actuators came to rest.
    """

    __slots__ = ()
    _nested = {"rest": ActuatorRest}
    family: str
    function: int
    rest: List[ActuatorRest]


class ActuatorSample(Record):
    """One actuator in a sample of ``watch``.

    Attributes:
        actuator: 1..6.
        position_counts: Its position.
        moving: True while it moves.
        flags: Its status 1 flags.
        current_amps: Its motor current in A.
    """

    __slots__ = ()
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

    __slots__ = ()
    _nested = {"actuators": ActuatorSample, "last_error": ErrorCode}
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

    __slots__ = ()
    family: str
    drive: int
    position_units: float


class StatusValue(Record):
    """A COMPAX status value (S1 .. S40).

    Attributes:
        family: ``"compax"``.
        drive: The drive.
        name: ``"S1"`` ...
        id: Its number (1 for S1).
        title: What it is, where the manuals say.
        unit: Its unit (``""`` when none).
        value: A number, or for the status bit words S16 and S17 the raw word.
        flags: S16 and S17: the meanings of the bits set.
    """

    __slots__ = ()
    family: str
    drive: int
    name: str
    id: int
    title: str
    unit: str
    value: Any
    flags: List[str]


class CompaxStarted(Record):
    """A move the drive took (its target read back from S2), not waited for.

    Attributes:
        family: ``"compax"``.
        drive: The drive.
        start_units: S1 before the move.
        target_units: The absolute target.
    """

    __slots__ = ()
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
    """

    __slots__ = ()
    family: str
    drive: int
    start_units: float
    target_units: float
    reached_units: float
    difference_units: float
    tolerance_units: float


class CompaxHome(Record):
    """The end of homing (POSA HOME).

    Attributes:
        family: ``"compax"``.
        drive: The drive.
        position_units: S1 at rest.
    """

    __slots__ = ()
    family: str
    drive: int
    position_units: float


class CompaxSample(Record):
    """One sample of a COMPAX ``watch``: S1 and S17.

    Attributes:
        family: ``"compax"``.
        t_s: Seconds since the start of the watch.
        drive: The drive.
        position_units: S1.
        moving: True while a command is active (S17).
        flags: The meanings of the S17 bits set.
    """

    __slots__ = ()
    family: str
    t_s: float
    drive: int
    position_units: float
    moving: bool
    flags: List[str]

