"""Ewellix/Schaeffler SCU control units (lifting columns): :class:`Scu`.

Positions are encoder counts (``position_counts``); speeds are percent of full speed (``speed_mode=
"percent"``, standard units) or counts per second on units set to absolute speed.
"""

from __future__ import annotations

from typing import Any, Iterator, List, Optional, Sequence, Union

from ._args import texts
from ._base import AsyncClientBase, ClientBase, samples
from ._ops import op
from ._probe import Profile, ProbeReport, profile_setting, save_setting
from ._record import Record
from .records import ActuatorPosition, ErrorCode, Parameter, ScuInfo, ScuMove, ScuRun, ScuSample

__all__ = ["Scu", "AsyncScu", "ScuStop", "ActuatorAtRest", "RefusedStop"]


class ActuatorAtRest(Record):
    """Where an actuator rests after a stop (its status was read back: it does not move).

    Attributes:
        actuator: 1..6.
        position_counts: Its position, in encoder counts.
    """

    actuator: int
    position_counts: int


class RefusedStop(Record):
    """An RS the unit refused (the other functions were stopped all the same).

    Attributes:
        function: The motion function (1..10).
        reason: The unit's answer.
    """

    function: int
    reason: str


class ScuStop(Record):
    """How :meth:`Scu.stop` stopped, as ``motionlink scu stop [FUNCTION] --json`` reports it (without what only
    the command knows: ``action``, ``holder``, ``stopped``).

    Attributes:
        family: ``"scu"``.
        function: The function named (1..22; absent when every motion function was stopped).
        functions: The motion functions sent RS, in that order (1..10).
        mode: ``"fast"`` or ``"soft"`` (along the stop ramp); ``"off"`` for a switching function (F11..F22)
            named, switched off with RS (its record has ``function``, ``mode``, ``verified`` and
            ``not_verifiable`` only).
        refused: The RS the unit refused, with its answer.
        at_rest: Every connected actuator and where it rests, read after the stop.
        verified: A switching function: the status entry that shows it showed it off after the RS.
        not_verifiable: A switching function: why that could not be verified (empty when ``verified``).
    """

    family: str
    function: int
    functions: List[int]
    mode: str
    refused: List[RefusedStop]
    at_rest: List[ActuatorAtRest]
    verified: bool
    not_verifiable: List[str]


Specs = Union[str, Sequence[str]]
"""One specification (a str), or several (a list), as the command line's repeated option takes them."""


def _specs(specs: Specs, name: str) -> List[str]:
    """A str is one specification (``"tlt"``, ``"F1=1,2"``), never a sequence of letters; a list holds
    several. Anything else is a :class:`UsageError` naming ``name``."""
    return texts(specs, name, "scu")


def _function(f: Union[int, str]) -> str:
    return f"F{f}" if isinstance(f, int) and not isinstance(f, bool) else str(f)


def _position(client: Any, counts: int, actuator: int) -> ActuatorPosition:
    return ActuatorPosition({"family": "scu", "actuator": actuator, "position_counts": counts})


def _stop_args(function: Optional[Union[int, str]], soft: bool) -> tuple:
    return (None if function is None else _function(function), soft)


class _Operations:
    """The operations of :class:`Scu` and (``aio``) :class:`AsyncScu`, declared once."""

    family = "scu"
    _native_name = "ScuClient"
    _start: Any

    def __init__(
        self,
        port: Optional[Union[str, Any]] = None,
        *,
        baud: int = 38_400,
        safety: int = 0,
        reply_timeout_ms: int = 2000,
        functions: Specs = (),
        strokes: Specs = (),
        tolerance_counts: int = 5,
        poll_ms: int = 50,
        speed_mode: str = "percent",
        profile: Profile = True,
        wake: bool = False,
    ) -> None:
        settings = dict(baud=baud, safety=safety, reply_timeout_ms=reply_timeout_ms, functions=_specs(functions, "functions"))
        settings.update(strokes=_specs(strokes, "strokes"), tolerance_counts=tolerance_counts, poll_ms=poll_ms)
        self._start(port, dict(settings, speed_mode=speed_mode, profile=profile_setting(profile), wake=wake))

    @op(ScuInfo)
    def info(self) -> ScuInfo:
        """Firmware and configuration texts, battery/mains, the last error and the connected actuators."""

    @op(_position, aio=True, with_args=True)
    def position(self, actuator: int) -> ActuatorPosition:
        """The position of ``actuator`` (1..6): ``position_counts``, in encoder counts."""

    @op(Parameter, args=lambda name: (str(name),))
    def get(self, name: str) -> Parameter:
        """Reads a data-list entry or group by name (``"actual_position_a1"``, ``"actual_positions"``) or
        index (``"0x0011"``). Currents come in A, voltages in V (``unit`` says)."""

    @op(Parameter, args=lambda name, value: (str(name), value))
    def set(self, name: str, value: Union[int, float, str]) -> Parameter:
        """Writes a remote data entry (``"remote_speed_f1"``, ``"remote_position_a1"``); the library reads it
        back and compares (a difference is a :class:`DeviceError`). ``read_back`` is the value then read
        from the unit, ``verified`` True; on a unit that does not read remote data back, ``read_back`` is
        None, ``verified`` False and ``not_verifiable`` says why."""

    @op(ScuMove, aio=True)
    def move_to(
        self, actuator: int, target_counts: int, *, speed: int = 100, function: Optional[int] = None
    ) -> ScuMove:
        """Moves ``actuator`` to ``target_counts`` with its function (F1 for A1, or ``function``) at
        ``speed`` and waits; returns only if every actuator the function drives ended within
        ``tolerance_counts`` (else :class:`DeviceError`). Ctrl-C stops it (RS); cancelling the awaiting
        task stops the function."""

    move = move_to

    @op(ScuRun, aio=True, args=lambda function, direction, seconds: (_function(function), direction, seconds))
    def run(self, function: Union[int, str], direction: str, *, seconds: Optional[float] = None) -> ScuRun:
        """Runs a function until it ends, ``seconds`` passed, or Ctrl-C (or the awaiting task's
        cancellation), then stops it: a motion function with a direction (``"in"``, ``"out"``, ``"mem1"``
        ...), or F11, F17/F18, F20, F21/F22 with ``"on"`` (its status read back after the RE and the RS:
        ``verified``, ``not_verifiable``)."""

    @op(ScuStop, aio=True, args=_stop_args)
    def stop(self, function: Optional[Union[int, str]] = None, *, soft: bool = False) -> ScuStop:
        """Stops what moves, as ``motionlink scu stop`` does: RS to the motion function named (``1``,
        ``"F1"``), or without ``function`` to every one (F1..F10), fast or along the stop ramp (``soft``);
        then the status of every actuator is read until none moves. Returns where each connected actuator
        rests (:class:`ScuStop`), or raises if the unit did not confirm it. A switching function named
        (F11..F22: buzzer, outputs, emergency stop, LEDs) is switched off with RS, acknowledged by the unit,
        and the status entry that shows it is read back (its record: ``function``, ``mode`` ``"off"``,
        ``verified``, ``not_verifiable``; a status that shows it still on raises :class:`DeviceError`)."""

    @op(ErrorCode)
    def errors(self) -> List[ErrorCode]:
        """The error history: Error_Code 1 (the most recent) to 5, each with its named bits."""


