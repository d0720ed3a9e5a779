"""motionlink: Ewellix/Schaeffler SCU lifting-column control units, Schunk/Amtec PowerCube modules and
Parker COMPAX drives from Python, safely.

Clients (:class:`Scu`, :class:`PowerCube`, :class:`Compax`, and their asyncio twins) open a port URL
(``"sim"``, ``"tcp://HOST:PORT"``, ``"/dev/ttyUSB0"``, ``"socketcan://can0"``, ``"slcan:///dev/ttyACM0"``)
or an :class:`Emulator`. A client is a context manager: leaving the block stops any motion it started.
Results are typed records whose field names carry their units; failures are :class:`MotionlinkError`\\ s.
"""

from __future__ import annotations

from .compax import AsyncCompax, Compax
from .emulator import Emulator, Event
from .errors import (
    Cancelled,
    CorruptFrame,
    DeviceError,
    DeviceRefused,
    Disconnected,
    MotionlinkError,
    TimeoutError,
    TransportError,
    UsageError,
)
from .powercube import AsyncPowerCube, PowerCube
from .scu import AsyncScu, Scu

__all__ = [
    "Emulator",
    "Event",
    "Scu",
    "AsyncScu",
    "Compax",
    "AsyncCompax",
    "PowerCube",
    "AsyncPowerCube",
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

__version__ = "0.1.0"
