"""The base of :mod:`motionlink.records`: the read-only :class:`Record` and the records every family
shares (error codes, flag words, parameters)."""

from __future__ import annotations

from typing import Any, ClassVar, Dict, List, Mapping, get_args, get_origin, get_type_hints

__all__ = ["Record", "ErrorBit", "ErrorCode", "FlagWord", "Parameter"]


_NO_EXTRAS: frozenset = frozenset()


class _Slots(type):
    """Gives each record class empty ``__slots__`` unless it declares its own (a record's fields live in
    ``_fields``)."""

    def __new__(mcs, name: str, bases: Any, namespace: Dict[str, Any], **kwargs: Any) -> Any:
        namespace.setdefault("__slots__", ())
        return super().__new__(mcs, name, bases, namespace, **kwargs)


class Record(metaclass=_Slots):
    """A read-only result with named fields (see the module documentation)."""

    __slots__ = ("_fields", "_extras")
    #: Fields whose values are records (or lists of records) of these types besides those the annotations
    #: say (a field annotated ``FlagWord`` or ``List[ErrorBit]`` is one of them already).
    _nested: ClassVar[Mapping[str, type]] = {}

    @classmethod
    def _nested_fields(cls) -> Mapping[str, type]:
        """The fields whose values are records, from the annotations (resolved once per class)."""
        found = cls.__dict__.get("_nested_resolved")
        if found is None:
            found = dict(cls._nested)
            for name, hint in get_type_hints(cls).items():
                inner = get_args(hint)[0] if get_origin(hint) is list else hint
                if isinstance(inner, type) and issubclass(inner, Record):
                    found[name] = inner
            type.__setattr__(cls, "_nested_resolved", found)
        return found  # type: ignore[no-any-return]

    def __init__(self, fields: Mapping[str, Any]) -> None:
        own: Dict[str, Any] = dict(fields)
        # Attributes that are not keys of the command line's JSON (the native side names them).
        named = own.pop("_extras", None)
        extras = frozenset(named) if named else _NO_EXTRAS
        nested = type(self).__dict__.get("_nested_resolved")
        if nested is None:
            nested = self._nested_fields()
        for name, kind in nested.items():
            value = own.get(name)
            if isinstance(value, list):
                own[name] = [v if isinstance(v, Record) else kind(v) for v in value]
            elif isinstance(value, Mapping) and not isinstance(value, Record):
                own[name] = kind(value)
        object.__setattr__(self, "_fields", own)
        object.__setattr__(self, "_extras", extras)

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
        """The record as the command line's JSON object (nested records as dicts; the extra attributes
        left out)."""

        def plain(v: Any) -> Any:
            if isinstance(v, Record):
                return v.to_dict()
            if isinstance(v, list):
                return [plain(x) for x in v]
            return v

        return {k: plain(v) for k, v in self._fields.items() if k not in self._extras}

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

    bit: int
    name: str
    cause: str


class FlagWord(Record):
    """A flag word (SCU battery/mains, PowerCube state, COMPAX S16 / S17).

    Attributes:
        word: The raw word.
        flags: The names of the flags set, as the manual spells them.
        unknown_bits: Bits set that no flag names (only when nonzero).
        faults: PowerCube state: the flags set that are errors.
        pattern: COMPAX S16 / S17: the word as the drive writes it (``"1101 1010"``, bit 1 first).
    """

    word: int
    flags: List[str]
    unknown_bits: int
    faults: List[str]
    pattern: str


class ErrorCode(Record):
    """An error code with its named bits (SCU Error_Code).

    Attributes:
        code: The raw code.
        bits: The bits set, named.
    """

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
        read_back: After a write: the value the library read back from the device (``None`` if nothing
            could be read back that shows the value written; then ``verified`` is False and
            ``not_verifiable`` says why). Only on the result of ``set``.
        verified: After a write: True when the value read back was compared with the one written.
        not_verifiable: After a write: what could not be verified and why, in plain words (a list of str in
            every family, empty when ``verified``).
        ok: PowerCube ``set``: True (the command line's field).
        module: PowerCube: the module (1..31).
        drive: COMPAX: the drive (1..31).
        title: COMPAX: what the parameter is, where the manual says.
    """

    family: str
    name: str
    id: int
    value: Any
    unit: str
    access: str
    read_back: Any
    verified: bool
    not_verifiable: List[str]
    ok: bool
    module: int
    drive: int
    title: str
