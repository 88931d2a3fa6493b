"""Calibration and compensation of a synthetic static log from Python give the CLI's
table bytes and compensated CSV, on every machine (no real log needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import qfa_thermal as q

from conftest import run_lab
from static_log import write_static_log
from test_real_log import assert_same_as_cli_csv


@pytest.fixture(scope="module")
def static_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("static") / "board.csv"
    write_static_log(p)
    return p


def test_static_calibrate_and_compensate_match_the_cli(static_log: Path, lab_bin: Path, tmp_path: Path) -> None:
    out = tmp_path / "cal"
    run_lab(lab_bin, ["calibrate", "--log", str(static_log), "--out", str(out)])
    table = q.calibrate(static_log)
    assert table.input == "samples" and table.axes == 3
    assert table.to_bytes() == (out / "table.bin").read_bytes()
    report = table.report()
    assert report["axes"][0]["ours"]["rms_mg"] > 0

    comp_csv = tmp_path / "comp.csv"
    run_lab(lab_bin, ["compensate", "--log", str(static_log), "--table", str(out / "table.bin"), "--out", str(comp_csv)])
    got = q.compensate(table, static_log)
    assert got.status.dtype == np.uint16
    assert_same_as_cli_csv(got, comp_csv)
    # The first row has a reading but no rate yet: compensated, and not refused. Its only
    # possible flag is MODEL_SETTLING: this log's x axis has heating and cooling branches,
    # and before the first decisive rate the firmware does not know which is in force.
    assert got.status_text()[0] in ("ok", "MODEL_SETTLING")
    assert got.status_text().count("ok") > len(got.status_text()) // 2

    written = table.write(tmp_path / "py")
    assert "table.bin" in written
    assert (tmp_path / "py" / "table.bin").read_bytes() == (out / "table.bin").read_bytes()


def test_the_parts_sensitivity_is_recorded_as_the_cli_records_it(static_log: Path, lab_bin: Path, tmp_path: Path) -> None:
    out = tmp_path / "cal"
    run_lab(lab_bin, ["calibrate", "--log", str(static_log), "--lsb-per-g", "4096", "--out", str(out)])
    table = q.calibrate(static_log, lsb_per_g=4096)
    assert table.to_bytes() == (out / "table.bin").read_bytes()
    # Without it the table records none: the bytes differ.
    assert q.calibrate(static_log).to_bytes() != table.to_bytes()
    for bad in (0.0, float("nan"), 2e9):
        with pytest.raises(q.CalibrationError, match="lsb_per_g="):
            q.calibrate(static_log, lsb_per_g=bad)


def test_arrays_go_through_the_reader(static_log: Path) -> None:
    log = q.read_log(static_log)
    again = q.log_from_arrays(
        log.columns["time_s"], log.columns["temp_c"], {a: log.columns[a] for a in log.axes}
    )
    assert again.rows == log.rows and again.axes == ["ax", "ay", "az"]
    for name in ["time_s", "temp_c", "ax", "ay", "az"]:
        assert np.array_equal(again.columns[name], log.columns[name])
    # A NaN row is skipped and counted, as in a file.
    temp = log.columns["temp_c"].copy()
    temp[100] = np.nan
    skipped = q.log_from_arrays(log.columns["time_s"], temp, {"ax": log.columns["ax"]})
    assert skipped.rows == log.rows - 1
    assert skipped.reader["skipped"]["nan"]["count"] == 1


def test_cycling_log_compensates_as_the_cli(lab_bin: Path, tmp_path: Path) -> None:
    log_csv = tmp_path / "log.csv"
    run_lab(lab_bin, ["simulate", "--out", str(log_csv), "--unit", "kt8-1", "--rates", "0.3,0.9", "--row-s", "10"])
    out = tmp_path / "cal"
    run_lab(lab_bin, ["calibrate", "--log", str(log_csv), "--out", str(out), "--no-plots"])
    table = q.calibrate(log_csv)
    assert table.input == "pulse_counts"
    assert table.to_bytes() == (out / "table.bin").read_bytes()

    comp_csv = tmp_path / "comp.csv"
    run_lab(lab_bin, ["compensate", "--log", str(log_csv), "--table", str(out / "table.bin"), "--out", str(comp_csv)])
    got = q.compensate(table, log_csv)
    lines = comp_csv.read_text().splitlines()
    assert lines[0].endswith(",accel_g")
    accel = got.columns["accel_g"]
    assert len(lines) - 1 == len(accel) == got.status.size
    for i, line in enumerate(lines[1:]):
        assert line.rsplit(",", 1)[1] == f"{accel[i]:.9f}", f"line {i + 2}"
    frame_cols = got.columns
    assert list(frame_cols)[:7] == ["program", "run", "time_s", "input_g", "temp_c", "pulses", "interval_s"]


def test_a_burst_in_a_cycling_row_is_in_the_reader_info_not_in_the_columns(tmp_path: Path) -> None:
    """The cycling reader skips a row whose pulses burst (50 000 extra in a 10-s row of a
    quiet ramp) and says so in ``reader["glitches"]``; the columns hold the rows kept."""
    rows = ["program,run,time_s,input_g,temp_c,pulses,interval_s"]
    for run, g in (("pos0", 1), ("pos2", -1)):
        for i in range(200):
            temp = round((-10.0 + 0.05 * i) * 16) / 16
            pulses = g * 3_200_000 - round(300 * temp) + (50_000 if run == "pos0" and i == 77 else 0)
            rows.append(f"p,{run},{10 * (i + 1)},{g},{temp:.4f},{pulses},10")
    path = tmp_path / "burst.csv"
    path.write_text("\n".join(rows) + "\n")
    log = q.read_log(path)
    assert len(log.reader["glitches"]) == 1
    assert log.reader["glitches"][0]["run"] == "pos0" and log.reader["glitches"][0]["time_s"] == 780.0
    assert len(log.columns["pulses"]) == 399


def test_discover_returns_the_report(static_log: Path, tmp_path: Path) -> None:
    report = q.discover(static_log, start="paper", out=tmp_path / "disc")
    assert [a["axis"] for a in report["axes"]] == ["ax", "ay", "az"]
    assert (tmp_path / "disc" / "report.json").is_file()


def test_a_static_discovery_names_what_calibrate_flashes(static_log: Path, tmp_path: Path) -> None:
    """One search: each axis's named structure is the one calibrate chose for table.bin, its
    held-out figure calibrate's, its steps end there, and each fold's last step is that figure."""
    report = q.discover(static_log, start="paper", out=tmp_path / "disc")
    table = q.calibrate(static_log)
    assert (tmp_path / "disc" / "table.bin").read_bytes() == table.to_bytes()
    for a, c in zip(report["axes"], table.report()["axes"]):
        assert a["named_structure"] == c["structure"]
        assert a["after"] == c["ours"]
        assert a["steps"][-1]["structure"] == a["named_structure"]
        for fold, structure in zip(a["heldout_steps"], c["heldout_structures"]):
            assert fold[-1]["structure"] == structure


def _write_cycling_log(path: Path) -> Path:
    """Four programs of ramps 0..40 °C at 0.3/0.5/0.7/0.9 °C/min, ±1 g, 10-s rows: a scale
    factor with a ΔT² and a Ṫ term, a curved bias, white noise."""
    rng = np.random.default_rng(7)
    rows = ["program,run,time_s,input_g,temp_c,pulses,interval_s"]
    for rate in (0.3, 0.5, 0.7, 0.9):
        half = int(round(40.0 / rate * 6))  # rows of one ramp
        temp = np.concatenate([np.linspace(0.0, 40.0, half), np.linspace(40.0, 0.0, half)])
        tdot = np.gradient(temp) * 6.0  # °C/min
        for run, g in (("pos0", 1), ("pos2", -1)):
            d = temp - 22.0
            k1 = 320_000.0 * (1.0 - 30e-6 * d + 0.1e-6 * d * d + 20e-6 * tdot)
            k0 = 1.2e-4 + 2.5e-6 * d + 1.5e-8 * d * d
            pulses = np.round(10.0 * k1 * (g + k0) + rng.normal(0.0, 30.0, temp.size)).astype(int)
            for i, (t, p) in enumerate(zip(temp, pulses)):
                rows.append(f"paper-{rate},{run},{10 * (i + 1)},{g},{round(t * 16) / 16:.4f},{p},10")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_a_cycling_discovery_flashes_what_calibrate_flashes(tmp_path: Path) -> None:
    """One table for one cycling log: discovery's table.bin is calibrate's bytes, and its
    report names that table's structure with calibrate's own held-out figures of it."""
    log = _write_cycling_log(tmp_path / "cycling.csv")
    report = q.discover(log, start="paper", out=tmp_path / "disc")
    table = q.calibrate(log)
    assert (tmp_path / "disc" / "table.bin").read_bytes() == table.to_bytes()
    t = report["table"]
    assert t["structure"].startswith("Eq. 11 + ") and report["flashed"]["model"] == t["structure"]
    assert report["verdict"]["answer"].startswith(f"named {t['structure']} = table.bin")
    held = table.report()
    assert t["calibrate_heldout"]["bias_residual_ug"] == held["bias_residual_ug"]["hysteresis"]
