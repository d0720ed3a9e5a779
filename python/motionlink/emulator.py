"""Emulators from Python, for your own tests: any family's device, in this process or served on a TCP
port (or a pseudo-terminal), with the events the emulated device reports."""

from __future__ import annotations

import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

from . import _native
from ._args import listed, mapping, texts

__all__ = ["Emulator", "Event"]


class Event(Tuple[float, str]):
    """One event of an emulated device: ``(at, text)``; ``at`` is a Unix time in seconds."""

    __slots__ = ()

    def __new__(cls, at: float, text: str) -> "Event":
        return super().__new__(cls, (at, text))

    @property
    def at(self) -> float:
        """When the emulated device did it (Unix time, s): for an emulator in this process, the instant of
        the device's step that produced it (as the client's line ran the device); for a served one, when
        its server reported it."""
        return self[0]

    @property
    def text(self) -> str:
        """What happened (``"module 1: motion started ..."``)."""
        return self[1]


class Emulator:
    """An emulated device of ``family`` (``"scu"``, ``"powercube"`` or ``"compax"``).

    With ``serve=None`` (the default) the device lives in this process: pass the emulator itself as the
    ``port`` of a client. With ``serve="tcp"`` it listens on ``bind`` (default ``127.0.0.1:0``, a free port)
    and :attr:`port` is the ``tcp://`` URL to give any client (another process too); ``serve="pty"`` gives a
    pseudo-terminal path.

    Settings per family (others raise :class:`UsageError`):
        scu: ``preset`` (``"scp11"``, ``"tlt"``, ``"liftkit"``), ``config`` (TOML text), ``variant`` (a
            firmware variant's name or a list of them, such as ``"no-groups"``: the unit does what the manual
            leaves open the other plausible way, as ``motionlink sim scu --variant``).
        powercube: ``modules`` (addresses), ``config`` (TOML text), ``strict`` (refuse bad BCCs),
            ``can`` (a CAN bus; served, it sits behind an emulated SLCAN adapter), ``variant`` (a firmware
            variant's name, or a list of them: ``"no-twin-mirror"``, ``"no-broadcast-pair"``,
            ``"ack-length-6"``, ``"ext-ack-on-put-id"``, ``"no-pos-state-dio"``,
            ``"life-sign-unacknowledged"``, ``"no-config-word"``, ``"reset-clears-watchdog"``,
            ``"no-extended-ack"``, ``"late-motion-start"``; as ``motionlink sim powercube --variant``).
        compax: ``drives`` (addresses), ``mode`` (P196), ``baud``, ``params`` ({"P3": 10.0}; P194..P196
            come from ``drives``, ``mode`` and ``baud``),
            ``config`` (TOML text), ``variant`` (a firmware variant's name, or a list of them:
            ``"echo-without-address"``, ``"echo-bare"``, ``"no-echo"``, ``"echo-without-store"``,
            ``"status-value-only"``, ``"no-position-message"``, ``"slow-replies"``, ``"buffer-queues"``,
            ``"no-command-bit"``, ``"echo-executes"``; as
            ``motionlink sim compax --variant``).

    Use it as a context manager (or call :meth:`close`).
    """

    def __init__(
        self,
        family: str,
        *,
        serve: Optional[str] = None,
        bind: Optional[str] = None,
        preset: Optional[str] = None,
        config: Optional[str] = None,
        modules: Optional[Sequence[int]] = None,
        drives: Optional[Sequence[int]] = None,
        mode: Optional[int] = None,
        baud: Optional[int] = None,
        params: Optional[Dict[str, float]] = None,
        strict: bool = False,
        can: bool = False,
        variant: Optional[Union[str, Sequence[str]]] = None,
    ) -> None:
        settings = {
            "preset": preset,
            "config": config,
            "modules": listed(modules, "modules") if modules is not None else None,
            "drives": listed(drives, "drives") if drives is not None else None,
            "mode": mode,
            "baud": baud,
            "params": mapping(params, "params") if params is not None else None,
            "strict": strict,
            "can": can,
            "serve": serve,
            "bind": bind,
            "variant": texts(variant, "variant") if variant is not None else None,
        }
        self._native = _native.NativeEmulator(family, settings)
        self._pending: List[Event] = []

    @property
    def family(self) -> str:
        """``"scu"``, ``"powercube"`` or ``"compax"``."""
        return str(self._native.family)

    @property
    def port(self) -> str:
        """The port URL a client connects to when served (``tcp://127.0.0.1:PORT``); ``""`` in process."""
        return str(self._native.port)

    @property
    def running(self) -> bool:
        """True until closed."""
        return bool(self._native.running)

    def take_events(self) -> List[Event]:
        """The events since the last call (or :meth:`wait_event`), oldest first."""
        new = [Event(at, text) for at, text in self._native.take_events()]
        pending, self._pending = self._pending, []
        return pending + new

    def wait_event(self, match: Callable[[str], bool], timeout_s: float = 5.0) -> Event:
        """Waits for an event whose text ``match`` accepts (looking at new events only) and returns it;
        events before it are dropped, events after it stay for the next call. Raises ``TimeoutError``
        (the builtin) naming the events seen if none came within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        seen: List[Event] = []
        while True:
            events = self.take_events()
            for i, e in enumerate(events):
                if match(e.text):
                    self._pending = events[i + 1 :]
                    return e
            seen.extend(events)
            if time.monotonic() > deadline:
                texts = "; ".join(e.text for e in seen) or "none"
                raise TimeoutError(f"no matching event within {timeout_s} s (events: {texts})")
            time.sleep(0.002)

    def close(self) -> None:
        """Stops the emulator. The clients still connected to an emulator in this process get
        :class:`motionlink.Disconnected` from their next call, as after a pulled cable (so close them
        first: a client's ``with`` block inside the emulator's does); a served emulator stops listening and
        drops its connection. Closing twice does nothing."""
        self._native.close()

    def __enter__(self) -> "Emulator":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        where = self.port or "in process"
        return f"<Emulator {self.family} {where}>"
