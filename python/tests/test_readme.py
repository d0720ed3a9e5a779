"""Every Python block of the user documentation (README.md, then docs/*.md in name order), run as it stands.

- The block marked ``<!-- python-example -->`` is the ten-line example: run, and its output checked.
- A block marked ``<!-- python-fixture -->`` is a test module: run under pytest, its tests must pass.
- Every other ``python`` block is a script that must end without an error. A port in a client's
  constructor (``motionlink.Scu("/dev/ttyUSB0", ...)``) is pointed at an emulator of that family served
  over TCP, as the command-line test points ``--port`` at one: a TLT column pair for an SCU block that
  names the ``"tlt"`` map, ``"sim"`` left as it is.
- A block marked ``python not-run`` is not run, on purpose; nothing else is skipped.
"""

from __future__ import annotations

import contextlib
import re
import subprocess
import sys
from pathlib import Path
from typing import List, NamedTuple, Optional

import pytest

import motionlink

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


class Block(NamedTuple):
    place: str  # "docs/python.md:17", the line of the opening fence
    not_run: bool
    marker: Optional[str]  # the HTML comment on the line before the fence
    code: str


def python_blocks() -> List[Block]:
    """The ``python`` blocks of every page, in order."""
    found: List[Block] = []
    for page in PAGES:
        name = page.relative_to(ROOT).as_posix()
        lines = page.read_text(encoding="utf-8").splitlines()
        previous: Optional[str] = None
        i = 0
        while i < len(lines):
            t = lines[i].strip()
            if t.startswith("```"):
                words = t[3:].split()
                end = next((j for j in range(i + 1, len(lines)) if lines[j].strip() == "```"), None)
                assert end is not None, f"{name}:{i + 1}: a block that is never closed"
                if words and words[0] == "python":
                    assert words[1:] in ([], ["not-run"]), f"{name}:{i + 1}: {words[1:]}: only not-run is known"
                    marker = previous if previous and previous.startswith("<!--") else None
                    code = "\n".join(lines[i + 1 : end]) + "\n"
                    found.append(Block(f"{name}:{i + 1}", words[1:] == ["not-run"], marker, code))
                previous, i = "```", end + 1
                continue
            if t:
                previous = t
            i += 1
    return found


BLOCKS = python_blocks()
EXAMPLE = "<!-- python-example -->"
FIXTURE = "<!-- python-fixture -->"
SCRIPTS = [b for b in BLOCKS if not b.not_run and b.marker not in (EXAMPLE, FIXTURE)]


def test_the_blocks_are_found() -> None:
    assert [b.marker for b in BLOCKS].count(EXAMPLE) == 1, BLOCKS
    assert [b.marker for b in BLOCKS].count(FIXTURE) >= 1, BLOCKS
    quick = [b for b in SCRIPTS if b.place.startswith("README.md")]
    assert any('motionlink.Scu("/dev/ttyUSB0", functions="tlt")' in b.code for b in quick), quick
    for client in ("motionlink.PowerCube(", "motionlink.Compax("):
        assert any(client in b.code for b in quick), f"the README's quick start has no {client}"
    assert all(b.marker is None for b in SCRIPTS), [b.place for b in SCRIPTS if b.marker]


def example() -> str:
    return next(b.code for b in BLOCKS if b.marker == EXAMPLE)


def test_the_example_is_ten_lines() -> None:
    lines = [line for line in example().splitlines() if line.strip()]
    assert len(lines) <= 10, lines


def test_the_readme_example_runs(tmp_path: Path) -> None:
    # Run from an empty folder: `python -c` puts the working directory first on sys.path, and run from
    # python/ that would import the source folder motionlink/ (without its built extension) instead of
    # the installed package.
    done = subprocess.run(
        [sys.executable, "-c", example()], capture_output=True, text=True, timeout=60, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    out = done.stdout.splitlines()
    assert out[0] == "rotary"
    assert out[1] == "0.500 rad"
    assert len(out) == 5 and all(line.endswith("['STATE_HOME_OK', 'STATE_RAMP_END']") for line in out[2:]), out


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.marker == FIXTURE], ids=lambda b: b.place)
def test_the_fixture_pattern_passes_under_pytest(block: Block, tmp_path: Path) -> None:
    (tmp_path / "test_fixture_pattern.py").write_text(block.code, encoding="utf-8")
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert re.search(r"\b[1-9]\d* passed", done.stdout), done.stdout


CLIENT = re.compile(r'motionlink\.(?:Async)?(Scu|PowerCube|Compax)\(\s*"([^"]*)"')
FAMILY = {"Scu": "scu", "PowerCube": "powercube", "Compax": "compax"}


def pointed_at_emulators(code: str, emulators: contextlib.ExitStack) -> str:
    """``code`` with the port of each client constructor replaced by a served emulator of its family."""

    def serve(found: "re.Match[str]") -> str:
        cls, port = found.group(1), found.group(2)
        if port == "sim":
            return found.group(0)
        family = FAMILY[cls]
        preset = "tlt" if family == "scu" and '"tlt"' in code else None
        emu = emulators.enter_context(motionlink.Emulator(family, serve="tcp", preset=preset))
        return found.group(0).replace(f'"{port}"', f'"{emu.port}"')

    return CLIENT.sub(serve, code)


def test_ports_are_pointed_at_emulators() -> None:
    with contextlib.ExitStack() as emulators:
        code = pointed_at_emulators('a = motionlink.Scu("/dev/ttyUSB0", functions="tlt")\n', emulators)
        assert re.fullmatch(r'a = motionlink\.Scu\("tcp://127\.0\.0\.1:\d+", functions="tlt"\)\n', code), code
        assert pointed_at_emulators('motionlink.Compax("sim")', emulators) == 'motionlink.Compax("sim")'


@pytest.mark.parametrize("block", SCRIPTS, ids=lambda b: b.place)
def test_every_python_block_runs(block: Block, tmp_path: Path) -> None:
    # From an empty folder, as the example above: never the source folder's package.
    with contextlib.ExitStack() as emulators:
        code = pointed_at_emulators(block.code, emulators)
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path
        )
    assert done.returncode == 0, f"{block.place}\n{code}\n{done.stdout}{done.stderr}"
