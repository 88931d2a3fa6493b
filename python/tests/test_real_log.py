"""The real IMU log from Python gives the CLI's calibration, byte for byte and figure for
figure, and the CLI's compensated CSV."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import qfa_thermal as q

import pytest

from conftest import REAL_LOG_FLAGS, REAL_LOG_READER, run_lab


@pytest.fixture(scope="module")
def cli_calibration(real_log: Path, lab_bin: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`qfa-lab calibrate` on the real log, once for the module: its output directory."""
    out = tmp_path_factory.mktemp("real") / "cal"
    run_lab(lab_bin, ["calibrate", "--log", str(real_log), "--out", str(out), *REAL_LOG_FLAGS])
    return out


def test_calibrate_matches_the_cli_exactly(real_log: Path, cli_calibration: Path) -> None:
    out = cli_calibration
    cli = json.loads((out / "report.json").read_text())

    table = q.calibrate(real_log, **REAL_LOG_READER)
    report = table.report()
    # The CLI's report.json opens with its verdict (which names the files the CLI wrote and
    # the limits it checked); the rest is the report, which must be the same.
    verdict = cli.pop("verdict")
    assert report == cli, "the report differs from the CLI's"
    expected = [(e["axis"], e["value"]) for e in verdict["expect"]]
    assert expected == [(a["axis"], a["ours"]["rms_mg"]) for a in report["axes"]], "the verdict's figures are the report's"
    assert report["rows"] == 8399
    for axis in report["axes"]:
        ours, cubic = axis["ours"]["rms_mg"], axis["cubic"]["rms_mg"]
        print(f"{axis['axis']}: held out ours {ours:.4f} mg, cubic {cubic:.4f} mg, structure {axis['structure']}")
        assert 0 < ours < cubic
    assert table.to_bytes() == (out / "table.bin").read_bytes()
    assert table.to_toml() == (out / "table.toml").read_text()
    # report.md: the CLI's is its title, the verdict, then the same report.
    title, rest = (out / "report.md").read_text().split("\n", 1)
    assert rest.lstrip().startswith("## Verdict\n")
    assert table.report_markdown() == title + "\n\n" + rest.split("\n\n", 1)[1].split("\n\n", 1)[1]
    files, notes = table.exports()
    for name, text in files.items():
        assert text == (out / name).read_text(), name
    assert "px4_tc.params" not in files and notes, notes


def test_compensate_matches_the_cli_csv(real_log: Path, lab_bin: Path, cli_calibration: Path, tmp_path: Path) -> None:
    out = cli_calibration
    comp_csv = tmp_path / "comp.csv"
    run_lab(
        lab_bin,
        ["compensate", "--log", str(real_log), "--table", str(out / "table.bin"), "--out", str(comp_csv), *REAL_LOG_FLAGS],
    )
    log = q.read_log(real_log, **REAL_LOG_READER)
    got = q.compensate(q.Table.load(out / "table.bin"), log)
    assert_same_as_cli_csv(got, comp_csv)

    # The same rows as plain numpy columns (no reader in between) give the same arrays.
    cols = got.columns
    again = q.compensate(
        q.Table.load(out / "table.bin"),
        time_s=cols["time_s"],
        temp_c=cols["temp_c"],
        accel=np.column_stack([log.columns[a] for a in log.axes]),
    )
    for name in log.axes:
        assert np.array_equal(again.columns[name], cols[name])
    assert np.array_equal(again.status, got.status)


def assert_same_as_cli_csv(got: q.Compensated, path: Path) -> None:
    """Every field of the CLI's static `compensate` CSV, formatted as the CLI formats it."""
    with open(path, newline="") as f:
        # The header comment lines (`# `: the status-flag counts) come before the CSV.
        rows = list(csv.reader(line for line in f if not line.startswith("#")))
    head, body = rows[0], rows[1:]
    axes = head[2:-1]
    assert head == ["time_s", "temp_c", *axes, "status"]
    assert len(body) == len(got.status)
    text = got.status_text()
    for i, row in enumerate(body):
        want = [f"{got.columns['time_s'][i]:.6f}", f"{got.columns['temp_c'][i]:.4f}"]
        want += [f"{got.columns[a][i]:.9f}" for a in axes]
        want.append(text[i])
        assert row == want, f"row {i + 2}: CLI {row} vs Python {want}"
