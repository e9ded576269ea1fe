"""Figures on demand (issue 23): a run folder draws the lead diagnoser's residual figure and the estimates by
default; `robofdi figures RUN` draws the others from record.h5, byte for byte the PNGs a `figures="all"` run
writes. Real runs of the chapter-3 arm (the suite's short calibration), every scheme online."""
from __future__ import annotations

import shutil
from dataclasses import replace

import pytest

from robofdi import RobofdiError
from robofdi.cli import main
from robofdi.evaluate import summarize
from robofdi.evaluate.run_folder import figures_setting, residual_figures_left, write_run_folder


@pytest.fixture(scope="module")
def folders(ch3, tmp_path_factory):
    """Run folders of one faulty ch3-actuator run (and its fault-free twin as another record): written with the
    default figures, with ``figures="all"`` and with ``figures="none"``."""
    from robofdi.systems.arm import run_scenario

    sc, cal = ch3
    record, fault_free = run_scenario(sc, cal), run_scenario(replace(sc, faults=()), cal)
    root = tmp_path_factory.mktemp("figures")
    out = {}
    for which in ("lead", "all", "none"):
        run_dir = root / which
        run_dir.mkdir()
        figures = None if which == "lead" else which
        out[which] = write_run_folder(run_dir, record, summarize(record, "ch3-actuator"), {"fault_free": fault_free},
                                      replay=False, figures=figures)
    return out, list(record.diagnosers), record.meta["lead_diagnoser"]


def _pngs(folder) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.glob("*.png")}


def test_a_run_folder_draws_the_lead_and_robofdi_figures_the_others_byte_identical(folders, tmp_path, capsys):
    out, names, lead = folders
    assert len(names) == 6 and lead in names
    assert set(_pngs(out["lead"] / "figures")) == {f"residuals_{lead}.png", "estimates.png"}
    assert set(_pngs(out["all"] / "figures")) == {f"residuals_{d}.png" for d in names} | {"estimates.png"}
    assert not any((out["none"] / "figures").iterdir())
    run = shutil.copytree(out["lead"], tmp_path / "run")
    assert sorted(residual_figures_left(run)) == sorted(d for d in names if d != lead)
    assert main(["figures", str(run)]) == 0
    printed = capsys.readouterr().out.split()
    assert len(printed) == 5 and all(p.startswith(str(run / "figures" / "residuals_")) for p in printed)
    assert _pngs(run / "figures") == _pngs(out["all"] / "figures")          # the same bytes as drawn in the run
    assert residual_figures_left(run) == []
    assert main(["figures", str(run)]) == 0 and "nothing to draw" in capsys.readouterr().out
    # --all redraws everything, estimates included, the same bytes again; --diagnoser one
    (run / "figures" / "estimates.png").unlink()
    assert main(["figures", str(run), "--all"]) == 0 and len(capsys.readouterr().out.split()) == 7
    assert main(["figures", str(run), "--diagnoser", "momentum"]) == 0
    assert capsys.readouterr().out.split() == [str(run / "figures" / "residuals_momentum.png")]
    assert _pngs(run / "figures") == _pngs(out["all"] / "figures")


def test_another_record_of_the_folder_gets_its_own_figure_folder(folders, tmp_path, capsys):
    out, names, _ = folders
    run = shutil.copytree(out["none"], tmp_path / "run")
    assert main(["figures", str(run / "fault_free.h5"), "--diagnoser", "recursive"]) == 0
    assert capsys.readouterr().out.split() == [str(run / "figures" / "fault_free" / "residuals_recursive.png")]
    assert main(["figures", str(run), "--record", "fault_free"]) == 0
    assert set(_pngs(run / "figures" / "fault_free")) == {f"residuals_{d}.png" for d in names} | {"estimates.png"}
    assert not any((run / "figures").glob("*.png"))                     # the main record's figures untouched


def test_a_new_run_in_the_folder_removes_the_figures_of_the_earlier_run_it_does_not_redraw(folders, tmp_path):
    out, names, lead = folders
    from robofdi.record import load

    run = shutil.copytree(out["all"], tmp_path / "run")
    assert main(["figures", str(run), "--record", "fault_free"]) == 0
    record, fault_free = load(run / "record.h5"), load(run / "fault_free.h5")
    write_run_folder(run, record, summarize(record, "ch3-actuator"), {"fault_free": fault_free}, replay=False)
    assert sorted(p.relative_to(run).as_posix() for p in (run / "figures").rglob("*")) == \
        ["figures/estimates.png", f"figures/residuals_{lead}.png"]
    name = f"residuals_{lead}.png"
    assert (run / "figures" / name).read_bytes() == (out["all"] / "figures" / name).read_bytes()
    write_run_folder(run, record, summarize(record, "ch3-actuator"), replay=False, figures="none")
    assert not any((run / "figures").iterdir())


def test_the_setting_and_the_command_line_choose_the_figures(folders, tmp_path, capsys):
    out, names, lead = folders
    from robofdi.record import load

    record = load(out["lead"] / "record.h5")
    with figures_setting("none"):
        write_run_folder(tmp_path, record, summarize(record, "ch3-actuator"), replay=False)
    assert not any((tmp_path / "figures").iterdir())
    with pytest.raises(RobofdiError, match=r"^figures must be one of lead, all, none .*got 'every'$"):
        write_run_folder(tmp_path, record, {}, replay=False, figures="every")
    # a bad --figures is refused before anything runs, in one line naming the option and the allowed values
    for command in (["run", "ch3-actuator"], ["demo"]):
        assert main([*command, "--figures", "some", "--out", str(tmp_path), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("robofdi: error: --figures must be one of lead, all, none")
    assert not (tmp_path / "ch3-actuator-seed0").exists()


@pytest.mark.parametrize("args, message", [
    (["{missing}"], "RUN: no run folder at '{missing}'"),
    (["{empty}"], "RUN: no record.h5 in '{empty}'; expected a run folder holding record.h5"),
    (["{parent}"], "its runs are in its folders run (e.g. `robofdi figures {parent}/run`)"),
    (["{run}", "--diagnoser", "kalman"], "--diagnoser: 'kalman' not in record.h5; expected one of simple, "
                                         "time_delayed, recursive, adaptive, position_only, momentum"),
    (["{run}", "--record", "oracle"], "--record: no oracle.h5 in '{run}'; expected --record one of record, fault_free"),
    (["{run}", "--all", "--diagnoser", "simple"], "--all and --diagnoser: give one"),
])
def test_robofdi_figures_bad_input_is_one_line(folders, tmp_path, capsys, args, message):
    out, _, _ = folders
    parent = tmp_path / "parent"
    shutil.copytree(out["none"], parent / "run")             # a folder of runs (like ch6-hydraulic's), no record
    (tmp_path / "empty").mkdir()
    paths = {"missing": tmp_path / "missing", "empty": tmp_path / "empty", "parent": parent, "run": out["none"]}
    assert main(["figures", *(a.format(**paths) for a in args)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("robofdi: error: ") and message.format(**paths) in err, err
    assert not any((out["none"] / "figures").iterdir())
