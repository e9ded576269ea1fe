"""Entries of summary.json's ``reproduction`` list (ARCHITECTURE.md, "Metrics"): one checked number of a source."""
from __future__ import annotations

__all__ = ["reproduction_check"]


def reproduction_check(quantity: str, paper, ours, tolerance, passed, note: str = "") -> dict:
    """{"quantity", "paper", "ours", "tolerance", "pass"[, "note"]}: the paper's value (or claim), ours, the
    tolerance (None when the check is a claim, not a number) and whether it passed."""
    entry = {"quantity": quantity, "paper": paper, "ours": ours, "tolerance": tolerance, "pass": bool(passed)}
    if note:
        entry["note"] = note
    return entry
