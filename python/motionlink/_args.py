"""The arguments the Python layer shapes before the native side checks them: a text or a list of texts, a
list of numbers, a mapping. A value of another shape is a :class:`UsageError` naming the argument and the
value, as the native side's checks of single values (an int, a float, a bool, a str) say it."""

from __future__ import annotations

from typing import Any, Dict, List, Mapping, Tuple

from .errors import UsageError

__all__ = ["texts", "items", "listed", "mapping", "refused"]


def refused(name: str, value: Any, what: str, family: str = "") -> UsageError:
    """The usage error of argument ``name``, whose ``value`` is none of ``what`` (``"a dict"``): ``name``,
    the value and its type, then ``give`` ``what``."""
    kind = type(value).__name__
    article = "an" if kind[:1].lower() in "aeiou" else "a"
    return UsageError(f"{name} {value!r} ({article} {kind}): give {what}", family=family)


def _a_list(value: Any) -> bool:
    """True for a list, tuple or other iterable that is no text, mapping or set (whose order is none)."""
    if isinstance(value, (str, bytes, bytearray, Mapping, set, frozenset)):
        return False
    try:
        iter(value)
    except TypeError:
        return False
    return True


def texts(value: Any, name: str, family: str = "") -> List[str]:
    """``value`` as a list of str: one str is one element (never a sequence of letters); a list or tuple of
    str is taken as it is."""
    if isinstance(value, str):
        return [value]
    if not _a_list(value):
        raise refused(name, value, "a str or a list of str", family)
    out = list(value)
    for v in out:
        if not isinstance(v, str):
            raise refused(name, v, "a str", family)
    return out


def items(value: Any, name: str, family: str = "") -> List[str]:
    """``value`` as a list of names or numbers, each as a str: one str or int is one element; a list or
    tuple of them is taken as it is (a bool is neither)."""
    if isinstance(value, (str, int)) and not isinstance(value, bool):
        return [str(value)]
    if not _a_list(value):
        raise refused(name, value, "a str, an int or a list of them", family)
    out = list(value)
    for v in out:
        if isinstance(v, bool) or not isinstance(v, (str, int)):
            raise refused(name, v, "a str or an int", family)
    return [str(v) for v in out]


def listed(value: Any, name: str, family: str = "") -> List[Any]:
    """``value`` (a list or tuple, such as addresses) as a list; its elements are the native side's to
    check."""
    if not _a_list(value):
        raise refused(name, value, "a list", family)
    return list(value)


def mapping(value: Any, name: str, family: str = "") -> List[Tuple[str, Any]]:
    """``value`` (a dict) as its (key, value) pairs; a key must be a str, the values are the native side's
    to check."""
    if not isinstance(value, Mapping):
        raise refused(name, value, "a dict", family)
    pairs: Dict[str, Any] = {}
    for k, v in value.items():
        if not isinstance(k, str):
            raise refused(f"{name} key", k, "a str", family)
        pairs[k] = v
    return list(pairs.items())
