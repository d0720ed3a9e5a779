"""The exceptions of motionlink: one hierarchy, one class per kind of failure.

Every exception raised by a client is a :class:`MotionlinkError`; its class says what kind of failure it
is, the same classification the command line maps to its exit codes::

    MotionlinkError
    ├── DeviceRefused        the device answered and refused the request        (exit code 1)
    ├── DeviceError          the device reports an error (code and named bits),
    │                        or a motion did not end where it was asked to      (exit code 1)
    ├── TransportError       the link failed (port, I/O)                         (exit code 3)
    │   ├── TimeoutError     no (complete) answer in time
    │   ├── Disconnected     the port went away or the peer closed it
    │   └── CorruptFrame     bytes that are not a valid answer
    ├── UsageError           a bad argument, found before anything was sent    (exit code 2)
    │                        (also a ValueError)
    └── Cancelled            the operation was cancelled (another thread's Ctrl-C, a closed client);
                             what it had set in motion was stopped

Ctrl-C during a long call (a move, homing, a wait) raises ``KeyboardInterrupt`` itself, after the motion
was stopped; its ``__cause__`` is the :class:`Cancelled` error that says whether the device confirmed
the stop.
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional

__all__ = [
    "MotionlinkError",
    "DeviceRefused",
    "DeviceError",
    "TransportError",
    "TimeoutError",
    "Disconnected",
    "CorruptFrame",
    "UsageError",
    "Cancelled",
]

_EXIT_CODES = {
    "refused": 1,
    "device": 1,
    "timeout": 3,
    "disconnected": 3,
    "corrupt": 3,
    "io": 3,
    "usage": 2,
    "cancelled": 130,
}


class MotionlinkError(Exception):
    """Any failure of a motionlink client.

    Attributes:
        kind: The class of the failure, as the command line's JSON names it: ``"refused"``, ``"device"``,
            ``"timeout"``, ``"disconnected"``, ``"corrupt"``, ``"io"``, ``"usage"`` or ``"cancelled"``.
        message: What happened, in words (also ``str(error)``).
        exit_code: The exit code the command line gives this failure (1, 2, 3, or 130).
        family: ``"scu"``, ``"powercube"``, ``"compax"``, or ``""`` when no family is involved.
        code: The device's error code or state word, when it reported one (SCU: Error_Code; PowerCube:
            CubeState; COMPAX: the number of its ``Exx`` answer), else ``None``.
        bits: The named bits set in ``code``: a list of dicts ``{"bit": int, "name": str, "cause": str}``.
        stop_unconfirmed: True when the failure says that a stop was not confirmed by the device: what
            the client had set in motion may still be moving (the message says what stops it then).
            Such an error is a :class:`TransportError`.
    """

    kind: str
    message: str
    exit_code: int
    family: str
    code: Optional[int]
    bits: List[Dict[str, Any]]
    stop_unconfirmed: bool

    _default_kind = "io"

    def __init__(
        self,
        message: str,
        *,
        kind: Optional[str] = None,
        exit_code: Optional[int] = None,
        family: str = "",
        code: Optional[int] = None,
        bits: Optional[List[Dict[str, Any]]] = None,
        stop_unconfirmed: bool = False,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.kind = kind or self._default_kind
        self.exit_code = exit_code if exit_code is not None else _EXIT_CODES.get(self.kind, 1)
        self.family = family
        self.code = code
        self.bits = list(bits or [])
        self.stop_unconfirmed = stop_unconfirmed

    def __str__(self) -> str:
        return self.message

    def to_dict(self) -> Dict[str, Any]:
        """The error as the command line's ``--json`` prints it (``kind``, ``message``, ``exit_code``,
        ``stop_unconfirmed`` when true, and ``code`` and ``bits`` where the device reported them)."""
        d: Dict[str, Any] = {"kind": self.kind, "message": self.message, "exit_code": self.exit_code}
        if self.stop_unconfirmed:
            d["stop_unconfirmed"] = True
        if self.code is not None:
            d["code"] = self.code
            d["bits"] = list(self.bits)
        return d


class DeviceRefused(MotionlinkError):
    """The device answered and refused the request (a bad checksum it saw, a command not allowed in its
    state, data out of its range)."""

    _default_kind = "refused"


class DeviceError(MotionlinkError):
    """The device reports an error (``code`` and its named ``bits``), or a motion did not end where it was
    asked to (the message names target, reached position and difference)."""

    _default_kind = "device"


class TransportError(MotionlinkError):
    """The link failed: the port could not be opened, or another I/O failure. The subclasses say how."""

    _default_kind = "io"


class TimeoutError(TransportError):  # noqa: A001 - the issue's name; it shadows the builtin only here
    """No (complete) answer within the time the protocol allows."""

    _default_kind = "timeout"


class Disconnected(TransportError):
    """The port went away or the peer closed the connection; it cannot be used until reopened."""

    _default_kind = "disconnected"


class CorruptFrame(TransportError):
    """Bytes arrived that are not a valid answer (checksum, framing, length, an answer to something else)."""

    _default_kind = "corrupt"


class UsageError(MotionlinkError, ValueError):
    """The caller asked for something invalid (a bad argument, a value out of range, a closed client);
    found before anything was sent. Also a ``ValueError``."""

    _default_kind = "usage"


class Cancelled(MotionlinkError):
    """The operation was cancelled (Ctrl-C seen by another call of the same client, or the client closed
    under it); what it had set in motion was stopped, and the message says whether the device confirmed
    that."""

    _default_kind = "cancelled"
