"""Lockstep diagnosis: the diagnoses of many runs of one system stepped together, sample by sample.

A campaign worker simulates a batch of runs (:meth:`robofdi.loop.ClosedLoop.run` with ``diagnose=False``), then
diagnoses them in lockstep (:func:`diagnose_lockstep`): every diagnoser with a batch form
(:func:`robofdi.lockstep.observers.batch_form`: the arm's book schemes and its momentum observer) updates all runs
of a sample in one call, with the nominal models' evaluations of the sample made once for all of them
(:class:`robofdi.lockstep.evaluations.BatchEvaluations`); each run keeps its own decision, identification and
trace. Every run's record and results row are the ones it gives alone, bit for bit.
"""
from robofdi.lockstep.engine import diagnose_lockstep, diagnoser_view

__all__ = ["diagnose_lockstep", "diagnoser_view"]
