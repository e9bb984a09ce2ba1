"""The loader reads a real run: a 20 s launch of the runtime's smoke scenario
(topologies/consensus-ring.toml; the release binaries must be built), in Parquet and in CSV.

    python3 -m unittest discover -s python/tests      (from the repository root)
"""

import os
import shutil
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "python"))

import cohort  # noqa: E402

ORCHESTRATOR = os.path.join(ROOT, "target", "release", "orchestrator")
SCENARIO = "topologies/consensus-ring.toml"
STEPS = 2000  # 20 s at dt = 0.01 s
AGENTS = 6


def launch(out, *extra):
    cmd = [ORCHESTRATOR, "launch", SCENARIO, "--duration", "20", "--out", out, "--no-plots", *extra]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} exited {done.returncode}:\n{done.stdout}\n{done.stderr}")


def same_bits(test, a, b, what):
    test.assertEqual(a.column_names, b.column_names, what)
    for name in a.column_names:
        # Bit for bit: compare the numbers' bytes (NaN included).
        test.assertEqual(
            a.column(name).combine_chunks().buffers()[1].to_pybytes(),
            b.column(name).combine_chunks().buffers()[1].to_pybytes(),
            f"{what}.{name}",
        )


@unittest.skipUnless(os.path.exists(ORCHESTRATOR), f"{ORCHESTRATOR} not built (cargo build --release --workspace --bins)")
class LoadRun(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="cohort-py-")
        cls.parquet = os.path.join(cls.tmp, "parquet")
        cls.csv = os.path.join(cls.tmp, "csv")
        launch(cls.parquet)
        launch(cls.csv, "--telemetry", "csv")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_tables_columns_units_and_rows(self):
        run = cohort.load(self.parquet)
        self.assertEqual(run.processes, ["plant"] + [f"agent-{i}" for i in range(1, AGENTS + 1)])
        plant = run["plant"]
        self.assertEqual(plant.num_rows, STEPS)
        self.assertEqual(plant.column_names[:3], ["k", "t_s", "formation_error_m"])
        self.assertEqual(plant.column("k").to_pylist(), list(range(STEPS)))
        self.assertEqual(run.unit("plant", "t_s"), "s")
        self.assertEqual(run.unit("plant", "formation_error_m"), "m")
        self.assertEqual(run.unit("plant", "a6_v_z_mps"), "m/s")
        self.assertEqual(run.unit("plant", "a1_u_x_mps2"), "m/s²")
        self.assertIsNone(run.unit("plant", "k"))
        for i in range(1, AGENTS + 1):
            self.assertEqual(run[f"agent-{i}"].num_rows, STEPS)
        self.assertEqual(run.summary["steps_completed"], STEPS)
        self.assertEqual(run.summary["status"], "ok")
        self.assertIsInstance(run.timeline, list)
        # The formation converged: the numbers are a run's, not zeros.
        err = run.column("plant", "formation_error_m")
        self.assertLess(err[-1], 0.5 * err[0])

    def test_csv_and_parquet_hold_the_same_numbers(self):
        pq_run, csv_run = cohort.load(self.parquet), cohort.load(self.csv)
        self.assertTrue(os.path.exists(os.path.join(self.csv, "telemetry", "plant.csv")))
        for p in pq_run.processes:
            same_bits(self, pq_run[p], csv_run[p], p)
            self.assertEqual(csv_run.units[p], pq_run.units[p], p)


if __name__ == "__main__":
    unittest.main()
