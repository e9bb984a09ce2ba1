"""The campaign reader: ``campaign.parquet`` of ``orchestrator campaign`` (docs/monte-carlo.md)."""

import json
import os
from typing import Dict, List, Optional

import pyarrow as pa
import pyarrow.parquet as pq

_FIXED = ("case", "seed", "status", "error", "verdict_overall")


class Campaign:
    """One campaign directory: ``table`` (a ``pyarrow.Table``, a row per case), ``drawn`` (the
    dispersed values' columns, by key path), ``metrics`` (the summary metrics' columns),
    ``verdicts`` (the verdict lines' names), ``units`` (column → unit or None), ``seed`` and
    ``dispersions`` (the TOML the values were drawn from)."""

    def __init__(self, directory: str):
        self.dir = os.fspath(directory)
        path = os.path.join(self.dir, "campaign.parquet")
        if not os.path.exists(path):
            raise FileNotFoundError(
                f"{path}: no campaign table (an interrupted campaign writes it once the same command finishes it)"
            )
        self.table: pa.Table = pq.read_table(path)
        meta = self.table.schema.metadata or {}
        self.drawn: List[str] = json.loads(meta.get(b"cohort.campaign.drawn", b"[]").decode("utf-8"))
        self.seed = int(meta.get(b"cohort.campaign.seed", b"0").decode("utf-8"))
        self.dispersions = meta.get(b"cohort.campaign.dispersions", b"").decode("utf-8")
        names = self.table.column_names
        self.verdicts: List[str] = [n[len("verdict: "):] for n in names if n.startswith("verdict: ")]
        self.metrics: List[str] = [
            n for n in names
            if n not in _FIXED and n not in self.drawn and not n.startswith(("verdict: ", "ours: "))
        ]
        self.units: Dict[str, Optional[str]] = {}
        for field in self.table.schema:
            m = field.metadata or {}
            self.units[field.name] = m[b"unit"].decode("utf-8") if b"unit" in m else None

    def __len__(self) -> int:
        return self.table.num_rows

    def column(self, name: str) -> list:
        """A column as a Python list (None where a case did not produce the value)."""
        if name not in self.table.column_names:
            raise KeyError(f"{name!r}: not a column of {self.dir}/campaign.parquet")
        return self.table.column(name).to_pylist()

    def unit(self, name: str) -> Optional[str]:
        return self.units.get(name)

    def pass_rate(self, line: Optional[str] = None) -> Optional[float]:
        """Passes over passes and fails of a verdict line (the overall verdict by default);
        None when no case judged it."""
        verdicts = self.column("verdict_overall" if line is None else f"verdict: {line}")
        judged = [v for v in verdicts if v in ("pass", "fail")]
        return sum(v == "pass" for v in judged) / len(judged) if judged else None

    def __repr__(self):
        return f"Campaign({self.dir!r}: {len(self)} cases, {len(self.drawn)} drawn, {len(self.metrics)} metrics)"


def load_campaign(directory) -> Campaign:
    """Read a campaign directory's table (see :class:`Campaign`)."""
    return Campaign(directory)
