"""The campaign reader reads a real campaign: three cases of fig1-fixed (1 s each) dispersed by
the system tests' fixture (tests/system/campaign/fig1-dispersions.toml); the release binaries
must be built.

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


@unittest.skipUnless(os.path.exists(ORCHESTRATOR), f"{ORCHESTRATOR} not built (cargo build --release --workspace --bins)")
class LoadCampaign(unittest.TestCase):
    def test_drawn_values_metrics_units_and_verdicts(self):
        tmp = tempfile.mkdtemp(prefix="cohort-py-campaign-")
        try:
            out = os.path.join(tmp, "c")
            cmd = [ORCHESTRATOR, "campaign", "topologies/fig1-fixed.toml", "--dispersions",
                   "tests/system/campaign/fig1-dispersions.toml", "--cases", "3", "--duration", "1",
                   "--no-plots", "--out", out]
            done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
            self.assertEqual(done.returncode, 0, done.stderr)
            c = cohort.load_campaign(out)
            self.assertEqual(len(c), 3)
            self.assertEqual(c.column("case"), [0, 1, 2])
            self.assertEqual(c.drawn, ["agents[0].offset_lvlh_m[0]", "agents[0].offset_lvlh_m[1]",
                                       "agents[0].offset_lvlh_m[2]", "agents[1].mass_kg", "algorithm.k1"])
            self.assertEqual(c.unit("agents[1].mass_kg"), "kg")
            self.assertTrue(all(1000.0 <= m <= 1200.0 for m in c.column("agents[1].mass_kg")))
            self.assertIn("servicer_1.dv_total_mps", c.metrics)
            self.assertEqual(c.unit("servicer_1.dv_total_mps"), "m/s")
            self.assertEqual(len(c.verdicts), 2)
            # A 1 s run cannot judge the paper's 200 s levels: every line n/a, no pass rate.
            self.assertIsNone(c.pass_rate())
            self.assertIn("[[dispersions]]", c.dispersions)
            with self.assertRaises(KeyError):
                c.column("no such column")
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    unittest.main()
