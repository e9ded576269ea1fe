"""Lockstep diagnosis: the diagnoses of many runs of one system stepped together, sample by sample.

A campaign worker simulates a batch of runs (:meth:`robofdi.loop.ClosedLoop.run` with ``diagnose=False``), then
diagnoses them in lockstep (:func:`diagnose_lockstep`): every diagnoser with a batch form
(:func:`robofdi.lockstep.observers.batch_form`: the arm's book schemes, its momentum observer and its consistency
scheme) updates all runs of a sample in one call, with the nominal models' evaluations of the sample made once for
all of them (:class:`robofdi.lockstep.evaluations.BatchEvaluations`); the decisions are tested for all runs at once
and each run's own decision steps only where it alarms. Every run's record and results row are the ones it gives
alone, bit for bit.
"""
from robofdi.lockstep.engine import diagnose_lockstep, diagnoser_view

__all__ = ["diagnose_lockstep", "diagnoser_view"]
