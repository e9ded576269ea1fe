"""The package layout: assets as package data of robofdi.assets, viz/ and experiments/ inside the robofdi namespace."""
from __future__ import annotations

import importlib
import os
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

import robofdi

REPO = Path(__file__).resolve().parents[1]


def test_the_mjcf_is_package_data_of_robofdi_assets():
    arm = resources.files("robofdi.assets").joinpath("arm6.xml")
    assert arm.is_file()
    assert "<mujoco" in arm.read_text(encoding="utf-8")


def test_assets_is_the_folder_of_the_installed_robofdi_assets_package():
    folder = Path(importlib.import_module("robofdi.assets").__file__).resolve().parent
    assert isinstance(robofdi.ASSETS, Path) and robofdi.ASSETS.resolve() == folder
    assert robofdi.assets_dir().resolve() == folder
    assert (robofdi.ASSETS / "arm6.xml").is_file()


def test_viz_and_experiments_import_from_another_folder_only_inside_robofdi(tmp_path):
    """From an unrelated working folder: robofdi.viz / robofdi.experiments import, no top-level viz / experiments."""
    code = ("import importlib.util as u, robofdi.viz, robofdi.experiments.ch3_industrial_robot;"
            "print(u.find_spec('viz') is None and u.find_spec('experiments') is None)")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                         env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"


def test_pyproject_lists_every_package():
    """The packages are explicit in pyproject.toml: a new subpackage that is not listed would be missing from the wheel."""
    tomllib = pytest.importorskip("tomllib")
    setuptools_cfg = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    listed = set(setuptools_cfg["packages"])
    roots = {"robofdi": REPO / "robofdi", **{k: REPO / v for k, v in setuptools_cfg["package-dir"].items()}}
    found = set()
    for name, root in roots.items():
        for init in root.rglob("__init__.py"):
            rel = init.parent.relative_to(root).parts
            if "__pycache__" not in rel:
                found.add(".".join((name, *rel)))
    assert found == listed


def test_every_example_campaign_spec_is_package_data():
    """Each experiments/campaigns/*.toml (robofdi campaign <name>) matches the package-data patterns of
    robofdi.experiments, so the wheel ships it (.ci/run checks the built wheel for the same list)."""
    import fnmatch

    tomllib = pytest.importorskip("tomllib")
    patterns = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"][
        "package-data"]["robofdi.experiments"]
    specs = sorted(p.relative_to(REPO / "experiments").as_posix() for p in (REPO / "experiments" / "campaigns").glob("*.toml"))
    assert {"campaigns/auv.toml", "campaigns/hydraulic.toml", "campaigns/helicopter.toml"} <= set(specs)
    assert [s for s in specs if not any(fnmatch.fnmatch(s, p) for p in patterns)] == []
