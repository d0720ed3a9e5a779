"""The README's ten-line Python example, extracted from the README and run as it stands."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"


def example() -> str:
    text = README.read_text(encoding="utf-8")
    found = re.search(r"<!-- python-example -->\n```python\n(.*?)```", text, re.S)
    assert found, "README.md has no <!-- python-example --> block"
    return found.group(1)


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


def test_the_readme_fixture_pattern_passes_under_pytest(tmp_path: Path) -> None:
    text = README.read_text(encoding="utf-8")
    found = re.search(r"<!-- python-fixture -->\n```python\n(.*?)```", text, re.S)
    assert found, "README.md has no <!-- python-fixture --> block"
    (tmp_path / "test_fixture_pattern.py").write_text(found.group(1), encoding="utf-8")
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 passed" in done.stdout
