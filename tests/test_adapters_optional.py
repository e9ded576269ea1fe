"""The adapters' dependencies are optional: the core imports without them, an adapter says how to install them."""
from __future__ import annotations

import subprocess
import sys

BLOCK = "import sys; sys.modules['dm_control'] = None; sys.modules['dm_env'] = None; "


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", BLOCK + code], capture_output=True, text=True, timeout=120)


def test_core_imports_without_dm_control():
    out = _run("import robofdi, robofdi.faults, robofdi.cli, robofdi.adapters, robofdi.models.multibody; print('ok')")
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


def test_dm_control_adapter_without_dm_control_says_what_to_install():
    for module in ("robofdi.adapters.dm_control", "robofdi.adapters.dm_control_diagnosis"):
        out = _run(f"import {module}")
        last = out.stderr.strip().splitlines()[-1]
        assert out.returncode != 0 and last.startswith("ImportError:") and "pip install 'robofdi[dm_control]'" in last, out.stderr


ROBOSUITE_BLOCK = "import sys; sys.modules['robosuite'] = None; "


def test_core_cli_and_campaigns_without_robosuite_say_what_to_install():
    code = ROBOSUITE_BLOCK + ("import robofdi.cli, robofdi.campaign; from robofdi.cli import _experiments; "
                              "assert 'robosuite-lift' in _experiments(); "
                              "from robofdi.campaign import load_spec\n"
                              "try:\n    load_spec({'system': 'robosuite-lift', 'fault_free_runs': 1})\n"
                              "except Exception as e:\n    print(type(e).__name__, e)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("RobofdiError") and "pip install 'robofdi[robosuite]'" in out.stdout, out.stdout
    for module in ("robofdi.adapters.robosuite", "robofdi.adapters.robosuite_diagnosis"):
        out = subprocess.run([sys.executable, "-c", ROBOSUITE_BLOCK + f"import {module}"], capture_output=True, text=True,
                             timeout=120)
        last = out.stderr.strip().splitlines()[-1]
        assert out.returncode != 0 and "pip install 'robofdi[robosuite]'" in last, out.stderr


def test_rerun_export_without_rerun_says_what_to_install(monkeypatch):
    import pytest

    from robofdi.adapters import adapter
    from robofdi.errors import RobofdiError

    monkeypatch.setitem(sys.modules, "rerun", None)
    monkeypatch.delitem(sys.modules, "robofdi.viz.rerun_export", raising=False)
    with pytest.raises(RobofdiError, match=r"pip install 'robofdi\[rerun\]'"):
        adapter("robofdi.viz.rerun_export", "rerun")
