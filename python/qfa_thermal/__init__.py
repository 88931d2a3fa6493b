"""qfa_thermal: the lab (`qfa-lab`) and the firmware's compensator from Python, bit-exact.

Everything here calls the project's Rust code through the ``_native`` extension: the lab's
log readers, calibration, compensation and discovery, and the root crate's
``Compensator``. Nothing is re-implemented in Python; this module adds type hints,
dataclasses and the optional pandas view. Columns are numpy arrays, one copy each way.
"""

# Every module-level name that is not API is private (`_np`, `_os`, `as _annotations`),
# so `dir(qfa_thermal)` lists the API alone.
from __future__ import annotations as _annotations

import enum as _enum
import json as _json
import os as _os
import typing as _t
from collections.abc import Mapping as _Mapping
from dataclasses import dataclass as _dataclass
from dataclasses import field as _field

import numpy as _np

from . import _native
from ._native import (
    BatchError,
    CalibrationError,
    CompensationError,
    Compensator,
    ConfigError,
    DiscoveryError,
    LogError,
    QfaError,
    SampleError,
    Table,
)

__all__ = [
    "Log",
    "Table",
    "Compensator",
    "Compensated",
    "Status",
    "read_log",
    "log_from_arrays",
    "calibrate",
    "compensate",
    "discover",
    "batch",
    "BatchShard",
    "calibrate_shard",
    "status_text",
    "QfaError",
    "LogError",
    "CalibrationError",
    "TableError",
    "CompensationError",
    "DiscoveryError",
    "ConfigError",
    "SampleError",
    "BatchError",
    "RATE_WINDOW",
    "G0",
]

TableError = _native.TableError

if _t.TYPE_CHECKING:
    # The annotations' names: type checkers read them; at run time the annotations stay
    # strings (`from __future__ import annotations`), so the module never holds them.
    import os
    from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

    import numpy as np
    import numpy.typing as npt

    PathLike = Union[str, os.PathLike[str]]
    FloatArray = npt.NDArray[np.float64]

#: Rate window (samples) of every ``Compensator`` here, as in the lab and the vectors.
RATE_WINDOW: int = _native.RATE_WINDOW
#: Standard gravity, m/s², as the firmware's f32 constant.
G0: float = _native.G0

#: The firmware's status word, one flag per condition (names and bits from the Rust
#: definition itself). ``Status(0)`` is fully compensated.
Status = _enum.IntFlag("Status", dict(_native.status_flags()))  # type: ignore[misc]
Status.__doc__ = "The firmware's status flags (qfa_thermal::Status), from its own definition."


