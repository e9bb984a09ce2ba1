"""The loader reads a real run: a 20 s fig1 launch (the release binaries must be built), Parquet
and CSV, and the example redraws Fig. 4 from it.

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
STEPS = 2000  # 20 s at dt = 0.01 s


def launch(out, *extra):
    cmd = [ORCHESTRATOR, "launch", "topologies/fig1.toml", "--duration", "20", "--out", out, "--no-plots", *extra]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} exited {done.returncode}:\n{done.stdout}\n{done.stderr}")


@unittest.skipUnless(os.path.exists(ORCHESTRATOR), f"{ORCHESTRATOR} not built (cargo build --release --workspace --bins)")
class LoadFig1(unittest.TestCase):
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
        self.assertEqual(run.processes, ["plant"] + [f"agent-{i}" for i in range(1, 7)])
        plant = run["plant"]
        self.assertEqual(plant.num_rows, STEPS)
        self.assertEqual(plant.column_names[:3], ["k", "t_s", "b0_r_eci_x_m"])
        self.assertIn("a6_e_norm_m", plant.column_names)
        self.assertEqual(run.unit("plant", "a6_e_norm_m"), "m")
        self.assertEqual(plant.column("k").to_pylist(), list(range(STEPS)))
        self.assertEqual(run.unit("plant", "t_s"), "s")
        self.assertEqual(run.unit("plant", "a1_zeta_x_mps"), "m/s")
        self.assertEqual(run.unit("plant", "a1_u_x_mps2"), "m/s²")
        self.assertIsNone(run.unit("plant", "k"))
        for i in range(1, 7):
            self.assertEqual(run[f"agent-{i}"].num_rows, STEPS)
        self.assertEqual(run.summary["steps_completed"], STEPS)
        self.assertEqual(run.summary["status"], "ok")
        self.assertIsInstance(run.timeline, list)

    def test_csv_and_parquet_hold_the_same_numbers(self):
        pq_run, csv_run = cohort.load(self.parquet), cohort.load(self.csv)
        self.assertTrue(os.path.exists(os.path.join(self.csv, "telemetry", "plant.csv")))
        for p in pq_run.processes:
            a, b = pq_run[p], csv_run[p]
            self.assertEqual(a.column_names, b.column_names, p)
            self.assertEqual(csv_run.units[p], pq_run.units[p], p)
            for name in a.column_names:
                # Bit for bit: compare the doubles' bytes (NaN included).
                self.assertEqual(
                    a.column(name).combine_chunks().buffers()[1].to_pybytes(),
                    b.column(name).combine_chunks().buffers()[1].to_pybytes(),
                    f"{p}.{name}",
                )

    def test_the_example_redraws_fig4(self):
        out = os.path.join(self.tmp, "fig4.png")
        example = os.path.join(ROOT, "python", "examples", "fig4.py")
        env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "python"))
        done = subprocess.run([sys.executable, example, self.parquet, out], capture_output=True, text=True, env=env)
        self.assertEqual(done.returncode, 0, done.stderr)
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            self.assertIn("matplotlib is not installed", done.stdout)
            self.skipTest("matplotlib is not installed: the example drew nothing")
        with open(out, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        self.assertGreater(os.path.getsize(out), 10_000)


if __name__ == "__main__":
    unittest.main()
