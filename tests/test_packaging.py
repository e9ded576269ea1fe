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


def _setuptools_config() -> dict:
    tomllib = pytest.importorskip("tomllib")
    return tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))


def _shipped_folders() -> dict[str, Path]:
    """Every folder of the package roots that holds a file, as its dotted package name (code and data folders)."""
    cfg = _setuptools_config()["tool"]["setuptools"]
    roots = {"robofdi": REPO / "robofdi", **{k: REPO / v for k, v in cfg["package-dir"].items()}}
    found = {}
    for name, root in roots.items():
        for path in root.rglob("*"):
            rel = path.parent.relative_to(root).parts
            if path.is_file() and "__pycache__" not in rel and not path.name.endswith(".pyc") \
                    and not any(p.endswith(".egg-info") for p in rel):
                found[".".join((name, *rel))] = path.parent
    return found


def test_pyproject_lists_every_package():
    """The packages are explicit in pyproject.toml: a new subpackage that is not listed would be missing from the
    wheel, and a data folder (assets/logs, the URDF package, the campaign specs) that is not listed makes setuptools
    warn "Package ... is absent from the `packages` configuration" on every install."""
    listed = set(_setuptools_config()["tool"]["setuptools"]["packages"])
    assert set(_shipped_folders()) == listed


def test_every_asset_and_campaign_spec_matches_a_package_data_pattern():
    """Each non-Python file of a listed folder is matched by a package-data pattern of the nearest package that
    declares one, so the wheel ships it (.ci/run lists the built wheel and checks the same files)."""
    import fnmatch

    cfg = _setuptools_config()["tool"]["setuptools"]
    data = cfg["package-data"]
    uncovered = []
    for name, folder in _shipped_folders().items():
        for path in folder.iterdir():
            if not path.is_file() or path.suffix in (".py", ".pyc"):
                continue
            owner = max((p for p in data if name == p or name.startswith(p + ".")), key=len, default=None)
            root = _shipped_folders()[owner] if owner else None
            rel = path.relative_to(root).as_posix() if root else path.name
            if owner is None or not any(fnmatch.fnmatch(rel, pat) or fnmatch.fnmatch(rel, pat.replace("**/", ""))
                                        for pat in data[owner]):
                uncovered.append(f"{name}:{path.name}")
    assert uncovered == []
    assert isinstance(_setuptools_config()["project"]["license"], str)      # an SPDX expression, not the deprecated table


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
