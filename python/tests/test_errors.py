"""Bad inputs raise the documented exceptions, with the CLI's messages."""

from __future__ import annotations

from pathlib import Path
from typing import Any

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
    with pytest.raises(q.CalibrationError, match='holdout="sideways": expected auto, after-max, blocks:K'):
        q.calibrate(q.log_from_arrays(np.arange(100.0), np.linspace(20, 30, 100), {"ax": np.zeros(100)}), holdout="sideways")


def test_a_stuck_axis_is_refused_with_its_kind() -> None:
    """An axis that reads one value on every row is a stuck output or a constant column:
    refused, not calibrated into a flat table that meets every limit."""
    t = np.arange(3000.0)
    temp = 25.0 + 35.0 * np.sin(t / 300.0)
    log = q.log_from_arrays(t, temp, {"ax": 1e-3 + 1e-6 * temp, "az": np.full(3000, 1.0)})
    with pytest.raises(q.CalibrationError, match="az .* reads 1 g on every one of its 3000 rows") as e:
        q.calibrate(log)
    assert e.value.kind == "StuckAxis"


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


def _cycling_log(path: Path) -> Path:
    path.write_text("program,run,time_s,input_g,temp_c,pulses,interval_s\np,0,1,1,25,320000,1\np,0,2,1,25,320000,1\n")
    return path


def _static_log(path: Path) -> Path:
    write_static_log(path)
    return path


def _one_axis_log() -> q.Log:
    """One axis (az), 600 1-s rows over -10..60 °C."""
    t = np.arange(600.0)
    temp = 25.0 + 35.0 * np.sin(t / 100.0)
    return q.log_from_arrays(t, temp, {"az": 1.0 + 1e-5 * temp})


def _hot_log() -> q.Log:
    """Three axes at rest over 15..85 °C: above the 80 °C ArduPilot's TMAX accepts."""
    t = np.arange(3000.0)
    temp = 50.0 + 35.0 * np.sin(t / 300.0)
    return q.log_from_arrays(t, temp, {"ax": 1e-3 + 1e-6 * temp, "ay": -2e-3 - 1e-6 * temp, "az": 1.0 + 2e-6 * temp})


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _rows(header: str, row: str, n: int = 400) -> str:
    return header + "\n" + "".join(row.format(i=i, t=20 + 0.05 * i) + "\n" for i in range(n))


def _notes(table: q.Table) -> str:
    return "\n".join(table.exports()[1])


