"""One declaration per operation. A family's operations are methods of one base class, each declared once
with :class:`op` on a method whose signature is the public one and whose body is its docstring; the
declaration gives the blocking client (``PowerCube``) its method, calling the native client's method of
the same name, and the asyncio client (``AsyncPowerCube``) its coroutine (``aio=True``), calling the
native async client's method with a ``done`` callback. The native methods take the arguments in the
order of the declared signature. The stubs (``.pyi``) are generated from the same declarations
(``python/tools/stubs.py``)."""

from __future__ import annotations

import functools
import inspect
from typing import Any, Callable, Optional

__all__ = ["op", "is_async"]


def is_async(client: Any) -> bool:
    """True for an asyncio client (it awaits its native operations)."""
    return hasattr(client, "_run")


class op:
    """Declares an operation: ``@op(Record)`` turns the native result into ``Record(result)`` (each element
    of a list; ``None`` stays ``None``), or with ``with_args`` into ``result(client, result, *arguments)``;
    ``aio=True`` gives the asyncio client the operation too; ``args`` maps the arguments (in the
    signature's order) to the native call's."""

    def __init__(
        self,
        result: Optional[Callable[[Any], Any]] = None,
        *,
        aio: bool = False,
        args: Optional[Callable[..., tuple]] = None,
        with_args: bool = False,
    ) -> None:
        self.result = result
        self.aio = aio
        self.args = args
        self.with_args = with_args

    def __call__(self, declared: Callable[..., Any]) -> "op":
        self.declared = declared
        self.name = declared.__name__
        self.signature = inspect.signature(declared)
        self.__doc__ = declared.__doc__
        functools.update_wrapper(self, declared)
        name, result, convert, signature = self.name, self.result, self.args, self.signature
        with_args = self.with_args

        params = list(signature.parameters.values())[1:]
        positional = [p for p in params if p.kind is p.POSITIONAL_OR_KEYWORD]
        # The arguments past those given positionally, when all of them have defaults (a position read's
        # common case: no binding on the hot path).
        rest = [
            [p.default for p in params[n:]] if all(p.default is not p.empty for p in params[n:]) else None
            for n in range(len(positional) + 1)
        ]

        def native_args(client: Any, args: Any, kwargs: Any) -> list:
            if not kwargs and len(args) < len(rest) and rest[len(args)] is not None and not convert:
                return [*args, *rest[len(args)]]  # type: ignore[misc]
            bound = signature.bind(client, *args, **kwargs)
            bound.apply_defaults()
            values = list(bound.arguments.values())[1:]
            return list(convert(*values)) if convert else values

        def shape(client: Any, raw: Any, values: list) -> Any:
            if result is None or raw is None:
                return raw
            if with_args:
                return result(client, raw, *values)
            if isinstance(raw, list):
                return [result(r) for r in raw]
            return result(raw)

        @functools.wraps(declared)
        def blocking(client: Any, *args: Any, **kwargs: Any) -> Any:
            values = native_args(client, args, kwargs)
            return shape(client, getattr(client._native, name)(*values), values)

        @functools.wraps(declared)
        async def coroutine(client: Any, *args: Any, **kwargs: Any) -> Any:
            values = native_args(client, args, kwargs)
            raw = await client._run(lambda done: getattr(client._client(), name)(*values, done))
            return shape(client, raw, values)

        for made in (blocking, coroutine):
            # Frames and tracebacks inside the call name the operation (``move_to``), not this wrapper.
            code = made.__code__.replace(co_name=name)
            if hasattr(code, "co_qualname"):
                code = code.replace(co_qualname=declared.__qualname__)
            made.__code__ = code
        self.blocking, self.coroutine = blocking, coroutine
        return self

    def __get__(self, client: Any, owner: Any = None) -> Any:
        # On the class, the face of that class: a function, or a coroutine function (as a `def` or an
        # `async def` in the class would be).
        face = is_async(client if client is not None else owner)
        if face and not self.aio:
            who = type(client).__name__ if client is not None else owner.__name__
            raise AttributeError(f"{who} has no {self.name}() (the blocking client has)")
        made = self.coroutine if face else self.blocking
        return made if client is None else made.__get__(client, owner)
