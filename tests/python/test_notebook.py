"""The example notebook (clients/python/examples/analyse_a_leg.ipynb) runs
headless (jupyter nbconvert --execute) against a real fesbench-server with a
leg's recordings, as an analyst would run it, and draws its figures.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import unittest

from server import Server

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
NOTEBOOK = os.path.join(ROOT, "clients", "python", "examples", "analyse_a_leg.ipynb")
FIGURES = ("curves.png", "prediction.png", "comparison.png", "export_trial.png")


class NotebookTest(unittest.TestCase):
    def test_the_example_notebook_runs_and_draws_its_figures(self):
        out = os.environ.get("FESBENCH_NOTEBOOK_OUT") or tempfile.mkdtemp(prefix="fesbench-nb-")
        shutil.rmtree(out, ignore_errors=True)
        os.makedirs(os.path.join(out, "figures"))
        server = Server(os.environ["FESBENCH_SERVER_BINARY"])
        try:
            server.leg_with_recordings("NB-01", rapid_runs=2,
                                       fresh=("prediction_random_binary", "prediction_step"))
            token_file = os.path.join(out, "analyst.token")
            with open(token_file, "w") as f:
                f.write(server.user_token("nb-analyst", "analyst") + "\n")
            env = dict(os.environ, FESBENCH_URL=server.url, FESBENCH_TOKEN_FILE=token_file,
                       FESBENCH_FIGURES=os.path.join(out, "figures"))
            run = subprocess.run(
                ["/usr/bin/jupyter-nbconvert", "--to", "notebook", "--execute",
                 "--ExecutePreprocessor.timeout=60", "--output-dir", out, NOTEBOOK],
                env=env, capture_output=True, text=True, timeout=100)
            self.assertEqual(run.returncode, 0, run.stderr[-4000:])
        finally:
            self.assertEqual(server.stop(), 0)
        with open(os.path.join(out, os.path.basename(NOTEBOOK))) as f:
            executed = json.load(f)
        outputs = [o for c in executed["cells"] if c["cell_type"] == "code" for o in c["outputs"]]
        self.assertFalse([o for o in outputs if o["output_type"] == "error"])
        images = [o for o in outputs if "image/png" in o.get("data", {})]
        self.assertGreaterEqual(len(images), len(FIGURES), "every figure is shown in the notebook")
        text = json.dumps(outputs)
        self.assertIn("p =", text, "the comparison over several trials has its t-test")
        for name in FIGURES:
            path = os.path.join(out, "figures", name)
            self.assertTrue(os.path.exists(path), name)
            self.assertGreater(os.path.getsize(path), 5000, f"{name} has something drawn")


if __name__ == "__main__":
    unittest.main()
