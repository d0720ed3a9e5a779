"""Schunk/Amtec PowerCube modules: :class:`PowerCube` (blocking) and :class:`AsyncPowerCube` (asyncio).

Positions are in the module's own unit: radians on a rotary module, metres on a linear one; every result
names which (``position_rad`` / ``position_m``, and ``unit``).
"""

from __future__ import annotations

from typing import Any, Iterator, List, Optional, Union

from ._base import AsyncClientBase, ClientBase, samples
from ._ops import op
from ._probe import Profile, ProbeReport, profile_setting, save_setting
from .records import (
    ModuleInfo,
    ModulePosition,
    ModuleState,
    Parameter,
    PowerCubeHome,
    PowerCubeMotion,
    PowerCubeMove,
    PowerCubeSample,
    PowerCubeSetpoint,
    PowerCubeStop,
)

__all__ = ["PowerCube", "AsyncPowerCube"]

Port = Union[str, Any]


def _position(raw: Any) -> ModulePosition:
    module, value, unit = raw
    suffix = {"rad": "position_rad", "m": "position_m"}.get(unit, "position")
    # `unit` is an attribute only, not in `to_dict()`: the key of the position names the unit, as in the
    # command line's JSON (`powercube watch --json`: `position_rad`, no `unit`).
    return ModulePosition(
        {"family": "powercube", "module": module, suffix: value, "unit": unit, "_extras": ("unit",)}
    )


class _Operations:
    """The operations of :class:`PowerCube` and (``aio``) :class:`AsyncPowerCube`, declared once."""

    family = "powercube"
    _native_name = "PowerCubeClient"
    _start: Any
    #: The module the operations address unless they name another (1..31): the constructor's ``module``.
    module: int

    def __init__(
        self,
        port: Optional[Port] = None,
        module: int = 1,
        *,
        baud: int = 9600,
        bitrate: int = 1_000_000,
        timeout_ms: Optional[int] = None,
        poll_ms: int = 10,
        watchdog: bool = True,
        profile: Profile = True,
    ) -> None:
        self.module = module
        settings = dict(module=module, baud=baud, bitrate=bitrate, timeout_ms=timeout_ms, poll_ms=poll_ms)
        self._start(port, dict(settings, watchdog=watchdog, profile=profile_setting(profile)))

    @op(_position, aio=True)
    def position(self, module: Optional[int] = None) -> ModulePosition:
        """The actual position (``position_rad`` or ``position_m``)."""

    @op(ModuleState, aio=True)
    def state(self, module: Optional[int] = None) -> ModuleState:
        """The module's state word (CubeState), flag by flag."""

    @op(PowerCubeHome, aio=True)
    def home(self, module: Optional[int] = None, *, timeout_s: float = 60.0) -> PowerCubeHome:
        """Homes the module and waits for the end of homing (``reached_rad`` / ``reached_m``). Ctrl-C
        halts it; cancelling the awaiting task halts it."""

    @op(PowerCubeMove, aio=True)
    def move_to(
        self,
        target: float,
        module: Optional[int] = None,
        *,
        velocity: Optional[float] = None,
        acceleration: Optional[float] = None,
        tolerance: Optional[float] = None,
        timeout_s: float = 60.0,
    ) -> PowerCubeMove:
        """A ramp move to ``target`` (rad or m, the module's unit), waited for and checked: it returns only
        if the module came to rest within ``tolerance`` of the target (else :class:`DeviceError`).
        ``velocity`` (unit/s) and ``acceleration`` (unit/s²) default to the module's. Ctrl-C halts it;
        cancelling the awaiting task halts it."""

    move = move_to

    @op(PowerCubeMotion, aio=True)
    def motion(
        self,
        mode: str,
        value: float,
        module: Optional[int] = None,
        *,
        time_ms: Optional[int] = None,
        for_s: Optional[float] = None,
        tolerance: Optional[float] = None,
        timeout_s: float = 60.0,
    ) -> PowerCubeMotion:
        """A motion of one of the manual's modes (``mode``: ``"fvel"``, ``"FSTEP_MODE"``, ``"ivel_ack"``
        ...; FSTEP, FVEL, FCUR, IRAMP, ISTEP, IVEL, ICUR, FCOSLOOP, FRAMPLOOP, FRAMP) with ``value`` in the
        mode's unit (a position, velocity or current; ticks, ticks/s or digits in the I modes) and
        ``time_ms`` for FSTEP, ISTEP and FCOSLOOP, checked against the module's limits before anything
        moves, as ``motionlink powercube motion`` runs it. A position mode returns once the module is at
        rest within ``tolerance`` of its target; a velocity, current or loop mode runs for ``for_s``
        seconds (without it, until Ctrl-C or the task is cancelled, which halt it), then a velocity mode
        is sent velocity 0 and waited for at rest, the others are halted (until :meth:`reset`)."""

    @op(ModuleState, aio=True)
    def wait(self, module: Optional[int] = None, *, timeout_s: float = 60.0) -> ModuleState:
        """Waits until the module stands still; its state then. Ctrl-C halts it; cancelling the awaiting
        task halts it."""

    @op(PowerCubeSetpoint, aio=True)
    def setpoint(
        self, mode: str, value: float, module: Optional[int] = None, *, time_ms: Optional[int] = None
    ) -> PowerCubeSetpoint:
        """One motion command of a control loop (``mode`` and ``value`` as :meth:`motion` takes them;
        ``"fvel_ack"``: a velocity whose acknowledge says where the module stood, in ``ext_ack``), checked
        against the module's limits, read once and cached until this client writes one of them or the
        module resets, homes or halts. After the first call to a module each call is one exchange; the
        first also checks that the module takes motion and arms its watchdog (``watchdog=True``), which
        this client then refreshes until it closes. The motion goes on after the call: a velocity of 0
        (or :meth:`stop`) ends it; closing the client (the end of ``with``, Ctrl-C out of it) halts it."""

    @op(PowerCubeStop, aio=True)
    def stop(self, module: Optional[int] = None) -> PowerCubeStop:
        """Halts the module at once (it stays halted until :meth:`PowerCube.reset`), as ``motionlink
        powercube stop`` does: confirmed by its state read back until it is at rest; returns that state
        and where it stands (:class:`PowerCubeStop`), or raises if the module did not confirm it."""

    @op(ModuleInfo)
    def scan(self) -> List[ModuleInfo]:
        """Every module on the bus (an ``error`` field on a module that answered but could not be read); an
        empty list when none answers (``motionlink powercube scan`` calls that an error, exit 3).
        Ctrl-C raises ``KeyboardInterrupt`` at once (the scan sets nothing in motion; it ends on its own
        thread, and the session's next call waits for it on the line)."""

    @op(ModuleInfo)
    def info(self, module: Optional[int] = None) -> ModuleInfo:
        """Kind, firmware version, serial number, state, limits and position of a module."""

    @op(Parameter, args=lambda name, module: (str(name), module))
    def get(self, name: str, module: Optional[int] = None) -> Parameter:
        """Reads a parameter by name (``"ActPos"``) or id (``"60"``, ``"0x3c"``)."""

    @op(Parameter, args=lambda name, value, module: (str(name), value, module))
    def set(self, name: str, value: float, module: Optional[int] = None) -> Parameter:
        """Writes a parameter (a target beyond its limit is refused) and reads it back: ``read_back`` is the
        value read (``None`` with ``not_verifiable`` for a parameter that cannot be read)."""

    @op(bool)
    def reset(self, module: Optional[int] = None) -> bool:
        """Resets the module's error state, confirmed by the state read back (STATE_ERROR still set, as a
        servo amplifier fault leaves it, raises :class:`DeviceError`); True if it also switched off a
        watchdog that a dead host had left expired."""


