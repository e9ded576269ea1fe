"""robofdi: model-based fault detection, isolation, identification and fault-tolerant control of robots.

The simulator is the truth (MuJoCo), the nominal model is the belief (Pinocchio, or matrices): diagnosers see
only nominal models, commands and measurements. The main objects, importable from here::

    import robofdi as fdi
    from robofdi.systems import arm
    scenario = arm.arm_scenario(fdi.ASSETS / "arm6.xml", faults=["actuator_additive:joint2:100@1.0"], seed=1)
    cal, _ = arm.calibration(scenario)           # thresholds per robot and seed (cached: robofdi.calibration)
    record = arm.run_scenario(scenario, cal)     # the closed-loop run, every arm diagnoser online
    summary = fdi.summarize(record, "my-test")   # detection delay, isolation, false alarms, estimate error

Rooms: ``faults`` (what fails), ``sims`` (plants), ``models`` (beliefs), ``control``, ``observers`` (residual
generators), ``decision`` (thresholds, isolation), ``ftc`` (accommodation), ``loop`` (ClosedLoop), ``record``,
``evaluate`` (metrics, summary.json, figures), ``systems`` (one module per plant family: configuration →
calibrated loop, campaign face; a registry), ``calibration`` (the one calibration cache), ``campaign``
(many seeded runs, local pool or Dask, campaign metrics), ``viz``
(Meshcat), ``experiments`` (one script per book chapter / paper).
"""
from importlib import resources
from pathlib import Path

__version__ = "0.1.0"
# Public API, imported lazily (``robofdi.X`` loads the room of X on first use): name -> module.
_API = {
    "Fault": "robofdi.faults", "FaultInjector": "robofdi.faults", "parse_fault_spec": "robofdi.faults",
    "Step": "robofdi.faults", "ExponentialRise": "robofdi.faults", "Ramp": "robofdi.faults",
    "Sinusoid": "robofdi.faults", "Intermittent": "robofdi.faults",
    "ArmSimulator": "robofdi.sims", "SensorModel": "robofdi.sims", "TorqueRipple": "robofdi.sims",
    "ManipulatorModel": "robofdi.models", "ModelMismatch": "robofdi.models",
    "ComputedTorque": "robofdi.control", "Quintic": "robofdi.control", "MotionLimits": "robofdi.control",
    "random_point_to_point": "robofdi.control",
    "DiagnosticObserver": "robofdi.observers", "MomentumObserver": "robofdi.observers",
    "ThresholdDecision": "robofdi.decision", "Signature": "robofdi.decision", "calibrate_thresholds": "robofdi.decision",
    "FaultCompensation": "robofdi.ftc",
    "ClosedLoop": "robofdi.loop", "Diagnosis": "robofdi.loop", "Rates": "robofdi.loop", "RunAborted": "robofdi.loop",
    "RunInterrupted": "robofdi.loop",
    "diagnose_record": "robofdi.loop",
    "Record": "robofdi.record", "load": "robofdi.record",
    "summarize": "robofdi.evaluate", "write_summary": "robofdi.evaluate", "results_table": "robofdi.evaluate",
    "ArmScenario": "robofdi.systems.arm", "arm_scenario": "robofdi.systems.arm",
    "run_scenario": "robofdi.systems.arm",
    "Health": "robofdi.protocols",
    "LinearModel": "robofdi.models", "LinearPlant": "robofdi.sims", "ObserverResidual": "robofdi.observers",
    "StateFeedback": "robofdi.control",
    "Oscillation": "robofdi.faults", "EffectivenessCompensation": "robofdi.ftc", "GainCompensation": "robofdi.ftc",
    "KalmanFaultEstimator": "robofdi.observers.kalman", "UnknownInputObserver": "robofdi.observers.uio",
    "LockInPlaceBank": "robofdi.observers.uio", "AdaptiveFaultEstimator": "robofdi.observers.adaptive",
    "GainFaultObserver": "robofdi.observers.gain", "SwitchingIndexDecision": "robofdi.decision",
    "WindowedTTest": "robofdi.decision", "EkfBank": "robofdi.observers.ekf_bank", "NisBankDecision": "robofdi.decision",
    "ControlAffineModel": "robofdi.models", "derive_nlar": "robofdi.redundancy",
    "HydraulicScenario": "robofdi.systems.hydraulic",
    "run_campaign": "robofdi.campaign", "load_spec": "robofdi.campaign",
}
__all__ = ["ASSETS", "RobofdiError", "__version__", "assets_dir", *_API]


def __getattr__(name: str):
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'robofdi' has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_API))


def assets_dir() -> Path:
    """Folder of the shipped MJCF models: the package data of ``robofdi.assets`` (the repository's ``assets/``).

    Read through ``importlib.resources``; robofdi is installed as plain files (wheel or ``pip install -e .``), so
    this is a real folder that MuJoCo and Pinocchio can open by path.
    """
    try:
        folder = resources.files("robofdi.assets")
    except ModuleNotFoundError:
        # A source checkout on PYTHONPATH without an install: robofdi.assets is only mapped by the packaging.
        folder = Path(__file__).resolve().parents[1] / "assets"
        if not (folder / "__init__.py").is_file():
            raise
    if not isinstance(folder, Path):
        raise RuntimeError(f"robofdi.assets is not a folder on the file system ({folder!r}); install robofdi unzipped")
    return folder


#: Folder of the shipped MJCF models (same as :func:`assets_dir`, kept for compatibility).
ASSETS = assets_dir()


from robofdi.errors import RobofdiError  # noqa: E402