@_dataclass(frozen=True)
class Log:
    """A log as the lab's reader read it: a static multi-axis log or a cycling log.

    ``columns`` holds numpy arrays by name (static: ``time_s``, ``temp_c``, one array per
    axis in g, ``line``; cycling: ``program``, ``run``, ``time_s``, ``input_g``,
    ``temp_c`` with NaN before the first reading, ``pulses``, ``interval_s``). ``reader``
    says what the static reader skipped and how the log is sampled; for a cycling log, the
    rows its reader skipped as one-row glitches (``reader["glitches"]``: program, run,
    time, pulses, interval) and as written twice (``reader["repeated"]``: count, lines),
    which no column holds.
    """

    native: Any = _field(repr=False)
    kind: str
    rows: int
    axes: List[str]
    columns: Dict[str, Any]
    reader: Dict[str, Any]

    @classmethod
    def _of(cls, native: Any) -> "Log":
        return cls(
            native=native,
            kind=native.kind,
            rows=native.rows,
            axes=list(native.axes),
            columns=dict(native.columns()),
            reader=_json.loads(native.reader_json()),
        )

    @property
    def path(self) -> Optional[str]:
        """The file read, or ``None`` for a log made from arrays."""
        p = self.native.path
        return None if p is None else str(p)

    def to_pandas(self) -> Any:
        """The columns as a pandas DataFrame (pandas is needed for this call only)."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("Log.to_pandas needs pandas: pip install pandas") from e
        return pd.DataFrame(self.columns)


def read_log(
    path: PathLike,
    *,
    columns: Optional[str] = None,
    time_unit: Optional[str] = None,
    accel_unit: Optional[str] = None,
    temp_unit: Optional[str] = None,
    decimal_comma: bool = False,
) -> Log:
    """Read a log file with the lab's reader, choosing it as ``qfa-lab`` does.

    Any reader option, or a header without a ``pulses`` column, selects the static reader
    (``columns`` as ``--columns``, e.g. ``"time=timestamp,temp=imu.temperature,ax=imu.acc.x"``;
    ``time_unit`` s/ms/us/ns; ``accel_unit`` g/mg/m/s2; ``temp_unit`` C/F/K, default from
    the column name, else C); otherwise the cycling reader.

    Raises:
        LogError: with the CLI's message, reader options named as this function's keywords
            (``accel_unit="m/s2"``), and ``kind`` the reader's error variant (``Unit`` for
            a unit the data contradict, ``Rows``, ``UnknownColumn``, ...).
    """
    return Log._of(
        _native.read_log(
            _os.fspath(path),
            columns=columns,
            time_unit=time_unit,
            accel_unit=accel_unit,
            temp_unit=temp_unit,
            decimal_comma=decimal_comma,
        )
    )


def _f64(a: npt.ArrayLike) -> FloatArray:
    return _np.ascontiguousarray(a, dtype=_np.float64)


def log_from_arrays(
    time: npt.ArrayLike,
    temp_c: npt.ArrayLike,
    accel: Mapping[str, npt.ArrayLike],
    *,
    time_unit: str = "s",
    accel_unit: str = "g",
) -> Log:
    """A static log from columns, passed through the static reader's own checks.

    ``accel`` maps axis roles (``ax``, ``ay``, ``az``) to columns. Rows with a NaN are
    skipped and glitch rows dropped exactly as for a file; time going backwards and
    implausible units raise ``LogError``.
    """
    pairs = [(name, _f64(col)) for name, col in accel.items()]
    return Log._of(
        _native.log_from_arrays(_f64(time), _f64(temp_c), pairs, time_unit=time_unit, accel_unit=accel_unit)
    )


def _as_log(log: Union[Log, PathLike], reader: Mapping[str, Any]) -> Log:
    if isinstance(log, Log):
        if reader:
            raise TypeError("reader options apply to a path, not to a Log already read")
        return log
    return read_log(log, **reader)


def calibrate(
    log: Union[Log, PathLike],
    *,
    holdout: str = "auto",
    fit_programs: Optional[Sequence[str]] = None,
    axis: str = "x",
    px4_device_id: Optional[int] = None,
    export_range: Optional[Tuple[float, float]] = None,
    lsb_per_g: Optional[float] = None,
    **reader: Any,
) -> Table:
    """``qfa-lab calibrate``: fit a table to a log (a ``Log``, or a path read with ``reader``
    options as in ``read_log``).

    Static logs take ``holdout`` (auto, after-max, blocks:K, none) and ``lsb_per_g``, the
    part's sensitivity at the range it was logged at (4096 for ±8 g at 16 bits), which the
    table records so that a firmware stating another ``sample_lsb_per_g`` refuses it
    (``--lsb-per-g``); cycling logs take ``fit_programs`` and ``axis`` (the IMU axis of its
    parameter files). The returned
    ``Table`` has ``to_bytes()`` (flash it), ``to_toml()``, ``report()`` (the report as a
    dict), ``exports()`` (PX4 / ArduPilot files) and ``write(dir)``.

    Raises:
        LogError: the log is refused by the reader.
        CalibrationError: the fit or a held-out figure cannot be formed, or an option is
            refused (CLI's message, options named as keywords: ``holdout="blocks:50"``;
            ``kind`` the Rust variant, ``UnknownHoldout``, ``BlocksTooShort``, ..., or
            ``None`` for an argument checked here).
    """
    lg = _as_log(log, reader)
    return _native.calibrate(
        lg.native,
        holdout=holdout,
        fit_programs=None if fit_programs is None else list(fit_programs),
        axis=axis,
        px4_device_id=px4_device_id,
        export_range=export_range,
        lsb_per_g=lsb_per_g,
    )


@_dataclass(frozen=True)
class Compensated:
    """Compensated rows, as ``qfa-lab compensate`` computes them before formatting.

    ``columns``: static logs ``time_s``, ``temp_c`` and one array per axis in g; cycling
    logs the log's columns and ``accel_g``. ``status``: the firmware's flags per row
    (uint16, OR-ed over the axes of a static log; see ``Status`` and ``status_text``).
    """

    kind: str
    columns: Dict[str, Any]
    status: npt.NDArray[np.uint16]

    def status_text(self) -> List[str]:
        """The CLI's ``status`` column text for a static log (``ok``, ``no_temperature``,
        flags joined by ``|``)."""
        return status_text(self.status)

    def to_pandas(self) -> Any:
        """The rows as a pandas DataFrame with the ``status`` flags (pandas needed)."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("Compensated.to_pandas needs pandas: pip install pandas") from e
        frame = pd.DataFrame(self.columns)
        frame["status"] = self.status
        return frame