#: Every message of this package that is about an option the caller passed, with the
#: keyword it must name: `(id, keyword, call)`; `call(tmp_path)` raises a QfaError or
#: returns the message (the export notes).
OPTION_MESSAGES = [
    ("bad unit", "time_unit=", lambda d: q.read_log(_static_log(d / "s.csv"), time_unit="hours")),
    ("unit the data contradict", 'time_unit="', lambda d: q.read_log(_static_log(d / "s.csv"), time_unit="ns")),
    (
        "unit not known",
        'time_unit="',
        lambda d: q.read_log(_write(d / "u.csv", _rows("timestamp,temp_c,ax_g,ay_g,az_g", "{i},{t},0,0,1"))),
    ),
    (
        "no column for a role",
        'columns="',
        lambda d: q.read_log(_write(d / "m.csv", _rows("time_s,temp_c,foo", "{i},{t},1"))),
    ),
    ("bad columns item", "columns", lambda d: q.read_log(_static_log(d / "s.csv"), columns="nonsense")),
    (
        "decimal comma not asked for",
        "decimal_comma=True",
        lambda d: q.read_log(_write(d / "c.csv", _rows("time_s;temp_c;ax_g;ay_g;az_g", "{i};20,5;0;0;1"))),
    ),
    (
        "decimal comma with a comma delimiter",
        "decimal_comma=True",
        lambda d: q.read_log(_static_log(d / "s.csv"), decimal_comma=True),
    ),
    (
        "arrays in a unit they contradict",
        'accel_unit="',
        lambda d: q.log_from_arrays(np.arange(400.0), np.linspace(20, 30, 400), {"az": np.full(400, 9.8)}),
    ),
    ("calibrate: bad holdout", 'holdout="sideways"', lambda d: q.calibrate(_static_log(d / "s.csv"), holdout="sideways")),
    ("discover: bad holdout", 'holdout="sideways"', lambda d: q.discover(_static_log(d / "s.csv"), holdout="sideways")),
    (
        "calibrate: holdout blocks too short",
        'holdout="blocks:2000"',
        lambda d: q.calibrate(_static_log(d / "s.csv"), holdout="blocks:2000"),
    ),
    (
        "discover: holdout blocks too short",
        'holdout="blocks:2000"',
        lambda d: q.discover(_static_log(d / "s.csv"), holdout="blocks:2000"),
    ),
    (
        "calibrate: holdout on a cycling log",
        'holdout="blocks:3"',
        lambda d: q.calibrate(_cycling_log(d / "c.csv"), holdout="blocks:3"),
    ),
    (
        "discover: holdout on a cycling log",
        'holdout="blocks:3"',
        lambda d: q.discover(_cycling_log(d / "c.csv"), holdout="blocks:3"),
    ),
    ("calibrate: bad axis", 'axis="w"', lambda d: q.calibrate(_cycling_log(d / "c.csv"), axis="w")),
    ("device ID 0", "px4_device_id=0", lambda d: q.calibrate(_one_axis_log(), px4_device_id=0)),
    ("device ID too large", "px4_device_id=", lambda d: q.calibrate(_one_axis_log(), px4_device_id=2**40)),
    ("export range reversed", "export_range=(5", lambda d: q.calibrate(_one_axis_log(), export_range=(5.0, 1.0))),
    ("note: one axis needs a range", "export_range=(TMIN, TMAX)", lambda d: _notes(q.calibrate(_one_axis_log()))),
    (
        "note: range outside the training temperatures",
        "export_range=(-50",
        lambda d: _notes(q.calibrate(_one_axis_log(), export_range=(-50.0, 50.0))),
    ),
    (
        "note: no device ID",
        "px4_device_id=ID",
        lambda d: _notes(q.calibrate(_one_axis_log(), export_range=(0.0, 50.0))),
    ),
    ("note: training range beyond ArduPilot's", "export_range=(TMIN, TMAX)", lambda d: _notes(q.calibrate(_hot_log()))),
    (
        "note: range beyond ArduPilot's",
        "export_range=(20",
        lambda d: _notes(q.calibrate(_hot_log(), export_range=(20.0, 84.0))),
    ),
]


@pytest.mark.parametrize("keyword,call", [c[1:] for c in OPTION_MESSAGES], ids=[c[0] for c in OPTION_MESSAGES])
def test_messages_name_keywords_not_flags(tmp_path: Path, keyword: str, call: Any) -> None:
    """A message about an option names it as this package's keyword, never as the CLI's
    flag (``holdout="blocks:5"``, not ``--holdout blocks:5``)."""
    try:
        message = call(tmp_path)
    except q.QfaError as e:
        message = str(e)
    assert isinstance(message, str) and message, "no message"
    assert keyword in message and "--" not in message, message


def test_kind_comes_from_the_error_type(tmp_path: Path) -> None:
    """``kind`` names the Rust variant on every error that has one, and is ``None`` on the
    others; a calibration's held-out refusal is typed too, through ``discover`` as well."""
    log = _static_log(tmp_path / "s.csv")
    with pytest.raises(q.CalibrationError) as e:
        q.calibrate(log, holdout="sideways")
    assert e.value.kind == "UnknownHoldout"
    with pytest.raises(q.DiscoveryError) as d:
        q.discover(log, holdout="blocks:2000")
    assert d.value.kind == "BlocksTooShort"
    with pytest.raises(q.LogError) as r:
        q.read_log(log, columns="nonsense")
    assert r.value.kind == "BadColumnSpec"
    with pytest.raises(q.CalibrationError) as c:
        q.calibrate(_cycling_log(tmp_path / "c.csv"), holdout="blocks:3")
    assert c.value.kind is None
    # A cycling log whose only program has no -1 g run: the fit's own variant.
    with pytest.raises(q.CalibrationError) as f:
        q.calibrate(_cycling_log(tmp_path / "c.csv"))
    assert f.value.kind == "NoPair", (f.value.kind, str(f.value))
    c = q.Compensator(axes=1)
    with pytest.raises(q.SampleError) as s:
        c.on_raw(1000, 400, sensor=1)
    assert s.value.kind == "NoSuchSensor"
    with pytest.raises(q.TableError) as t:
        q.Table.from_bytes(b"QFAT")
    assert t.value.kind == "Truncated"
