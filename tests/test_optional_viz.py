"""The Meshcat replay is the optional ``viz`` extra: without meshcat a run writes everything else and says why in
one line, ``robofdi view`` names the extra; with it the replay writers are the usual ones. (.ci/run runs
``robofdi run ch3-actuator`` on the wheel's base dependencies, where meshcat really is absent.)"""
from __future__ import annotations

import sys

import pytest

from robofdi.cli import main
from robofdi.evaluate import run_folder


@pytest.fixture
def no_meshcat(monkeypatch):
    """meshcat uninstalled, as far as imports in this process can tell (robofdi.viz forgotten, so it re-imports)."""
    monkeypatch.setitem(sys.modules, "meshcat", None)
    for name in [m for m in sys.modules if m == "robofdi.viz" or m.startswith("robofdi.viz.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setattr(run_folder, "_noted", False)


def test_without_meshcat_there_is_no_replay_writer_and_one_note(no_meshcat, capsys):
    assert run_folder.replay_writer() is None
    assert run_folder.replay_writer("write_hydraulic_replay", "robofdi.viz.hydraulic") is None
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [run_folder.NO_REPLAY_NOTE] and "pip install 'robofdi[viz]'" in err[0]


def test_without_meshcat_robofdi_view_names_the_extra(no_meshcat, tmp_path, capsys):
    (tmp_path / "record.h5").write_bytes(b"")
    assert main(["view", str(tmp_path)]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install 'robofdi[viz]'" in err


def test_with_meshcat_the_writers_are_the_viz_ones():
    pytest.importorskip("meshcat")
    from robofdi.viz import write_replay_html
    from robofdi.viz.hydraulic import write_hydraulic_replay

    assert run_folder.replay_writer() is write_replay_html
    assert run_folder.replay_writer("write_hydraulic_replay", "robofdi.viz.hydraulic") is write_hydraulic_replay
