"""The rerun export of a run folder: the file reads back headless (rerun's own RRD reader) and holds the arm's bodies
and geoms, every residual, threshold and alarm, the true fault and the isolated joint highlighted, on one timeline."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rerun", reason="the rerun export needs the optional extra 'rerun'")
from rerun.chunk import RrdReader  # noqa: E402

from robofdi import RobofdiError  # noqa: E402
from robofdi.record import FaultLabels  # noqa: E402
from robofdi.viz.rerun_export import HIGHLIGHT, TIMELINE, export_rrd  # noqa: E402

from test_viz import make_record  # noqa: E402


def _run_folder(tmp_path):
    record = make_record()                   # arm6, 1 s, a joint3 fault at 0.4 s isolated from 0.45 s
    active = record.time >= 0.4
    record.faults["f1"] = FaultLabels(active, np.where(active, 5.0, 0.0), "N·m")
    tr = record.diagnosers["gom"]
    tr.residual[:, 2] = np.where(tr.time >= 0.42, 2.0, 0.1)
    tr.alarm[:, 2] = tr.time >= 0.42
    record.meta["joint_names"] = [f"joint{i}" for i in range(1, 7)]
    record.save(tmp_path / "record.h5")
    return tmp_path


def test_the_export_reads_back_with_the_arm_residuals_and_alarms(tmp_path):
    path = export_rrd(_run_folder(tmp_path), fps=20)
    assert path == tmp_path / "run.rrd"
    reader = RrdReader(str(path))
    assert [s.application_id for s in reader.recordings()] == ["robofdi"]
    store = reader.store()
    entities = set(store.schema().entity_paths())
    for j in range(1, 7):
        assert {f"/residuals/gom/joint{j}", f"/thresholds/gom/joint{j}", f"/alarms/gom/joint{j}",
                f"/joints/joint{j}", f"/world/robot/link{j}"} <= entities
    assert {"/faults/f1", "/events"} <= entities
    assert sum(e.startswith("/world/robot/link3/geom_") for e in entities) >= 2
    chunks = list(store.stream())
    alarms = [c for c in chunks if c.entity_path == "/alarms/gom/joint3"]
    batch = alarms[0].to_record_batch()
    assert TIMELINE in batch.schema.names and batch.num_rows == 100
    values = np.concatenate([np.asarray(v, dtype=float) for v in batch.column("Scalars:scalars").to_pylist()])
    assert values.sum() == pytest.approx(58)                    # alarmed from 0.42 s: 58 of 100 samples
    # the isolated joint's body turns red at the isolation time (after its colour at t = 0)
    colours = []
    for c in chunks:
        if c.entity_path.startswith("/world/robot/link3/geom_") and not c.is_static:
            b = c.to_record_batch()
            name = next(n for n in b.schema.names if n.endswith(":colors"))
            colours += [(t, v[0]) for t, v in zip(b.column(TIMELINE).to_pylist(), b.column(name).to_pylist())]
    red = int.from_bytes(bytes(HIGHLIGHT), "big")
    assert any(v == red for _, v in colours) and any(v != red for _, v in colours)
    texts = [c for c in chunks if c.entity_path == "/events"]
    logged = sum((c.to_record_batch().column("TextLog:text").to_pylist() for c in texts), [])
    assert any("isolated joint3" in str(t) for t in logged) and any("true fault f1" in str(t) for t in logged)


def test_robofdi_view_rerun_writes_the_recording(tmp_path, capsys):
    from robofdi.cli import main

    folder = _run_folder(tmp_path)
    assert main(["view", str(folder), "--rerun", str(tmp_path / "out.rrd")]) == 0
    assert (tmp_path / "out.rrd").stat().st_size > 0 and "out.rrd" in capsys.readouterr().out


def test_bad_input_is_one_line(tmp_path):
    with pytest.raises(RobofdiError, match="neither a run folder"):
        export_rrd(tmp_path)
    with pytest.raises(RobofdiError, match="fps"):
        export_rrd(make_record(), tmp_path / "x.rrd", fps=0)
    with pytest.raises(RobofdiError, match="path: expected"):
        export_rrd(make_record())