def status_text(status: npt.ArrayLike) -> List[str]:
    """The text ``qfa-lab compensate`` writes in a static log's ``status`` column for each
    flags word."""
    return list(_native.status_texts(_np.ascontiguousarray(status, dtype=_np.uint16)))


def compensate(
    table: Table,
    log: Union[Log, PathLike, None] = None,
    *,
    time_s: Optional[npt.ArrayLike] = None,
    temp_c: Optional[npt.ArrayLike] = None,
    accel: Optional[Union[Mapping[str, npt.ArrayLike], npt.ArrayLike]] = None,
    **reader: Any,
) -> Compensated:
    """``qfa-lab compensate``: run rows through the firmware's compensator with ``table``.

    Either a log (``Log`` or a path with ``reader`` options), or static columns:
    ``time_s`` (s), ``temp_c`` and ``accel`` (g) as a mapping ``{role: column}`` or a
    2-D array with one column per table axis. Columns go straight to the compensation
    (no reader), as the benchmark measures it; one copy in, one out.

    Raises:
        CompensationError: a table of the other kind or axis count, unequal columns, or
            rows the firmware's settings refuse (CLI's message; ``kind`` ``Table``,
            ``AxisCount``, ``Length``, ``Config``, ...).
    """
    if log is not None:
        if time_s is not None or temp_c is not None or accel is not None:
            raise TypeError("pass a log or columns, not both")
        lg = _as_log(log, reader)
        if lg.kind == "cycling":
            accel_g, status = _native.compensate_cycling(table, lg.native)
            cols = dict(lg.columns)
            cols["accel_g"] = accel_g
            return Compensated("cycling", cols, status)
        names = lg.axes
        t, temp = lg.columns["time_s"], lg.columns["temp_c"]
        axes = [lg.columns[n] for n in names]
    else:
        if time_s is None or temp_c is None or accel is None:
            raise TypeError("compensate needs a log, or time_s, temp_c and accel")
        t, temp = _f64(time_s), _f64(temp_c)
        if isinstance(accel, _Mapping):
            names = list(accel.keys())
            axes = [_f64(a) for a in accel.values()]
        else:
            arr = _np.asarray(accel, dtype=_np.float64)
            arr = arr.reshape(-1, 1) if arr.ndim == 1 else arr
            names = ["ax", "ay", "az"][: arr.shape[1]]
            axes = [_np.ascontiguousarray(arr[:, k]) for k in range(arr.shape[1])]
    outputs, status = _native.compensate_columns(table, t, temp, axes)
    cols: Dict[str, Any] = {"time_s": t, "temp_c": temp}
    cols.update(zip(names, outputs))
    return Compensated("static", cols, status)


