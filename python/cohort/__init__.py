"""Read a Cohort run directory from Python.

``cohort.load(run_dir)`` gives the run's telemetry, one ``pyarrow.Table`` per process
(``plant``, ``agent-1`` ...), each column's unit, the summary (``summary.json``) and the fault
timeline (``timeline.json``, empty when the run had none). Telemetry is read from
``telemetry/<process>.parquet`` (the default format), or from ``<process>.csv`` when the run was
launched with ``--telemetry csv`` (then the units come from the column-name suffixes, as the
Rust side derives them).

``cohort.load_campaign(dir)`` reads a Monte Carlo campaign's ``campaign.parquet`` (a row per
case: its drawn values, metrics and verdict lines; see ``Campaign``).
"""

from .campaign import Campaign, load_campaign
from .run import Run, load, unit_from_name

__all__ = ["Campaign", "Run", "load", "load_campaign", "unit_from_name"]
