"""Compensation speed from Python versus the same Rust function on the same rows.

Run from the repository root, after ``pip install ./python``::

    python python/bench/bench_compensate.py            # the Python side only
    python python/bench/bench_compensate.py --rust     # also the Rust side, and the ratio

Prints ``key=value`` lines: ``python_best_s`` (best of five runs after a warm-up of
``qfa_thermal.compensate`` on 1 000 000 three-axis rows given as numpy columns), with
``--rust`` the Rust run's lines (``cargo test --release -p qfa-lab --test compensate_bench
-- --ignored --nocapture``: ``compensate_samples`` on the same rows, bit for bit) and
``ratio`` = python_best_s / rust_best_s. Both print a checksum of the outputs: equal
checksums show the same rows and table went through the same code.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Dict, Tuple

import numpy as np
import qfa_thermal as q

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
ROWS = 1_000_000
#: Triangle period of the temperature, rows (as lab/tests/compensate_bench.rs).
PERIOD = 20_000


def columns() -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Rust benchmark's columns, computed with the same f64 operations in the same order."""
    i = np.arange(ROWS, dtype=np.int64)
    time_s = i.astype(np.float64) * 0.5
    phase = (i % PERIOD).astype(np.float64) / float(PERIOD)
    tri = np.where(phase < 0.5, 4.0 * phase - 1.0, 3.0 - 4.0 * phase)
    temp_c = 25.0 + 35.0 * tri
    ax = 1e-3 + 2e-5 * (temp_c - 25.0)
    ay = np.full(ROWS, -2e-3)
    az = 1.0 + 3e-5 * (temp_c - 25.0)
    return time_s, temp_c, np.column_stack([ax, ay, az])


def python_side() -> Dict[str, str]:
    table = q.Table.from_toml((HERE / "bench_table.toml").read_text())
    time_s, temp_c, accel = columns()
    times = []
    checksum = 0.0
    for run in range(6):
        t = time.perf_counter()
        out = q.compensate(table, time_s=time_s, temp_c=temp_c, accel=accel)
        s = time.perf_counter() - t
        # Summed in the Rust side's order (axis after axis, row after row).
        checksum = float(sum(np.concatenate([out.columns[a] for a in ("ax", "ay", "az")]).tolist()))
        if run > 0:
            times.append(s)
    times.sort()
    return {
        "rows": str(ROWS),
        "axes": "3",
        "python_best_s": f"{times[0]:.4f}",
        "python_median_s": f"{times[len(times) // 2]:.4f}",
        "python_checksum": f"{checksum:.9e}",
    }


def rust_side() -> Dict[str, str]:
    cmd = ["cargo", "test", "--release", "-p", "qfa-lab", "--test", "compensate_bench", "--", "--ignored", "--nocapture"]
    out = subprocess.run(cmd, cwd=REPO, check=True, capture_output=True, text=True).stdout
    found = dict(re.findall(r"^(\w+)=(\S+)$", out, re.M))
    return {"rust_best_s": found["rust_best_s"], "rust_median_s": found["rust_median_s"], "rust_checksum": found["checksum"]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rust", action="store_true", help="also run the Rust benchmark and print the ratio")
    args = parser.parse_args()
    result = python_side()
    if args.rust:
        result.update(rust_side())
        result["ratio"] = f"{float(result['python_best_s']) / float(result['rust_best_s']):.3f}"
        same = float(result["python_checksum"]) == float(result["rust_checksum"])
        result["same_checksum"] = str(same).lower()
    for k, v in result.items():
        print(f"{k}={v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
