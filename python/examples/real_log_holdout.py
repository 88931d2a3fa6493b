"""The real IMU log's held-out table from Python, and a plot of it when matplotlib is there.

The log is the public tofupilot IMU thermal-cycle log (docs/lab.md, "Real data"): GitHub
``tofupilot/examples``, ``templates/imu_thermal_calibration/data/imu_raw_data.csv`` at
commit fc190f7cd507ec6b53fba4c4368b1a2a0a8e5125. Fetch it, then::

    pip install ./python matplotlib
    python python/examples/real_log_holdout.py imu_raw_data.csv [--plot holdout.png]

Prints the held-out bias RMS (mg) of every model on every axis, the table of
docs/measurements.md ("Real data"), from ``qfa_thermal.calibrate``: the lab's own
calibration, so the figures are the CLI's to the last digit.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, Dict, List

import numpy as np
import qfa_thermal as q

#: The reader flags this log needs (a tab-separated file with µs timestamps and m/s²).
READER = {
    "columns": "time=timestamp,temp=imu.temperature,ax=imu.acc.x,ay=imu.acc.y,az=imu.acc.z",
    "time_unit": "us",
    "accel_unit": "m/s2",
}
#: The report's models, in the table's column order, with their headings.
MODELS = [
    ("ours", "ours"),
    ("cubic", "PX4 / tofupilot cubic"),
    ("ardupilot", "ArduPilot TCAL"),
    ("simple", "paper simple"),
    ("none", "none"),
]


def held_out_table(report: Dict[str, Any]) -> List[str]:
    """The held-out RMS table (markdown), one row per axis."""
    lines = ["| axis | " + " | ".join(h for _, h in MODELS) + " | our structure (held-out fit) |", "|---" * (len(MODELS) + 2) + "|"]
    for axis in report["axes"]:
        cells = [f"{axis[key]['rms_mg']:.2f}" for key, _ in MODELS]
        lines.append(f"| {axis['axis'][1]} | " + " | ".join(cells) + f" | {', '.join(axis['heldout_structures'])} |")
    return lines


def plot(report: Dict[str, Any], log: q.Log, table: q.Table, path: str) -> None:
    """Held-out RMS per model and axis, and the compensated last leg, into ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    comp = q.compensate(table, log)
    first_heldout = report["holdout"]["folds"][0]["heldout_rows"][0] - 1
    fig, (bars, trace) = plt.subplots(1, 2, figsize=(12, 4.5))
    width = 0.8 / len(MODELS)
    x = np.arange(len(report["axes"]))
    for k, (key, heading) in enumerate(MODELS):
        bars.bar(x + k * width, [a[key]["rms_mg"] for a in report["axes"]], width, label=heading)
    bars.set_xticks(x + 0.4 - width / 2, [a["axis"] for a in report["axes"]])
    bars.set_ylabel("held-out bias RMS, mg")
    bars.set_title("Held out: the last cooling leg")
    bars.legend(fontsize=8)
    t_min = comp.columns["time_s"][first_heldout:] / 60.0
    for axis in report["axes"]:
        name = axis["axis"]
        raw = (log.columns[name][first_heldout:] - axis["reference_g"]) * 1e3
        out = (comp.columns[name][first_heldout:] - axis["reference_g"]) * 1e3
        line = trace.plot(t_min, raw, alpha=0.35, lw=0.8)[0]
        trace.plot(t_min, out, color=line.get_color(), lw=1.0, label=f"{name}: raw (faint) / table.bin")
    trace.set_xlabel("time, min")
    trace.set_ylabel("a − reference, mg")
    trace.set_title("Last leg, table.bin (fitted on every row: in-sample here)")
    trace.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main() -> int:
    parser = argparse.ArgumentParser(description="Held-out table of the real IMU log")
    parser.add_argument("log", help="the tofupilot imu_raw_data file")
    parser.add_argument("--plot", default="real_log_holdout.png", help="PNG to write when matplotlib is installed")
    args = parser.parse_args()
    log = q.read_log(args.log, **READER)
    print(f"{log.rows} rows; {log.reader['skipped_text']}")
    table = q.calibrate(log)
    report = table.report()
    print("\n".join(held_out_table(report)))
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("matplotlib is not installed: no plot (pip install matplotlib)")
        return 0
    plot(report, log, table, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
