"""What the emulators report when a long move of the tests starts, when it is stopped, and when the client
ended its session (``None`` where the device shows no such thing), per family: the events of
``motionlink.Emulator`` and of ``motionlink sim --events`` are the same texts."""

from __future__ import annotations

from typing import Callable, Dict, Optional, Tuple

Match = Callable[[str], bool]

EVENTS: Dict[str, Tuple[Match, Match, Optional[Match]]] = {
    "powercube": (
        lambda t: "motion started" in t,
        lambda t: t == "module 1 halted",
        lambda t: t == "module 1 watchdog offline",
    ),
    "scu": (
        lambda t: t.startswith("F1 started direction 9"),
        lambda t: t.startswith("F1 stopped (RS"),
        lambda t: t == "remote mode closed by RA",
    ),
    "compax": (lambda t: "motion started" in t, lambda t: "switched off" in t or "at rest" in t, None),
}
