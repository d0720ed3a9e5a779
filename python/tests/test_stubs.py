"""The client modules' typing stubs are what python/tools/stubs.py writes from the operations' declarations
(one declaration per operation: the blocking method, the asyncio coroutine and the stub entry)."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
from pathlib import Path

import pytest

import motionlink

TOOL = Path(__file__).resolve().parent.parent / "tools" / "stubs.py"


def _tool():
    spec = importlib.util.spec_from_file_location("motionlink_stubs", TOOL)
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("name", _tool().MODULES)
def test_checked_in_stub_is_generated(name: str) -> None:
    path = TOOL.parent.parent / "motionlink" / f"{name}.pyi"
    assert path.read_text(encoding="utf-8") == _tool().stub(name), f"run python/tools/stubs.py: {path}"


def test_one_declaration_gives_both_faces() -> None:
    move = motionlink.PowerCube.move_to
    assert str(inspect.signature(move)) == str(inspect.signature(motionlink.AsyncPowerCube.move_to))
    stub = (TOOL.parent.parent / "motionlink" / "powercube.pyi").read_text(encoding="utf-8")
    assert "    def move_to(self, target: float" in stub and "    async def move_to(self, target: float" in stub
    # An operation the asyncio client does not have is not there.
    assert "    async def scan" not in stub and "    def scan(self) -> List[ModuleInfo]: ..." in stub
    assert not hasattr(motionlink.AsyncPowerCube(port="sim"), "scan")
    assert not hasattr(motionlink.AsyncPowerCube, "scan") and hasattr(motionlink.PowerCube, "scan")
    # Each class has its face: a function, or a coroutine function, with the declaration's docstring.
    assert inspect.iscoroutinefunction(motionlink.AsyncPowerCube.move_to)
    assert not inspect.iscoroutinefunction(motionlink.PowerCube.move_to)
    assert motionlink.PowerCube.move_to.__doc__ == motionlink.AsyncPowerCube.move_to.__doc__


@pytest.mark.parametrize("name", _tool().MODULES)
def test_stub_is_python_with_each_records_fields(name: str) -> None:
    # A type checker reads the stub: it must parse, and a record class declared in the module lists its
    # fields (an empty class body was a syntax error that made every user's type check of the package fail).
    text = (TOOL.parent.parent / "motionlink" / f"{name}.pyi").read_text(encoding="utf-8")
    tree = ast.parse(text)
    module = importlib.import_module(f"motionlink.{name}")
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            cls = getattr(module, node.name)
            fields = [n.target for n in node.body if isinstance(n, ast.AnnAssign)]
            stubbed = {t.id for t in fields if isinstance(t, ast.Name)}
            own = {k for k in vars(cls).get("__annotations__", {}) if not k.startswith("_")}
            assert own <= stubbed, f"{name}.pyi: {node.name} lacks {sorted(own - stubbed)}"
    if name == "scu":
        assert "class ScuStop(Record):\n    family: str\n" in text


@pytest.mark.parametrize(
    "name, classes, attribute",
    [("powercube", ("PowerCube", "AsyncPowerCube"), "module"), ("compax", ("Compax", "AsyncCompax"), "drive")],
)
def test_the_clients_public_attributes_are_in_the_stubs(name: str, classes: "tuple[str, ...]", attribute: str) -> None:
    """`PowerCube.module` and `Compax.drive` (what the operations address unless told otherwise) are public:
    each client class of the stub declares it, so that a type checker knows them."""
    text = (TOOL.parent.parent / "motionlink" / f"{name}.pyi").read_text(encoding="utf-8")
    tree = ast.parse(text)
    declared = {
        node.name: {n.target.id for n in node.body if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)}
        for node in tree.body
        if isinstance(node, ast.ClassDef)
    }
    for cls in classes:
        assert attribute in declared[cls], f"{name}.pyi: {cls} lacks {attribute}"
        client = getattr(motionlink, cls)("sim", 2)
        try:
            assert getattr(client, attribute) == 2
        finally:
            if not cls.startswith("Async"):
                client.close()


def test_a_type_checker_accepts_a_users_program(tmp_path: Path) -> None:
    """mypy --strict on a user's program as the documentation writes one: the clients' attributes
    (`cube.module`, `drive.drive`), an SCU stop of everything (a report) and of one function (None), a
    record's fields, an async client. `.ci/run` installs mypy; elsewhere the test says it was skipped."""
    api = pytest.importorskip("mypy.api")
    program = tmp_path / "program.py"
    program.write_text(
        "import asyncio\n"
        "import motionlink\n"
        "from typing import List\n"
        "\n"
        "def main() -> None:\n"
        "    cube = motionlink.PowerCube('sim')\n"
        "    drive = motionlink.Compax('sim')\n"
        "    n: int = cube.module + drive.drive\n"
        "    with motionlink.Scu('sim', functions='tlt') as lift:\n"
        "        moved = lift.move_to(1, 400)\n"
        "        rest: List[motionlink.scu.ActuatorAtRest] = lift.stop().at_rest\n"
        "        one: List[motionlink.scu.ActuatorAtRest] = lift.stop(1).at_rest\n"
        "        print(moved.to_dict(), rest, one, n)\n"
        "\n"
        "async def amain() -> None:\n"
        "    async with motionlink.AsyncScu('sim') as lift:\n"
        "        stopped = await lift.stop()\n"
        "        print(stopped.functions)\n"
        "    async with motionlink.AsyncPowerCube('sim') as cube:\n"
        "        print((await cube.move_to(0.5)).reached_rad)\n"
    )
    out, err, status = api.run(
        ["--strict", str(program), "--no-incremental", "--cache-dir", str(tmp_path / "cache")]
    )
    assert status == 0, out + err
