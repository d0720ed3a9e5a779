"""What every client shares: the context manager that stops what the client started, and the safety net
that closes clients still open when the interpreter exits."""

from __future__ import annotations

import asyncio
import atexit
import os
import time
import weakref
from typing import Any, Callable, Dict, Iterator, List, Optional, TypeVar

from . import _native
from ._probe import warn_profile_notices
from .errors import Cancelled, MotionlinkError, UsageError

__all__ = ["ClientBase", "AsyncClientBase", "resolve_port"]

_open: "weakref.WeakSet[Any]" = weakref.WeakSet()

PORT_ENV = "MOTIONLINK_PORT"
"""The environment variable that gives the port when a client is given none (as for the command line)."""


def resolve_port(port: Any, family: str) -> Any:
    """The port a client of ``family`` opens: ``port`` (a port URL, or a :class:`motionlink.Emulator`)
    when given, else the environment variable ``MOTIONLINK_PORT``; neither is a :class:`UsageError`. Never
    an emulator by default: ``"sim"`` is opened only when asked for."""
    if port is None:
        port = os.environ.get(PORT_ENV, "").strip()
        if not port:
            raise UsageError(
                'no port: give port=PORT (such as "/dev/ttyUSB0", "tcp://HOST:PORT" or "sim"), '
                f"or set {PORT_ENV}",
                family=family,
            )
    return getattr(port, "_native", port)


@atexit.register
def _close_all_at_exit() -> None:
    """A program that ends (normally, or by an exception nobody caught) without closing a client still
    stops what the client started: each client still open is closed here. Then the library's delivery
    thread stops calling into Python (it is no Python thread, and must not be inside a callback when the
    interpreter finalises)."""
    try:
        for client in list(_open):
            try:
                client._close_at_exit()
            except Exception:  # noqa: BLE001 - nothing can be reported at this point but by the close itself
                pass
    finally:
        _native.stop_deliveries()


class ClientBase:
    """A session with a device. Use it as a context manager: leaving the ``with`` block, normally or by an
    exception (``KeyboardInterrupt`` included), closes it, which stops any motion it started and reports
    (raises) if the device did not confirm that. ``close()`` does the same."""

    family: str = ""
    _native: Any
    #: The name of the family's native client in :mod:`motionlink._native` (``Async`` before it: the
    #: asyncio client's).
    _native_name: str = ""

    def _start(self, port: Any, settings: Dict[str, Any]) -> None:
        """Opens the session on ``port`` (see :func:`resolve_port`) with the family's ``settings``."""
        self._native = getattr(_native, self._native_name)(resolve_port(port, self.family), settings)
        _open.add(self)
        warn_profile_notices(self._native)

    @property
    def port(self) -> str:
        """The port, as the link describes it."""
        return str(self._native.port)

    @property
    def is_open(self) -> bool:
        """True until the client is closed."""
        return bool(self._native.is_open)

    @property
    def profile(self) -> Optional[str]:
        """The device profile the session took (``"<path>#<key>"``, as ``--json`` results name it), or None:
        none is kept for this port, its identity differs (a warning said so), or ``profile=False``."""
        return self._native.profile  # type: ignore[no-any-return]

    def started(self) -> List[int]:
        """The ids of what this session set in motion and has not seen stop: SCU motion function numbers
        (1..10), PowerCube module addresses, COMPAX drive addresses."""
        return list(self._native.started())

    def close(self) -> List[int]:
        """Ends the session: stops what it set in motion and still moves, then leaves the device as the
        family's library leaves it (see docs/safety.md). Returns the ids of what it stopped, as
        :meth:`started` names them (SCU motion function numbers, PowerCube modules, COMPAX drives; while
        another thread's call still holds the session, that call is cancelled and these are the ones
        being stopped). Raises if the stop could not be confirmed. Closing twice does nothing (and
        returns ``[]``)."""
        _open.discard(self)
        return list(self._native.close())

    def _close_at_exit(self) -> None:
        self.close()

    def __enter__(self: "_C") -> "_C":
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        try:
            self.close()
        except MotionlinkError as closing:
            if not _kept_with_a_note(exc, closing):
                raise

    def __repr__(self) -> str:
        state = "open" if self.is_open else "closed"
        return f"<{type(self).__name__} {self.port!r} {state}>"


