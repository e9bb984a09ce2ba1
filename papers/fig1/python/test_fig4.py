"""The fig1 example redraws Fig. 4 from a real run: a 20 s launch of topologies/fig1.toml (the
release binaries must be built), read with the generic loader (python/).

    python3 -m unittest discover -s papers/fig1/python      (from the repository root)
"""

import os
import shutil
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
sys.path.insert(0, os.path.join(ROOT, "python"))

import cohort  # noqa: E402

ORCHESTRATOR = os.path.join(ROOT, "target", "release", "orchestrator")
STEPS = 2000  # 20 s at dt = 0.01 s


@unittest.skipUnless(os.path.exists(ORCHESTRATOR), f"{ORCHESTRATOR} not built (cargo build --release --workspace --bins)")
class Fig4(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="cohort-py-fig1-")
        cls.run_dir = os.path.join(cls.tmp, "run")
        cmd = [ORCHESTRATOR, "launch", "topologies/fig1.toml", "--duration", "20", "--out", cls.run_dir, "--no-plots"]
        done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
        if done.returncode != 0:
            raise AssertionError(f"{' '.join(cmd)} exited {done.returncode}:\n{done.stdout}\n{done.stderr}")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_the_plant_has_the_fig4_columns_with_units(self):
        run = cohort.load(self.run_dir)
        self.assertEqual(run.processes, ["plant"] + [f"agent-{i}" for i in range(1, 7)])
        plant = run["plant"]
        self.assertEqual(plant.num_rows, STEPS)
        self.assertEqual(plant.column_names[:3], ["k", "t_s", "b0_r_eci_x_m"])
        self.assertEqual(run.unit("plant", "a6_e_norm_m"), "m")
        self.assertEqual(run.unit("plant", "a1_zeta_x_mps"), "m/s")

    def test_the_example_redraws_fig4(self):
        out = os.path.join(self.tmp, "fig4.png")
        example = os.path.join(HERE, "fig4.py")
        env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "python"))
        done = subprocess.run([sys.executable, example, self.run_dir, out], capture_output=True, text=True, env=env)
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