class PowerCube(_Operations, ClientBase):
    """A session with PowerCube modules on one bus (RS232 or CAN).

    Args:
        port: ``"sim"`` (an emulated module in this process), ``"tcp://HOST:PORT"`` (a serial gateway or
            ``motionlink sim powercube --tcp``), a serial device (``"/dev/ttyUSB0"``, ``"COM3"``),
            ``"socketcan://can0"``, ``"slcan:///dev/ttyACM0"``, or a :class:`motionlink.Emulator`. Not given:
            the environment variable ``MOTIONLINK_PORT``; neither is a :class:`UsageError`.
        module: The module the operations address unless they name another (1..31).
        baud: Baud rate of an RS232 line.
        bitrate: CAN bit rate of an SLCAN adapter.
        timeout_ms: How long to wait for a reply (default: the library's, per bus).
        poll_ms: How often ``home``, ``move_to`` and ``wait`` read the module's state (1..10000).
        watchdog: Arm the module's watchdog while it moves (not for an emulator in this process, which
            dies with the program anyway), so that a host that dies (SIGKILL) halts the module.

    Leaving a ``with`` block, ``close()``, or the end of the program halts every module this session set in
    motion. Ctrl-C during ``home``, ``move_to`` or ``wait`` halts the module, then raises
    ``KeyboardInterrupt``.
    """

    def probe(
        self, *, save: Union[bool, str, Any] = False, exchanges: int = 20, low_latency: bool = False
    ) -> ProbeReport:
        """``motionlink probe powercube``'s report of the bus (see :func:`motionlink.probe`); nothing moves.
        ``save`` writes the profile of each module (``True``: profiles.toml beside devices.toml; a path:
        that file). ``profile=`` (``True`` by default) makes a later client take the profile of its
        ``module`` when the module gives the same version and serial number; the emulator's firmware
        variants (``motionlink sim powercube --variant``) show what each probe finds."""
        return ProbeReport(self._native.probe(exchanges, low_latency, save_setting(save)))

    def watch(
        self, module: Optional[int] = None, *, interval_ms: int = 200, count: Optional[int] = None
    ) -> Iterator[PowerCubeSample]:
        """Samples of state and position every ``interval_ms`` (fixed schedule), ``count`` times or until
        the loop ends."""
        m = self.module if module is None else module

        def read(t_s: float) -> PowerCubeSample:
            fields = dict(self._native.sample(m))
            fields["t_s"] = t_s
            return PowerCubeSample(fields)

        return samples(read, interval_ms, count)


class AsyncPowerCube(_Operations, AsyncClientBase):
    """The asyncio twin of :class:`PowerCube` (same arguments)::

        async with AsyncPowerCube("tcp://127.0.0.1:5000") as cube:
            await cube.move_to(0.5)

    Cancelling a task that awaits ``move_to``, ``home`` or ``wait`` halts the module; leaving the block
    (or ``aclose()``, or the end of the program) first cancels the operations still under way (their
    awaiters get :class:`motionlink.Cancelled`), then halts what the session set in motion.
    """