_C = TypeVar("_C", bound=ClientBase)


def _kept_with_a_note(error: Any, closing: MotionlinkError) -> bool:
    """True, and the note added, when the block ended with ``error``, which said already that a stop was
    not confirmed (the axis may still be moving), and the close failed too (it tried the stop again, or
    left a watchdog online): the block's error goes on, with the close's as a note (``add_note``, Python
    3.11+; ``__notes__`` before), instead of a second exception that would hide it. After any other error
    the close's failure is raised (chained to it): it is then the news about what may still move."""
    if not (isinstance(error, MotionlinkError) and error.stop_unconfirmed):
        return False
    note = f"then the end of the session: {closing}"
    if hasattr(error, "add_note"):
        error.add_note(note)
    else:
        error.__notes__ = [*getattr(error, "__notes__", []), note]
    return True


def check_interval(interval_ms: int, count: Optional[int]) -> None:
    if isinstance(interval_ms, bool) or not isinstance(interval_ms, int) or not 1 <= interval_ms <= 3_600_000:
        raise UsageError(f"interval_ms {interval_ms!r}: give a whole number of ms, 1 to 3600000")
    if count is not None and (isinstance(count, bool) or not isinstance(count, int) or count < 1):
        raise UsageError(f"count {count!r}: give a whole number of samples, at least 1 (or None)")


_T = TypeVar("_T")


def samples(read: Callable[[float], _T], interval_ms: int, count: Optional[int]) -> Iterator[_T]:
    """Calls ``read(t_s)`` every ``interval_ms`` on a fixed schedule (absolute deadlines), ``count`` times
    or until the caller stops iterating; ``time.sleep`` between samples, so Ctrl-C ends it at once."""
    check_interval(interval_ms, count)
    start = time.monotonic()
    due = start
    n = 0
    while count is None or n < count:
        yield read(time.monotonic() - start)
        n += 1
        if count is not None and n >= count:
            return
        due += interval_ms / 1000.0
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)


Calls = Dict[Any, "asyncio.Future[Any]"]
"""The native operations of one async client under way: each one's task and the future its caller awaits."""


async def run_native(start: Callable[[Callable[[bool, Any], None]], Any], calls: Optional[Calls] = None) -> Any:
    """Awaits a native operation: ``start(done)`` starts it on the library's runtime thread and returns
    its task; ``done(ok, value)`` is called there with the outcome. Cancelling the awaiting asyncio task
    cancels the operation (its future is dropped, which stops what it set in motion) and waits, on a
    worker thread, until that is done before ``CancelledError`` propagates. While it runs, the operation
    is in ``calls`` (its client's), so that closing the client can cancel it."""
    loop = asyncio.get_running_loop()
    fut: "asyncio.Future[Any]" = loop.create_future()

    def settle(ok: bool, value: Any) -> None:
        if fut.done():
            return
        if ok:
            fut.set_result(value)
        else:
            fut.set_exception(value)

    def done(ok: bool, value: Any) -> None:
        try:
            loop.call_soon_threadsafe(settle, ok, value)
        except RuntimeError:  # the loop is closed: nobody waits any more
            pass

    task = start(done)
    if calls is not None:
        calls[task] = fut
    try:
        return await fut
    except asyncio.CancelledError:
        await loop.run_in_executor(None, task.cancel)
        raise
    finally:
        if calls is not None:
            calls.pop(task, None)


def _blocking_only(cls: type) -> "set[str]":
    """The operations ``cls`` declares (:class:`motionlink._ops.op`) for the blocking client only."""
    from ._ops import op

    return {
        name
        for klass in cls.__mro__
        for name, member in vars(klass).items()
        if isinstance(member, op) and not member.aio
    }


