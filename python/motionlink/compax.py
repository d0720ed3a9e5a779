"""Parker COMPAX drives (RS485 / RS232, ASCII): :class:`Compax`.

Positions are in the drive's configured user unit (``position_units``, ``target_units`` ...); speeds in
percent of the drive's maximum (``speed_percent``), ramps in ms (``ramp_ms``).
"""

from __future__ import annotations

from typing import Any, Iterator, List, Optional, Sequence, Union

from . import _native
from ._args import items
from ._base import AsyncClientBase, ClientBase, check_interval
from ._ops import op
from ._probe import Profile, ProbeReport, profile_setting, save_setting
from .records import (
    CompaxHome,
    CompaxMove,
    CompaxOutput,
    CompaxSample,
    CompaxStop,
    DriveFound,
    DrivePosition,
    Parameter,
    StatusValue,
)

__all__ = ["Compax", "AsyncCompax"]

#: The in-position tolerance of a checked move unless told otherwise, in the drive's unit.
DEFAULT_TOLERANCE_UNITS: float = float(_native.COMPAX_DEFAULT_TOLERANCE_UNITS)


def _position(client: Any, units: float, drive: Optional[int]) -> DrivePosition:
    d = client.drive if drive is None else drive
    return DrivePosition({"family": "compax", "drive": d, "position_units": units})


def _param(name: Union[str, int]) -> str:
    return f"P{name}" if isinstance(name, int) and not isinstance(name, bool) else str(name)


class _Operations:
    """The operations of :class:`Compax` and (``aio``) :class:`AsyncCompax`, declared once."""

    family = "compax"
    _native_name = "CompaxClient"
    _start: Any
    #: The drive the operations address unless they name another (1..31): the constructor's ``drive``.
    drive: int

    def __init__(
        self,
        port: Optional[Union[str, Any]] = None,
        drive: int = 1,
        *,
        mode: int = 0,
        baud: int = 9600,
        timeout_ms: int = 200,
        poll_ms: int = 50,
        tolerance_units: float = DEFAULT_TOLERANCE_UNITS,
        profile: Profile = True,
    ) -> None:
        self.drive = drive
        settings = dict(drive=drive, mode=mode, baud=baud, timeout_ms=timeout_ms, poll_ms=poll_ms)
        self._start(port, dict(settings, tolerance_units=tolerance_units, profile=profile_setting(profile)))

    @op(DriveFound)
    def scan(self) -> List[DriveFound]:
        """Every drive that answers (addresses 1..31), with its position S1; an empty list when none
        answers (``motionlink compax scan`` calls that an error, exit 3). Ctrl-C raises
        ``KeyboardInterrupt`` at once; the library's scan ends before the next address."""

    @op(StatusValue, args=lambda names, drive: (items(names, "names", "compax"), drive))
    def status(
        self, names: Union[str, int, Sequence[Union[str, int]]] = (), drive: Optional[int] = None
    ) -> List[StatusValue]:
        """Status values by name (``"S1"``) or number: one (a str or an int), or a list of them; none (or
        an empty list): the main ones, as ``motionlink compax status`` and :meth:`Compax.info` read them."""

    @op(_position, aio=True, with_args=True)
    def position(self, drive: Optional[int] = None) -> DrivePosition:
        """The actual position S1: ``position_units``, in the drive's unit."""

    @op(Parameter, args=lambda name, drive: (_param(name), drive))
    def get(self, name: Union[str, int], drive: Optional[int] = None) -> Parameter:
        """Reads a parameter (``"P194"``, ``194``, ``"device_address"``)."""

    @op(Parameter, args=lambda name, value, drive: (_param(name), value, drive))
    def set(self, name: Union[str, int], value: float, drive: Optional[int] = None) -> Parameter:
        """Writes a parameter; the library reads it back and compares (a difference is a
        :class:`DeviceError`). ``read_back`` is the value then read from the drive, ``verified`` True and
        ``not_verifiable`` empty."""

    @op(CompaxMove, aio=True, args=lambda t, drive, distance, *rest: (t, distance, drive, *rest))
    def move_to(
        self,
        target: Optional[float] = None,
        drive: Optional[int] = None,
        *,
        distance: Optional[float] = None,
        speed_percent: Optional[float] = None,
        ramp_ms: Optional[int] = None,
        min_units: Optional[float] = None,
        max_units: Optional[float] = None,
        timeout_s: float = 600.0,
    ) -> CompaxMove:
        """A checked move to ``target`` (POSA) or by ``distance`` (POSR, never repeated blind), waited for;
        returns only if the drive came to rest within the tolerance (else :class:`DeviceError`). A target
        outside ``min_units``/``max_units`` is refused before anything is sent. Ctrl-C (or cancelling the
        awaiting task) stops the drive."""

    move = move_to

    @op(CompaxHome, aio=True)
    def home(self, drive: Optional[int] = None, *, timeout_s: float = 600.0) -> CompaxHome:
        """POSA HOME (find machine zero), waited for, then checked: S16 must show machine zero approached
        and the drive switched on, else :class:`DeviceError` (a homing stopped halfway, by another
        program's stop say, ends at rest too). Ctrl-C (or cancelling the awaiting task) stops the drive."""

    @op(DrivePosition, aio=True)
    def wait(self, drive: Optional[int] = None, *, timeout_s: float = 600.0) -> DrivePosition:
        """Waits until the drive's positioning ended (S17); its position S1 then. Ctrl-C (or cancelling
        the awaiting task) stops the drive."""

    @op(CompaxStop, aio=True)
    def stop(self, drive: Optional[int] = None) -> CompaxStop:
        """Stops the drive as ``motionlink compax stop`` does: if S17 shows it moving (or cannot be read),
        OUTPUT O0=0, the only stop there is, which switches it off (``output(0, 1)`` switches it on again);
        a drive at rest is left as it is. Returns the stop, confirmed by S17, and S1 and O0 read after it
        (:class:`CompaxStop`); raises if the drive did not confirm it."""

    @op(CompaxOutput)
    def output(self, number: int, state: int, drive: Optional[int] = None) -> CompaxOutput:
        """Sets output ``number`` to ``state`` (OUTPUT Ox=y), as ``motionlink compax output`` does: O0 (the
        drive switched on or off) is read back from S16 (another state raises :class:`DeviceError`); another
        output is not read back, and the record says so (``verified`` False)."""


