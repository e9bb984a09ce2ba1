"""Read a Cohort run directory from Python.

``cohort.load(run_dir)`` gives the run's telemetry, one ``pyarrow.Table`` per process
(``plant``, ``agent-1`` ...), each column's unit, the summary (``summary.json``) and the fault
timeline (``timeline.json``, empty when the run had none). Telemetry is read from
``telemetry/<process>.parquet`` (the default format), or from ``<process>.csv`` when the run was
launched with ``--telemetry csv`` (then the units come from the column-name suffixes, as the
Rust side derives them).
"""

from .run import Run, load, unit_from_name

__all__ = ["Run", "load", "unit_from_name"]
