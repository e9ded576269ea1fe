"""Systems and experiments are found, not listed: the package's own modules, and installed plug-ins through the
entry-point groups ``robofdi.systems`` / ``robofdi.experiments`` (a real dist-info folder on sys.path here)."""
from __future__ import annotations

import sys
import textwrap

import pytest

import robofdi.systems as systems
from robofdi import RobofdiError
from robofdi.cli import main
from robofdi.experiments import experiments

PLUGIN = '''
from dataclasses import dataclass

from robofdi.systems import register_system
from robofdi.systems.linear import LinearOptions, LinearSystem

EXPERIMENTS = {"plugin-hello": "an experiment from an installed plug-in"}


def run(name, out="runs", seed=0, progress=True):
    raise RuntimeError("not run by this test")


class PluginLinear(LinearSystem):
    """The linear plant under another name, from a plug-in."""

    name = "plugin-linear"
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    (tmp_path / "robofdi_plugin_probe.py").write_text(textwrap.dedent(PLUGIN))
    info = tmp_path / "robofdi_plugin_probe-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: robofdi-plugin-probe\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[robofdi.systems]\nplugin-linear = robofdi_plugin_probe:PluginLinear\n\n"
                                           "[robofdi.experiments]\nplugin-hello = robofdi_plugin_probe\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(systems, "_discovered", False)
    yield
    systems.SYSTEMS.pop("plugin-linear", None)
    sys.modules.pop("robofdi_plugin_probe", None)


def test_every_shipped_system_is_found_without_a_list():
    names = systems.system_names()
    for name in ("arm", "auv", "hydraulic", "linear", "helicopter", "robosuite-lift", "dm_control-cartpole"):
        assert name in names
        assert systems.get_system(name).name == name


def test_an_installed_plugin_adds_a_system_and_an_experiment(plugin, capsys):
    assert "plugin-linear" in systems.system_names()
    assert systems.get_system("plugin-linear").name == "plugin-linear"
    assert "plugin-hello" in experiments()
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "plugin-hello" in out and "plugin-linear" in out


def test_unknown_names_are_one_clear_error(capsys):
    with pytest.raises(RobofdiError, match="unknown system 'nope'.*arm"):
        systems.get_system("nope")
    with pytest.raises(RobofdiError, match="cannot import 'no_such_module:X'"):
        systems.get_system("no_such_module:X")
    with pytest.raises(RobofdiError, match="does not implement the System protocol.*missing: .*run"):
        systems.register_system(type("Half", (), {"name": "half", "options_type": dict}))
    assert main(["run", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown experiment or system 'nope'" in err
