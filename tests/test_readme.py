"""The README: its Python example runs as written from an empty folder, and the quick start has two lines."""
from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

from robofdi.record import load

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _python_example() -> str:
    section = README.split("## Python example", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_readme_python_example_runs_from_an_empty_folder(tmp_path):
    code = _python_example()
    assert len(code.strip().splitlines()) <= 20
    schemes = next(ast.literal_eval(k.value) for node in ast.walk(ast.parse(code)) if isinstance(node, ast.Call)
                   for k in node.keywords if k.arg == "schemes")
    env = {"ROBOFDI_CACHE": str(tmp_path / "cache"), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert [line.split()[0] for line in lines] == list(schemes)      # one line per diagnoser of the example
    for line in lines:
        assert "isolated joint2" in line and "false alarms 0" in line, line
    record = load(tmp_path / "my_run.h5")
    assert record.system == "arm6" and record.faults["joint2_additive"].active.any()


def test_readme_quick_start_is_two_lines_in_a_venv():
    block = re.search(r"## Quick start\n.*?```bash\n(.*?)```", README, re.S).group(1).strip().splitlines()
    assert len(block) == 2
    assert block[0].startswith("python3 -m venv .venv && . .venv/bin/activate && pip install -e '.[viz]' ")
    # .ci/run greps this line and runs it in its own fresh venv
    assert block[1] == ". .venv/bin/activate && pip install -e '.[test]' && pytest -n auto --dist loadfile"
    assert len(README.splitlines()) <= 200


def test_readme_and_docs_links_resolve_and_stay_inside_the_repository():
    """Every relative link of the README and the docs pages names a file of the repository (no ../shared/)."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    pages = [p for p in pages if "_build" not in p.parts and "_autosummary" not in p.parts]
    for page in pages:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text(encoding="utf-8")):
            if target.startswith(("http://", "https://", "mailto:", "#")):
                continue
            path = (page.parent / target.split("#", 1)[0]).resolve()
            assert path.is_relative_to(ROOT), f"{page.name}: link {target} leaves the repository"
            assert path.exists(), f"{page.name}: link {target} names no file"
        assert "../shared" not in page.read_text(encoding="utf-8"), page
