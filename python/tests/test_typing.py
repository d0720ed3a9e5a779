"""Item 7 of the issue: docstrings for every public name, `py.typed` and the native module's stubs ship
with the installed package."""

from __future__ import annotations

import inspect
from pathlib import Path

import motionlink
from motionlink import compax, emulator, errors, powercube, records, scu


def test_every_public_name_has_a_docstring() -> None:
    missing = []
    for mod in (motionlink, records, errors, emulator, powercube, scu, compax):
        assert inspect.getdoc(mod), mod.__name__
        for name in mod.__all__:
            obj = getattr(mod, name)
            if not inspect.getdoc(obj):
                missing.append(f"{mod.__name__}.{name}")
            if inspect.isclass(obj):
                for attr, member in vars(obj).items():
                    if not attr.startswith("_") and (callable(member) or isinstance(member, property)):
                        if not inspect.getdoc(member):
                            missing.append(f"{mod.__name__}.{name}.{attr}")
    assert missing == []


def test_the_package_is_typed() -> None:
    folder = Path(motionlink.__file__).parent
    assert (folder / "py.typed").is_file()
    stub = (folder / "_native.pyi").read_text(encoding="utf-8")
    for cls in ("PowerCubeClient", "ScuClient", "CompaxClient", "NativeEmulator", "AsyncPowerCubeClient"):
        assert f"class {cls}:" in stub
        assert hasattr(motionlink._native, cls)
