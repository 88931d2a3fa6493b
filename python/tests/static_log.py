"""A small synthetic static log (one board on a chamber shelf), written as CSV, for the
tests that need a log on every machine."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def write_static_log(path: Path, rows: int = 6000, seed: int = 7) -> None:
    """Two ramps of ±35 °C about 25 °C at 2 °C/min, 1-s rows, three axes in g with a bias
    quadratic in temperature, a heating/cooling split and noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(rows, dtype=np.float64)
    period = 4200.0
    phase = (t % period) / period
    tri = np.where(phase < 0.5, 4.0 * phase - 1.0, 3.0 - 4.0 * phase)
    temp = 25.0 + 35.0 * tri + rng.normal(0.0, 0.02, rows)
    heating = np.gradient(temp) > 0
    d = temp - 25.0
    ax = 1e-3 + 2e-5 * d + 3e-7 * d * d + np.where(heating, 4e-5, -4e-5) + rng.normal(0, 5e-5, rows)
    ay = -2e-3 - 1e-5 * d + rng.normal(0, 5e-5, rows)
    az = 1.0 + 3e-5 * d - 2e-7 * d * d + rng.normal(0, 5e-5, rows)
    with open(path, "w") as f:
        f.write("time_s,temp_c,ax_g,ay_g,az_g\n")
        for row in zip(t, np.round(temp * 16.0) / 16.0, ax, ay, az):
            f.write(",".join(repr(float(x)) for x in row) + "\n")