class Scu(_Operations, ClientBase):
    """A session with an SCU control unit in remote mode (RO with ``safety``; the library keeps it alive).

    Args:
        port: A serial device (``"/dev/ttyUSB0"``, ``"COM3"``), ``"tcp://HOST:PORT"``, ``"sim"`` (an emulated
            unit in this process, with the ``functions`` map), or a :class:`motionlink.Emulator`. Not given:
            the environment variable ``MOTIONLINK_PORT``; neither is a :class:`UsageError`.
        baud: 38400 on standard units (9600 or 19200 on customised ones).
        safety: The Safety_ID sent with RO: 0 a timeout stops all motion and locks remote motion until RO,
            1 stops all motion, 2 stops remote motion only.
        reply_timeout_ms: How long to wait for the reply to RO (the unit is allowed 2000 ms).
        functions: Which actuators each motion function drives (the unit's parameterisation), as the
            command line's ``--functions``: one specification (a str), a preset ``"scp11"``, ``"tlt"`` or
            ``"liftkit"``, or one function ``"F1=1,2"``; or a list of them, applied in order (a preset
            replaces the whole map): ``["tlt", "F4=1"]``. With ``port="sim"`` the emulated unit is
            parameterised the same way.
        strokes: Travel ranges for move targets, ``"1=0:865"`` (actuator=min:max in counts); a list for
            several actuators.
        tolerance_counts: How close to its target a move must end to succeed, in counts (0..100).
        poll_ms: How often a move looks at the actuators (5..10000).
        speed_mode: ``"percent"`` or ``"counts_per_s"``.
        profile: The device profile (``motionlink probe scu --save``, :func:`motionlink.probe`): ``True``
            takes the one in profiles.toml beside devices.toml when the unit gives the same firmware and
            configuration texts (its probes are then skipped; another unit's is left alone with a warning),
            ``False`` none, a path that profiles file. :attr:`profile` names the one taken. The emulator's
            firmware variants (``motionlink sim scu --variant``, :class:`motionlink.Emulator`) show what
            each probe finds.
        wake: Hold the unit's RxD at "space" for 150 ms before opening (a break, ``motionlink scu
            --wake``): a battery unit in low-power mode answers nothing until woken so. A serial port (or
            an emulator in this process) only.

    Leaving a ``with`` block, ``close()`` or the end of the program sends RS for every function this
    session started, then RA. Ctrl-C during ``move_to`` or ``run`` stops the function (fast RS), then
    raises ``KeyboardInterrupt``; during ``info`` it raises at once (nothing is in motion; the reads in
    flight end on their own thread).
    """

    def probe(
        self, *, save: Union[bool, str, Any] = False, exchanges: int = 20, low_latency: bool = False
    ) -> ProbeReport:
        """``motionlink probe scu``'s report of this unit (see :func:`motionlink.probe`); nothing moves.
        ``save`` writes its profile (``True``: profiles.toml beside devices.toml; a path: that file)."""
        return ProbeReport(self._native.probe(exchanges, low_latency, save_setting(save)))

    def watch(self, *, interval_ms: int = 250, count: Optional[int] = None) -> Iterator[ScuSample]:
        """Samples of every connected actuator (position, moving, flags, current) every ``interval_ms``."""

        def read(t_s: float) -> ScuSample:
            return ScuSample(self._native.sample(t_s))

        return samples(read, interval_ms, count)


class AsyncScu(_Operations, AsyncClientBase):
    """The asyncio twin of :class:`Scu` (same arguments)::

        async with AsyncScu("tcp://127.0.0.1:5000") as scu:
            await scu.move_to(1, 400)

    Cancelling a task that awaits ``move_to`` or ``run`` stops the function (fast RS, confirmed); leaving
    the block (or ``aclose()``, or the end of the program) first cancels the operations still under way
    (their awaiters get :class:`motionlink.Cancelled`), then sends RS for what the session started, then RA.
    """
