"""Writes the typing stubs of the client modules (``motionlink/scu.pyi``, ``powercube.pyi``,
``compax.pyi``) from the operations as they are declared (:mod:`motionlink._ops`): an operation is a
method of the blocking client and, where declared ``aio``, a coroutine of the asyncio client.

    python python/tools/stubs.py          # rewrite the stubs (run with the installed package)
    python python/tools/stubs.py --check  # exit 1 if a checked-in stub differs

``python/tests/test_stubs.py`` fails when a checked-in stub differs from what this writes."""

from __future__ import annotations

import ast
import importlib
import inspect
import sys
from pathlib import Path
from typing import Any, List

MODULES = ("compax", "powercube", "scu")
FOLDER = Path(__file__).resolve().parent.parent / "motionlink"


def _params(fn: Any) -> str:
    out: List[str] = []
    star = False
    for p in inspect.signature(fn).parameters.values():
        if p.kind is p.KEYWORD_ONLY and not star:
            out.append("*")
            star = True
        text = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "") + p.name
        star = star or p.kind is p.VAR_POSITIONAL
        if p.annotation is not p.empty:
            text += f": {p.annotation}"
        if p.default is not p.empty:
            text += " = ..."
        out.append(text)
    ret = inspect.signature(fn).return_annotation
    return f"({', '.join(out)})" + ("" if ret is inspect.Signature.empty else f" -> {ret}")


def stub(name: str) -> str:
    """The stub of ``motionlink.<name>``."""
    from motionlink._ops import op

    module = importlib.import_module(f"motionlink.{name}")
    source = Path(module.__file__).read_text(encoding="utf-8")  # type: ignore[arg-type]
    tree = ast.parse(source)
    lines = [f'"""Typing stubs of :mod:`motionlink.{name}`, written by python/tools/stubs.py: do not edit."""', ""]
    for node in tree.body:
        if isinstance(node, (ast.Import, ast.ImportFrom)) and getattr(node, "module", "") != "__future__":
            lines.append(ast.get_source_segment(source, node) or "")
    lines.append("")
    for node in tree.body:
        if isinstance(node, ast.Assign):
            lines.append(ast.get_source_segment(source, node) or "")
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            lines.append(f"{node.target.id}: {ast.get_source_segment(source, node.annotation)}")
    for cls_name in module.__all__:
        cls = getattr(module, cls_name)
        public_bases = [b for b in cls.__mro__[1:] if not b.__name__.startswith("_") and b is not object]
        lines += ["", "", f"class {cls_name}({public_bases[0].__name__}):"]
        is_async = hasattr(cls, "_run")
        own = [k for k in cls.__mro__ if k.__module__ == module.__name__]
        body = len(lines)
        seen = set()
        for klass in own:
            # A record's fields are its annotations (strings: the modules use postponed annotations).
            for attr, hint in vars(klass).get("__annotations__", {}).items():
                if attr not in seen and not attr.startswith("_"):
                    seen.add(attr)
                    lines.append(f"    {attr}: {hint}")
            for attr, member in vars(klass).items():
                if attr in seen or (attr.startswith("_") and attr != "__init__"):
                    continue
                seen.add(attr)
                if isinstance(member, op):
                    if is_async and not member.aio:
                        continue
                    prefix = "async def" if is_async else "def"
                    lines.append(f"    {prefix} {attr}{_params(member.declared)}: ...")
                elif isinstance(member, property):
                    lines += ["    @property", f"    def {attr}{_params(member.fget)}: ..."]
                elif inspect.isfunction(member):
                    prefix = "async def" if inspect.iscoroutinefunction(member) else "def"
                    lines.append(f"    {prefix} {attr}{_params(member)}: ...")
                elif not callable(member):
                    lines.append(f"    {attr}: {type(member).__name__}")
        if len(lines) == body:
            lines.append("    ...")
    return "\n".join(lines) + "\n"


def main(argv: List[str]) -> int:
    differ = []
    for name in MODULES:
        path = FOLDER / f"{name}.pyi"
        text = stub(name)
        if "--check" in argv:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                differ.append(str(path))
        else:
            path.write_text(text, encoding="utf-8")
    for path in differ:
        print(f"{path} differs from what python/tools/stubs.py writes: run it", file=sys.stderr)
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
