"""Campaigns: many seeded fault scenarios on any system, on a local process pool or a Dask cluster, and the
metrics that judge a diagnoser over them.

    from robofdi import campaign
    result = campaign.run_campaign("arm", "runs/arm-campaign", workers=2)   # a spec file, shipped name or dict
    result.table                     # pandas: one row per run × diagnoser × fault
    result.metrics()["momentum"]["false_alarm_rate"]
    again = campaign.load("runs/arm-campaign")

Rooms: ``spec`` (TOML → validated dataclasses), ``runs`` (one run: seed, draw, rows), ``backends`` (local pool,
Dask), ``engine`` (calibrate, run, journal, resume), ``metrics`` (false-alarm CI, detection, isolation, delay,
detectability, diagnosers at equal false alarms), ``results`` (files).
The systems a campaign runs are :mod:`robofdi.systems` (the :class:`~robofdi.protocols.System` protocol); this
package knows none of them.
"""
from robofdi.campaign.engine import CampaignInterrupted, run_campaign
from robofdi.campaign.metrics import analyse, at_equal_false_alarms, clopper_pearson, detection_curve
from robofdi.campaign.results import CampaignResult, load
from robofdi.campaign.runs import COLUMNS, UNITS, run_seed
from robofdi.campaign.spec import CampaignSpec, FaultDistribution, load_spec, parse_spec, shipped_specs
from robofdi.protocols import Mission, System, TargetLimit
from robofdi.systems import SYSTEMS, get_system, register_system

__all__ = ["run_campaign", "CampaignInterrupted", "load", "CampaignResult", "analyse", "at_equal_false_alarms",
           "clopper_pearson", "detection_curve", "load_spec", "parse_spec", "CampaignSpec", "FaultDistribution", "shipped_specs",
           "System", "register_system", "get_system", "SYSTEMS", "Mission", "TargetLimit", "COLUMNS", "UNITS",
           "run_seed"]