def discover(
    log: Union[Log, PathLike],
    *,
    start: str = "simple",
    holdout: str = "auto",
    out: Optional[PathLike] = None,
    **reader: Any,
) -> Dict[str, Any]:
    """``qfa-lab discover``: name the effects the start model (``simple`` or ``paper``)
    misses; returns ``report.json`` as a dict. The files go to ``out`` when given.

    Raises:
        DiscoveryError: the run failed (CLI's message, options named as keywords; ``kind``
            the Rust variant, as for ``calibrate`` when calibration's held-out scheme
            refused the log).
    """
    lg = _as_log(log, reader)
    text = _native.discover(lg.native, start=start, holdout=holdout, out=None if out is None else _os.fspath(out))
    return _json.loads(text)


@_dataclass(frozen=True)
class BatchShard:
    """One shard of a production batch: the units whose place ``i`` in the batch has
    ``i % n == k``. Plain data, so it pickles to any executor's workers."""

    out: str
    k: int
    n: int
    log: Optional[str] = None
    manifest: Optional[str] = None
    holdout: str = "auto"
    limits: Optional[str] = None
    reader: Tuple[Tuple[str, Any], ...] = ()


def calibrate_shard(shard: BatchShard) -> int:
    """Calibrate one shard into ``shard.out`` (``qfa-lab batch --shard K/N``) on one thread;
    returns the number of units calibrated. A plain module-level function, so executors
    can pickle it."""
    return _native.batch_shard(
        out=shard.out,
        k=shard.k,
        n=shard.n,
        log=shard.log,
        manifest=shard.manifest,
        holdout=shard.holdout,
        limits=shard.limits,
        threads=1,
        **dict(shard.reader),
    )


def batch(
    *,
    out: PathLike,
    log: Optional[PathLike] = None,
    manifest: Optional[PathLike] = None,
    executor: Any = None,
    shards: int = 16,
    holdout: str = "auto",
    limits: Optional[PathLike] = None,
    **reader: Any,
) -> Dict[str, Any]:
    """``qfa-lab batch``: calibrate every unit of a chamber ``log`` (or of a ``manifest``)
    into ``out``, a certificate per serial and the fleet page; returns ``fleet.json`` as a
    dict.

    The units are cut into ``shards`` (``BatchShard``) and mapped with
    ``executor.map(calibrate_shard, ...)``: any ``concurrent.futures.Executor`` (a
    ``ProcessPoolExecutor``, Dask's ``Client.get_executor()``, Ray's executor), or one
    after another in this process when ``executor`` is None. Every worker writes into
    ``out``, so they must share its file system. The fleet is then formed here from every
    unit's ``unit.json``; the files are byte-identical to one ``qfa-lab batch`` run.

    Raises:
        BatchError: the manifest or chamber log cannot be read, or the merge failed
            (``kind``: ``Manifest``, ``Chamber``, ``Serial``, ``Shard``, ``Merge``, ``Io``,
            ``Limits``, ``UnknownHoldout``). A unit that cannot be calibrated is not an
            error: it is FAIL in the fleet, with its reason.
    """
    if (log is None) == (manifest is None):
        raise BatchError("give log= (a chamber log) or manifest= (batch.toml), one of them")
    if shards < 1:
        raise BatchError(f"shards={shards}: at least 1")
    tasks = [
        BatchShard(
            out=_os.fspath(out),
            k=k,
            n=shards,
            log=None if log is None else _os.fspath(log),
            manifest=None if manifest is None else _os.fspath(manifest),
            holdout=holdout,
            limits=None if limits is None else _os.fspath(limits),
            reader=tuple(sorted(reader.items())),
        )
        for k in range(shards)
    ]
    if executor is None:
        for t in tasks:
            calibrate_shard(t)
    else:
        list(executor.map(calibrate_shard, tasks))
    text = _native.batch_merge(_os.fspath(out), limits=None if limits is None else _os.fspath(limits))
    return _json.loads(text)
