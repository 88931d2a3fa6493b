"""Bad inputs raise the documented exceptions, with the CLI's messages."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import qfa_thermal as q

from conftest import cli_error, run_lab
from static_log import write_static_log


def test_hierarchy() -> None:
    for e in [q.LogError, q.CalibrationError, q.TableError, q.CompensationError, q.DiscoveryError, q.ConfigError, q.SampleError]:
        assert issubclass(e, q.QfaError) and issubclass(q.QfaError, Exception)


def test_bad_cycling_rows_raise_log_error_with_the_cli_message(lab_bin: Path, tmp_path: Path) -> None:
    log = tmp_path / "bad.csv"
    log.write_text(
        "program,run,time_s,input_g,temp_c,pulses,interval_s\n"
        "p,0,1,1,25,320000,1\n"
        "p,0,2,1,abc,320000,1\n"
        "p,0,2,1,25,320000,1\n"
    )
    code, _, err = run_lab(lab_bin, ["compensate", "--log", str(log), "--table", str(log), "--out", str(tmp_path / "o.csv")], ok=False)
    assert code != 0
    with pytest.raises(q.LogError) as e:
        q.read_log(log)
    assert str(e.value).strip() == cli_error(err)
    assert "line 3: bad temp_c `abc`" in str(e.value)


def test_unknown_column_raises_log_error_with_the_cli_message(lab_bin: Path, tmp_path: Path) -> None:
    log = tmp_path / "board.csv"
    write_static_log(log, rows=400)
    args = ["--columns", "temp=nope"]
    _, _, err = run_lab(lab_bin, ["compensate", "--log", str(log), "--table", str(log), "--out", str(tmp_path / "o.csv"), *args], ok=False)
    with pytest.raises(q.LogError) as e:
        q.read_log(log, columns="temp=nope")
    assert str(e.value) == cli_error(err)


def test_corrupt_table_raises_table_error_with_the_cli_message(lab_bin: Path, tmp_path: Path) -> None:
    log = tmp_path / "board.csv"
    write_static_log(log)
    table = q.calibrate(log)
    data = bytearray(table.to_bytes())
    data[20] ^= 1
    bad = tmp_path / "bad.bin"
    bad.write_bytes(bytes(data))
    _, _, err = run_lab(lab_bin, ["compensate", "--log", str(log), "--table", str(bad), "--out", str(tmp_path / "o.csv")], ok=False)
    with pytest.raises(q.TableError) as e:
        q.Table.load(bad)
    assert str(e.value) == cli_error(err)
    assert e.value.kind == "Crc"


def test_wrong_kind_of_table_raises_compensation_error_with_the_cli_message(lab_bin: Path, tmp_path: Path) -> None:
    cyc = tmp_path / "log.csv"
    run_lab(lab_bin, ["simulate", "--out", str(cyc), "--unit", "kt8-1", "--rates", "0.3,0.9", "--row-s", "10"])
    out = tmp_path / "cal"
    run_lab(lab_bin, ["calibrate", "--log", str(cyc), "--out", str(out), "--no-plots"])
    board = tmp_path / "board.csv"
    write_static_log(board, rows=400)
    _, _, err = run_lab(lab_bin, ["compensate", "--log", str(board), "--table", str(out / "table.bin"), "--out", str(tmp_path / "o.csv")], ok=False)
    with pytest.raises(q.CompensationError) as e:
        q.compensate(q.Table.load(out / "table.bin"), board)
    assert str(e.value) == cli_error(err)


def test_unequal_columns_and_bad_holdout() -> None:
    table_log = np.arange(10.0)
    with pytest.raises(q.LogError, match="unequal length"):
        q.log_from_arrays(table_log, table_log[:5], {"ax": table_log})
    with pytest.raises(q.CalibrationError, match="--holdout `sideways`: expected auto, after-max, blocks:K"):
        q.calibrate(q.log_from_arrays(np.arange(100.0), np.linspace(20, 30, 100), {"ax": np.zeros(100)}), holdout="sideways")


def test_firmware_errors_are_typed() -> None:
    with pytest.raises(q.ConfigError) as e:
        q.Compensator(confirm_samples=1)
    assert str(e.value) == "confirm_samples is out of range" and e.value.kind == "OutOfRange"
    c = q.Compensator(axes=3)
    with pytest.raises(q.SampleError) as s:
        c.on_scratchpad(1000, bytes(9))
    assert s.value.kind == "AllZero" and s.value.status & q.Status.TEMP_STALE
    with pytest.raises(ValueError):
        c.cycle([1, 2], 1000)


def test_unit_mistakes_name_keywords_not_flags(tmp_path: Path) -> None:
    """A unit the data contradict is refused with the CLI's message style, the option named
    as this package's keyword (``accel_unit="m/s2"``) and never as a CLI flag; ``kind`` comes
    from the error's type. Fails before the two-sided check (m/s² read as mg was read)."""
    log = tmp_path / "board.csv"
    with open(log, "w") as f:
        f.write("time_s,temp_c,acc_x,acc_y,acc_z\n")
        for i in range(400):
            f.write(f"{i},{20 + 0.05 * i:.4f},0.01,-0.02,-9.80\n")
    with pytest.raises(q.LogError) as e:
        q.read_log(log, accel_unit="mg")
    assert e.value.kind == "Unit"
    assert 'pass accel_unit="m/s2"' in str(e.value) and "--" not in str(e.value), str(e.value)
    with pytest.raises(q.LogError) as e:
        q.read_log(log, accel_unit="m/s2", temp_unit="X")
    assert e.value.kind == "BadUnit" and str(e.value) == 'temp_unit="X": expected C|F|K'
    assert q.read_log(log, accel_unit="m/s2", temp_unit="C").rows == 400
