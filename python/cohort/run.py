"""The run directory reader (see the package docs)."""

import json
import os
from typing import Dict, List, Optional

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

# The unit-suffix table of runtime/src/units.rs, used only for CSV telemetry (a Parquet file
# carries each column's unit in its schema). The longest suffix that matches wins.
_UNITS = {
    "n_m_s": "N·m·s", "kg_m2": "kg·m²", "rad_s2": "rad/s²", "rad_s": "rad/s", "deg_s": "deg/s",
    "n_m": "N·m", "n_s": "N·s", "m_s2": "m/s²", "mps2": "m/s²", "kmps2": "km/s²", "mps": "m/s",
    "kmps": "km/s", "radps2": "rad/s²", "radps": "rad/s", "degps": "deg/s", "au": "AU", "km": "km",
    "mm": "mm", "um": "µm", "m": "m", "ms": "ms", "us": "µs", "ns": "ns", "s": "s", "rad": "rad",
    "deg": "deg", "n": "N", "kg": "kg", "j": "J", "hz": "Hz", "pct": "%",
}


def unit_from_name(name: str) -> Optional[str]:
    """The unit a column name's suffix stands for (``omega_x_rad_s`` → ``rad/s``), if any."""
    best = None
    for suffix, label in _UNITS.items():
        if len(name) > len(suffix) + 1 and name.endswith("_" + suffix):
            if best is None or len(suffix) > len(best[0]):
                best = (suffix, label)
    return best[1] if best else None


def _read_table(path: str) -> pa.Table:
    if path.endswith(".parquet"):
        return pq.read_table(path)
    # k as an unsigned count, every other column a double (as written).
    with open(path, encoding="utf-8") as f:
        names = f.readline().strip().split(",")
    types = {n: (pa.uint64() if i == 0 else pa.float64()) for i, n in enumerate(names)}
    return pacsv.read_csv(path, convert_options=pacsv.ConvertOptions(column_types=types))


def _units_of(table: pa.Table, from_schema: bool) -> Dict[str, Optional[str]]:
    units = {}
    for field in table.schema:
        unit = None
        if from_schema and field.metadata and b"unit" in field.metadata:
            unit = field.metadata[b"unit"].decode("utf-8")
        elif not from_schema:
            unit = unit_from_name(field.name)
        units[field.name] = unit
    return units


class Run:
    """One run directory: ``tables`` (process → ``pyarrow.Table``), ``units`` (process → column →
    unit or None), ``summary`` (dict), ``timeline`` (list of events)."""

    def __init__(self, run_dir: str):
        self.run_dir = os.fspath(run_dir)
        tel = os.path.join(self.run_dir, "telemetry")
        if not os.path.isdir(tel):
            raise FileNotFoundError(f"{tel}: no telemetry directory (is {self.run_dir} a run directory?)")
        self.tables: Dict[str, pa.Table] = {}
        self.units: Dict[str, Dict[str, Optional[str]]] = {}
        for name in sorted(os.listdir(tel)):
            stem, ext = os.path.splitext(name)
            if ext not in (".parquet", ".csv") or name.startswith("."):
                continue
            if ext == ".csv" and os.path.exists(os.path.join(tel, stem + ".parquet")):
                continue  # the Parquet file is the run's
            try:
                table = _read_table(os.path.join(tel, name))
            except (pa.ArrowInvalid, OSError) as e:
                raise ValueError(f"{os.path.join(tel, name)}: {e}") from e
            self.tables[stem] = table
            self.units[stem] = _units_of(table, ext == ".parquet")
        self.summary = self._json("summary.json", {})
        self.timeline = self._json("timeline.json", [])

    def _json(self, name: str, default):
        path = os.path.join(self.run_dir, name)
        if not os.path.exists(path):
            return default
        with open(path, encoding="utf-8") as f:
            return json.load(f)

    @property
    def processes(self) -> List[str]:
        """The processes with telemetry: ``plant`` first, then the agents by id."""
        def rank(p):
            if p == "plant":
                return (0, 0, p)
            if p.startswith("agent-") and p[6:].isdigit():
                return (2, int(p[6:]), p)
            return (1, 0, p)
        return sorted(self.tables, key=rank)

    def __getitem__(self, process: str) -> pa.Table:
        return self.tables[process]

    def unit(self, process: str, column: str) -> Optional[str]:
        """The unit of ``column`` of ``process`` (None: the name carries none)."""
        return self.units[process][column]

    def column(self, process: str, column: str) -> List[float]:
        """One column as a Python list."""
        return self.tables[process].column(column).to_pylist()

    def __repr__(self):
        rows = {p: self.tables[p].num_rows for p in self.processes}
        return f"Run({self.run_dir!r}, rows={rows})"


def load(run_dir) -> Run:
    """Read a run directory (see :class:`Run`)."""
    return Run(run_dir)
