"""What every client shares: the context manager that stops what the client started, and the safety net
that closes clients still open when the interpreter exits."""

from __future__ import annotations

import asyncio
import atexit
import os
import sys
import threading
import time
import weakref
from typing import Any, Callable, Dict, Iterator, List, Optional, Set, TypeVar

from . import _native
from ._probe import warn_profile_notices
from .errors import Cancelled, MotionlinkError, UsageError

__all__ = ["ClientBase", "AsyncClientBase", "resolve_port"]

_open: "weakref.WeakSet[Any]" = weakref.WeakSet()
"""The blocking clients still open (one that Python collects closes itself)."""
_open_async: "Set[Any]" = set()
"""The asyncio clients whose session has not finished closing, held here until it has: nothing else would
wait for the close of one the program dropped, and an ``aclose()`` cut short is done again at exit."""

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


def _close_all() -> None:
    """A program that ends (normally, or by an exception nobody caught, Ctrl-C's included) without closing a
    client still stops what the client started: each client still open is closed here, at exit, and
    before Python waits for the threads that are not daemons when the main thread ended by an exception
    (:func:`_close_all_if_main_failed`)."""
    for client in [*_open, *_open_async]:
        try:
            client._close_at_exit()
        except Exception:  # noqa: BLE001 - nothing can be reported at this point but by the close itself
            pass


def _close_all_if_main_failed() -> None:
    """When the main thread ended by an exception nobody caught (Ctrl-C's KeyboardInterrupt included: Python
    then records it as ``sys.last_value``), the clients are closed before Python waits for the threads that
    are not daemons, whose calls the closes cancel (else a move in such a thread ran to its end after
    Ctrl-C). A main thread that returned leaves those threads their motions: Python waits for them, and the
    exit closes what is left."""
    if getattr(sys, "last_exc", None) is not None or getattr(sys, "last_value", None) is not None:
        _close_all()


if hasattr(threading, "_register_atexit"):  # CPython 3.9 on; without it, at exit only
    threading._register_atexit(_close_all_if_main_failed)


@atexit.register
def _close_all_at_exit() -> None:
    """:func:`_close_all`; then the library's delivery thread stops calling into Python (it is no Python
    thread, and must not be inside a callback when the interpreter finalises)."""
    try:
        _close_all()
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
    cancels the operation, which stops what it set in motion, and waits on a worker thread until that stop
    has ended (through further cancellations): then ``CancelledError`` propagates, or, if the device did
    not confirm the stop, the library's error that says so (``stop_unconfirmed``), raised from the
    ``CancelledError``. While it runs, the operation is in ``calls`` (its client's), so that closing the
    client can cancel it."""
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
    except asyncio.CancelledError as cancelled:
        stopping = loop.run_in_executor(None, task.cancel)
        await _to_the_end(stopping)
        if _unconfirmed(stopping.result()):
            raise stopping.result() from cancelled
        raise
    finally:
        if calls is not None:
            calls.pop(task, None)


async def _to_the_end(work: "asyncio.Future[Any]") -> Optional[asyncio.CancelledError]:
    """Awaits ``work`` (a stop, a close: on a worker thread) to its end, even when the awaiting task is
    cancelled meanwhile: returns that cancellation (for the caller to raise), if there was one."""
    cancelled = None
    while not work.done():
        try:
            await asyncio.wait((work,))
        except asyncio.CancelledError as e:
            cancelled = e
    return cancelled


def _unconfirmed(stop: Any) -> bool:
    """True when ``stop`` (what a cancelled native operation's stop ended with) is the library's error
    saying that the device did not confirm the stop."""
    return isinstance(stop, MotionlinkError) and stop.stop_unconfirmed


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
    the client refuses new calls, cancels the operations still under way on it (their motions stop;
    whoever awaits them gets :class:`Cancelled`), then ends the session."""

    family: str = ""
    _native: Any = None
    _native_name: str = ""
    #: True from the start of the close on: a call is refused.
    _closing = False

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
        """Awaits an operation of this session (see :func:`run_native`); none starts once it closes."""
        if self._closing:
            raise UsageError("the client is closed", family=self.family)
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
            _open_async.add(self)
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
        :meth:`ClientBase.close` does). Raises if the stop could not be confirmed. Closing twice (or while
        it closes) does nothing (and returns ``[]``). Cancelled meanwhile, it still cancels and closes to
        the end, then raises ``CancelledError``."""
        native = self._native
        if native is None or self._closing:
            return []
        self._closing = True
        # What is in motion now: the cancelled calls stop theirs, the close the rest.
        stopped = list(native.started()) if native.is_open else []
        loop = asyncio.get_running_loop()
        cancelled = None
        while self._calls:
            task, fut = self._calls.popitem()
            stopping = loop.run_in_executor(None, task.cancel)
            cancelled = await _to_the_end(stopping) or cancelled
            self._settle(fut, stopping.result())
        closing = loop.run_in_executor(None, native.close_blocking)
        cancelled = await _to_the_end(closing) or cancelled
        _open_async.discard(self)
        if cancelled is not None:
            raise cancelled
        return stopped + [i for i in closing.result() if i not in stopped]

    def _settle(self, fut: "asyncio.Future[Any]", stop: Any) -> None:
        """Tells the awaiter of a call the close cancelled how it ended (on its loop, which may be another
        thread's): the error of its stop if that was not confirmed, else :class:`Cancelled`."""
        error = stop if _unconfirmed(stop) else Cancelled(
            f"{self.family}: the client was closed while this operation was under way: the operation was "
            "cancelled, which stops what it set in motion, and the session closed",
            family=self.family,
        )

        def settle() -> None:
            if not fut.done():
                fut.set_exception(error)

        try:
            fut.get_loop().call_soon_threadsafe(settle)
        except RuntimeError:  # its loop is closed: nobody awaits it any more
            pass

    def _close_at_exit(self) -> None:
        """The close at exit (the loop no longer runs here, if it runs at all)."""
        if self._native is not None:
            self._closing = True
            while self._calls:
                task, fut = self._calls.popitem()
                self._settle(fut, task.cancel())
            self._native.close_blocking()
        _open_async.discard(self)


_A = TypeVar("_A", bound=AsyncClientBase)
