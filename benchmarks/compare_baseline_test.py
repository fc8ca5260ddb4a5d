#!/usr/bin/env python3
"""benchmarks/compare_baseline.py against made-up runs: a figure 30 % slower is
named (and fails --strict), 20 % slower is not, units are converted, only
medians of aggregates count, manual-time benchmarks compare wall time."""

import json
import os
import subprocess
import sys
import tempfile
import unittest

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "compare_baseline.py")


def run_json(benchmarks):
    return {"context": {"host_name": "test", "num_cpus": 2, "mhz_per_cpu": 1000,
                        "date": "2026-11-27"},
            "benchmarks": benchmarks}


def median(name, cpu, real, unit):
    return {"name": name + "_median", "run_name": name, "run_type": "aggregate",
            "aggregate_name": "median", "cpu_time": cpu, "real_time": real, "time_unit": unit}


class CompareBaseline(unittest.TestCase):
    def compare(self, base, now, *flags):
        with tempfile.TemporaryDirectory() as d:
            os.mkdir(os.path.join(d, "baseline"))
            with open(os.path.join(d, "baseline", "prog.json"), "w") as f:
                json.dump(run_json(base), f)
            with open(os.path.join(d, "prog.json"), "w") as f:
                json.dump(run_json(now), f)
            return subprocess.run([sys.executable, SCRIPT, os.path.join(d, "prog.json"),
                                   "--baseline-dir", os.path.join(d, "baseline"), *flags],
                                  capture_output=True, text=True)

    def test_names_a_figure_that_slipped(self):
        base = [median("BM_Fast", 1000.0, 1000.0, "us"), median("BM_Ok", 5.0, 5.0, "ms"),
                {"name": "BM_Fast_mean", "run_name": "BM_Fast", "run_type": "aggregate",
                 "aggregate_name": "mean", "cpu_time": 1.0, "real_time": 1.0, "time_unit": "us"}]
        now = [median("BM_Fast", 1.3, 1.3, "ms"), median("BM_Ok", 6000.0, 6000.0, "us")]
        r = self.compare(base, now)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("SLOWER by 30 %", r.stdout)
        self.assertIn("1 figure(s) more than 25 % slower than their baseline: prog BM_Fast", r.stdout)
        self.assertNotIn("prog BM_Ok", r.stdout.splitlines()[-1])
        self.assertEqual(self.compare(base, now, "--strict").returncode, 1)

    def test_manual_time_compares_wall_time_and_reports_new_and_missing(self):
        base = [median("BM_Dds/manual_time", 1.0, 10.0, "us"), median("BM_Gone", 1.0, 1.0, "us")]
        now = [median("BM_Dds/manual_time", 100.0, 11.0, "us"), median("BM_New", 2.0, 2.0, "us")]
        r = self.compare(base, now, "--strict")
        self.assertEqual(r.returncode, 0, r.stdout)
        self.assertIn("no figure more than 25 % slower", r.stdout)
        self.assertIn("BM_Gone", r.stdout)
        self.assertIn("(new: 2 us, no baseline)", r.stdout)


if __name__ == "__main__":
    unittest.main()
