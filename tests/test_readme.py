"""The README's Python example, executed as written, on an arm file of the user's own (tests/data/my_arm.xml)."""
from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

from robofdi.observers.arm_schemes import SCHEMES
from robofdi.record import load

ROOT = Path(__file__).resolve().parents[1]


def _python_example() -> str:
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## Python example", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_readme_python_example_runs_and_diagnoses(tmp_path, monkeypatch):
    code = _python_example()
    assert len(code.strip().splitlines()) <= 20
    shutil.copy(ROOT / "tests" / "data" / "my_arm.xml", tmp_path / "my_arm.xml")
    env = {"ROBOFDI_CACHE": str(tmp_path / "cache"), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert len(lines) == len(SCHEMES)                        # one line per arm diagnoser
    for line in lines:
        assert "isolated joint2" in line and "false alarms 0" in line, line
    record = load(tmp_path / "my_run.h5")
    assert record.system == "my_arm" and record.faults["joint2_additive"].active.any()
