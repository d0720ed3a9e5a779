"""Commissioning from Python: :func:`probe` and its :class:`ProbeReport`, the same report as
``motionlink probe <family> --json`` (see ``docs/commissioning.md``), and the ``profile=`` option of the
clients, which load the device profile that ``probe(..., save=True)`` or ``motionlink probe --save`` wrote."""

from __future__ import annotations

import os
import sys
import warnings
from typing import Any, Dict, List, Optional, Union

from ._args import refused
from ._record import Record
from .errors import UsageError

__all__ = ["probe", "ProbeReport", "ProbeCheck", "profile_setting", "warn_profile_notices"]

Profile = Union[bool, str, "os.PathLike[str]", None]
"""``True`` (default): profiles.toml beside devices.toml; ``False`` or ``None``: no profile; a path: that
profiles file."""


def profile_setting(profile: Profile) -> str:
    """The native side's form of a client's ``profile=`` option."""
    if profile is True:
        return "auto"
    if profile is False or profile is None:
        return "off"
    if isinstance(profile, (str, os.PathLike)):
        return os.fspath(profile)
    raise refused("profile", profile, "True, False or the path of a profiles file")


_PACKAGE = os.path.dirname(os.path.abspath(__file__))


def _outside_the_package() -> int:
    """The ``stacklevel`` of a warning issued by the caller of this function that points at the first frame
    outside this package: the user's line, however many of the package's frames lie between (a
    constructor, ``async with``, ``await client.open()``, :func:`probe`)."""
    frame = sys._getframe(2)
    level = 2
    while frame is not None and os.path.dirname(os.path.abspath(frame.f_code.co_filename)) == _PACKAGE:
        frame = frame.f_back  # type: ignore[assignment]
        level += 1
    return level


def warn_profile_notices(native: Any) -> None:
    """Says, as a :class:`UserWarning` pointing at the user's line, each profile the session did not take
    (another identity, a file it could not read)."""
    notices = native.profile_notices
    if notices:
        level = _outside_the_package()
        for notice in notices:
            warnings.warn(notice, UserWarning, stacklevel=level)


class ProbeCheck(Record):
    """One check of a :class:`ProbeReport`: ``name``, ``result`` (``"ok"``, ``"unsupported"``, ``"failed"``,
    ``"skipped"``), ``detail``, ``sends`` (what the probe sent; nothing that moves), and where they apply
    ``address`` (a module or drive) and ``variant`` (the emulator variant that behaves otherwise)."""

    name: str
    result: str
    detail: str
    sends: str


class ProbeReport(Record):
    """What ``motionlink probe <family> --json`` prints: ``family``, ``port``, ``devices`` (dicts: identity,
    firmware, what was probed), ``link`` (round trips, errors, baud rate, latency timer), ``checks``
    (:class:`ProbeCheck`) and ``saved`` (the profiles written, ``<path>#<key>``)."""

    family: str
    port: str
    devices: List[Dict[str, Any]]
    link: Dict[str, Any]
    checks: List[ProbeCheck]
    saved: List[str]

    def check(self, name: str, address: Optional[int] = None) -> ProbeCheck:
        """The check ``name`` (of the module or drive at ``address``)."""
        for c in self.checks:
            if c.name == name and c.get("address") == address:
                return c
        raise KeyError(f"no check {name!r}" + (f" of {address}" if address is not None else ""))


def probe(
    family: str,
    port: Optional[Union[str, Any]] = None,
    *,
    save: Union[bool, str, "os.PathLike[str]"] = False,
    exchanges: int = 20,
    low_latency: bool = False,
    **options: Any,
) -> ProbeReport:
    """Probes the device of ``family`` (``"scu"``, ``"powercube"``, ``"compax"``) on ``port`` as
    ``motionlink probe <family>`` does: identifies it, measures the link over ``exchanges`` reads, and runs
    every harmless probe of what the manuals leave open (nothing moves). ``save``: ``True`` writes the device
    profile to profiles.toml beside devices.toml, a path to that file; later clients on this port load it.
    ``options`` are the family client's (``baud``, ``mode``, ...; for COMPAX also ``drives="1-31"``, the
    addresses looked at). ``low_latency`` sets a USB serial adapter's latency timer to 1 ms where permitted.
    The baud rate is the one given (the command line's ``--baud auto`` searches)."""
    from .compax import Compax
    from .powercube import PowerCube
    from .scu import Scu

    clients = {"scu": Scu, "powercube": PowerCube, "compax": Compax}
    if family not in clients:
        raise UsageError(f"family {family!r}: give one of {', '.join(clients)}")
    drives = options.pop("drives", "1-31") if family == "compax" else None
    with clients[family](port, profile=False, **options) as client:
        return client.probe(save=save, exchanges=exchanges, low_latency=low_latency, **({"drives": drives} if drives else {}))


def save_setting(save: Union[bool, str, "os.PathLike[str]"]) -> Optional[str]:
    """The native side's form of ``save``: None (no), ``""`` (the default file) or a path."""
    if save is False or save is None:
        return None
    if save is True:
        return ""
    if isinstance(save, (str, os.PathLike)):
        return os.fspath(save)
    raise refused("save", save, "True, False or the path of a profiles file")
