"""motionlink: Ewellix/Schaeffler SCU lifting-column control units, Schunk/Amtec PowerCube modules and
Parker COMPAX drives from Python, safely.

Clients (:class:`Scu`, :class:`PowerCube`, :class:`Compax`, and their asyncio twins) open the port they
are given, a port URL (``"/dev/ttyUSB0"``, ``"tcp://HOST:PORT"``, ``"socketcan://can0"``,
``"slcan:///dev/ttyACM0"``, ``"sim"`` for an emulator in this process) or an :class:`Emulator`; given none,
the port the environment variable ``MOTIONLINK_PORT`` names, as the command line does. There is no
default port: without either, a client raises :class:`UsageError`. A client is a context manager: leaving
the block stops any motion it started. Results are typed records whose field names carry their units;
failures are :class:`MotionlinkError`\\ s. :func:`probe` is ``motionlink probe``: it identifies a device and
probes what the manuals leave open, and can save a device profile that later clients load (``profile=``).
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
from ._probe import ProbeCheck, ProbeReport, probe
from .powercube import AsyncPowerCube, PowerCube
from .scu import AsyncScu, Scu

__all__ = [
    "Emulator",
    "Event",
    "probe",
    "ProbeReport",
    "ProbeCheck",
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