class Compax(_Operations, ClientBase):
    """A session with COMPAX drives on one RS485 bus (or one drive on RS232).

    Args:
        port: A serial device (``"/dev/ttyUSB0"``, ``"COM3"``), ``"tcp://HOST:PORT"``, ``"sim"`` (an emulated
            bus in this process), or a :class:`motionlink.Emulator`. Not given: the environment variable
            ``MOTIONLINK_PORT``; neither is a :class:`UsageError`.
        drive: The drive the operations address unless they name another (1..31).
        mode: The drives' operating mode P196 (sum of valences; 0: no checksum, no echo).
        baud: The bus's baud rate (P195).
        timeout_ms: How long to wait for a reply.
        poll_ms: How often a move or wait reads S17.
        tolerance_units: How close to its target a checked move must end.

    Leaving a ``with`` block, ``close()`` or the end of the program stops every drive this session set in
    motion that still moves (OUTPUT O0=0, confirmed by S17). Ctrl-C during ``move_to``, ``home`` or
    ``wait`` stops the drive, then raises ``KeyboardInterrupt``.
    """

    def probe(
        self,
        *,
        save: Union[bool, str, Any] = False,
        exchanges: int = 20,
        low_latency: bool = False,
        drives: str = "1-31",
    ) -> ProbeReport:
        """``motionlink probe compax``'s report of the drives at ``drives`` (``"1-31"``, ``"1,3"``; see
        :func:`motionlink.probe`); nothing moves. ``save`` writes the profile of each drive (``True``:
        profiles.toml beside devices.toml; a path: that file). ``profile=`` (``True`` by default) makes a
        later client take the profile of its ``drive`` (its echo form) when the drive gives the same S31 and
        S32; the emulator's firmware variants (``motionlink sim compax --variant``) show what each probe
        finds."""
        return ProbeReport(self._native.probe(exchanges, low_latency, save_setting(save), drives))

    def info(self, drive: Optional[int] = None) -> List[StatusValue]:
        """The drive's main status values: S1 position, S2 target, S3 following error, S16/S17 status
        bits, S18 error history."""
        return self.status([], drive)

    def watch(
        self, drive: Optional[int] = None, *, interval_ms: int = 200, count: Optional[int] = None
    ) -> Iterator[CompaxSample]:
        """The library's watch: S1 and S17 every ``interval_ms`` on the drive's schedule, ``count`` times
        or until the loop ends (leaving it, or closing the client, ends the watch). Ctrl-C ends it and
        raises ``KeyboardInterrupt``."""
        check_interval(interval_ms, count)
        native = self._native.watch_start(drive, interval_ms)

        def run() -> Iterator[CompaxSample]:
            try:
                n = 0
                while count is None or n < count:
                    yield CompaxSample(native.next())
                    n += 1
            finally:
                native.close()

        return run()


class AsyncCompax(_Operations, AsyncClientBase):
    """The asyncio twin of :class:`Compax` (same arguments)::

        async with AsyncCompax("tcp://127.0.0.1:5000") as drive:
            await drive.move_to(100.0)

    Cancelling a task that awaits ``move_to``, ``home`` or ``wait`` stops the drive (OUTPUT O0=0,
    confirmed by S17); leaving the block (or ``aclose()``, or the end of the program) first cancels the
    operations still under way (their awaiters get :class:`motionlink.Cancelled`), then stops what the
    session set in motion.
    """