class _AsyncFace(type):
    """The class of the asyncio clients: ``dir()`` of one leaves out the operations only the blocking client
    has (asking an asyncio client for one raises ``AttributeError``)."""

    def __dir__(cls) -> List[str]:
        return sorted(set(super().__dir__()) - _blocking_only(cls))


class AsyncClientBase(metaclass=_AsyncFace):
    """An async session with a device: ``async with`` opens it and closes it (stopping what it started);
    cancelling a task that awaits a long operation (a move, homing, a wait) stops that motion. Closing
    the client cancels the operations still under way on it first (their motions stop; whoever awaits
    them gets :class:`Cancelled`), then ends the session."""

    family: str = ""
    _native: Any = None
    _native_name: str = ""

    def _start(self, port: Any, settings: Dict[str, Any]) -> None:
        """Keeps ``port`` and ``settings`` for the opening (``async with`` or :meth:`open`)."""
        self._port = resolve_port(port, self.family)
        self._settings = settings
        self._native = None
        self._calls: Calls = {}

    def __dir__(self) -> List[str]:
        return sorted(set(super().__dir__()) - _blocking_only(type(self)))

    def _client(self) -> Any:
        if self._native is None:
            raise UsageError(f"{type(self).__name__} is not open: use `async with` or `await open()`")
        return self._native

    async def _run(self, start: Callable[[Callable[[bool, Any], None]], Any]) -> Any:
        """Awaits an operation of this session (see :func:`run_native`)."""
        return await run_native(start, self._calls)

    @property
    def port(self) -> str:
        """The port, as the link describes it."""
        return str(self._client().port)

    @property
    def profile(self) -> Optional[str]:
        """The device profile the session took (``"<path>#<key>"``, as ``--json`` results name it), or None
        (see :attr:`ClientBase.profile`)."""
        return self._client().profile  # type: ignore[no-any-return]

    def started(self) -> List[int]:
        """The ids of what this session set in motion and has not seen stop (see
        :meth:`ClientBase.started`)."""
        return list(self._client().started())

    async def open(self: "_A") -> "_A":
        """Opens the session (what ``async with`` does)."""
        return await self.__aenter__()

    async def __aenter__(self: "_A") -> "_A":
        if self._native is None:
            native = getattr(_native, "Async" + self._native_name)
            self._native = await run_native(lambda done: native.open(self._port, self._settings, done))
            _open.add(self)
            warn_profile_notices(self._native)
        return self

    async def __aexit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        try:
            await self.aclose()
        except MotionlinkError as closing:
            if not _kept_with_a_note(exc, closing):
                raise

    async def aclose(self) -> List[int]:
        """Ends the session: cancels the operations still under way on it (which stops their motions),
        then stops what it set in motion and still moves. Returns the ids of what it stopped (as
        :meth:`ClientBase.close` does). Raises if the stop could not be confirmed. Closing twice does
        nothing (and returns ``[]``)."""
        native = self._native
        if native is None:
            return []
        _open.discard(self)
        # What is in motion now: the cancelled calls stop theirs, the close the rest.
        stopped = list(native.started()) if native.is_open else []
        loop = asyncio.get_running_loop()
        for task, fut in list(self._calls.items()):
            await loop.run_in_executor(None, task.cancel)
            if not fut.done():
                fut.set_exception(self._closed_under_it())
        ended = await run_native(native.close)
        return stopped + [i for i in ended if i not in stopped]

    def _closed_under_it(self) -> Cancelled:
        return Cancelled(
            f"{self.family}: the client was closed while this operation was under way: the operation was "
            "cancelled, which stops what it set in motion, and the session closed",
            family=self.family,
        )

    def _close_at_exit(self) -> None:
        if self._native is not None:
            for task in list(self._calls):
                task.cancel()
            self._native.close_blocking()


_A = TypeVar("_A", bound=AsyncClientBase)
