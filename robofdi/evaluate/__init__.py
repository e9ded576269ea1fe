"""Metrics from labelled run records: detection delay, false alarms, isolation, identification error; summary.json."""
from robofdi.evaluate.metrics import evaluate_diagnoser
from robofdi.evaluate.summary import results_table, summarize, write_summary

__all__ = ["evaluate_diagnoser", "summarize", "write_summary", "results_table"]
