"""Shared fixtures: the repository's paths, the `qfa-lab` binary the tests compare with,
and the real IMU log (found as the lab's own real-log test finds it)."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import List, Optional, Tuple

import pytest

REPO = Path(__file__).resolve().parents[2]

#: The reader flags the real (tofupilot) log needs, as in docs/lab.md.
REAL_LOG_READER = {
    "columns": "time=timestamp,temp=imu.temperature,ax=imu.acc.x,ay=imu.acc.y,az=imu.acc.z",
    "time_unit": "us",
    "accel_unit": "m/s2",
}
REAL_LOG_FLAGS = [
    "--columns",
    REAL_LOG_READER["columns"],
    "--time-unit",
    "us",
    "--accel-unit",
    "m/s2",
]


def _target_dir() -> Path:
    out = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=REPO,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return Path(json.loads(out)["target_directory"])


@pytest.fixture(scope="session")
def lab_bin() -> Path:
    """The `qfa-lab` CLI: `$QFA_LAB_BIN`, else built (debug, as `cargo test` leaves it)."""
    env = os.environ.get("QFA_LAB_BIN")
    if env:
        return Path(env)
    subprocess.run(["cargo", "build", "-q", "-p", "qfa-lab", "--bin", "qfa-lab"], cwd=REPO, check=True)
    return _target_dir() / "debug" / "qfa-lab"


def run_lab(lab_bin: Path, args: List[str], ok: bool = True) -> Tuple[int, str, str]:
    """Run the CLI; with `ok`, fail the test unless it exits 0."""
    p = subprocess.run([str(lab_bin), *args], capture_output=True, text=True)
    if ok:
        assert p.returncode == 0, f"qfa-lab {args} failed:\n{p.stderr}"
    return p.returncode, p.stdout, p.stderr


def cli_error(stderr: str) -> str:
    """The message the CLI printed after `error: `."""
    assert "error: " in stderr, stderr
    return stderr[stderr.index("error: ") + len("error: ") :].strip()


@pytest.fixture(scope="session")
def real_log() -> Optional[Path]:
    """The real tofupilot IMU log: `$QFA_REAL_IMU_LOG`, else beside the repository in
    shared/real/. Missing: a loud SKIPPED line, and with CI=true a failure."""
    env = os.environ.get("QFA_REAL_IMU_LOG")
    p = Path(env) if env else REPO.parent / "shared" / "real" / "tofupilot-imu-thermal-cycle" / "imu_raw_data.tsv"
    if p.is_file():
        return p
    msg = (
        f"SKIPPED: real IMU log not found at {p} (set QFA_REAL_IMU_LOG): fetch it from GitHub tofupilot/examples, "
        "templates/imu_thermal_calibration/data/imu_raw_data.csv at commit fc190f7cd507ec6b53fba4c4368b1a2a0a8e5125"
    )
    print(msg)
    if os.environ.get("CI") == "true":
        pytest.fail(msg)
    pytest.skip(msg)
    return None
