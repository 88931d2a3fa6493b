"""Production batches from Python: the same files whatever runs the shards (this process,
a process pool, a Dask cluster), and the fleet read back."""

from __future__ import annotations

import concurrent.futures
import os
import hashlib
from pathlib import Path
from typing import Any, Dict, Tuple

import pytest

import qfa_thermal as q
from conftest import run_lab

READER = {"time_unit": "s", "accel_unit": "g", "temp_unit": "C"}
#: Units in the simulated chamber run: the simulator's three defects and one good unit,
#: in three shards of two, one and one.
UNITS = 4


def _tree(root: Path) -> Dict[str, str]:
    """Every file under ``root``: relative path → SHA-256."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(root.rglob("*")) if p.is_file()
    }


@pytest.fixture(scope="module")
def chamber(tmp_path_factory: pytest.TempPathFactory, lab_bin: Path) -> Path:
    """A simulated chamber run of 4 units (3 deliberately bad: one of each defect), written
    by the CLI."""
    d = tmp_path_factory.mktemp("sim")
    run_lab(lab_bin, ["simulate-batch", "--units", str(UNITS), "--seed", "4", "--out", str(d)])
    return d / "chamber.tsv"


@pytest.fixture(scope="module")
def single_run(tmp_path_factory: pytest.TempPathFactory, chamber: Path) -> Tuple[Path, Dict[str, Any]]:
    """The batch in this process: its folder and the fleet ``batch`` returned."""
    out = tmp_path_factory.mktemp("single")
    fleet = q.batch(log=chamber, out=out, shards=3, **READER)
    return out, fleet


@pytest.fixture(scope="module")
def single(single_run: Tuple[Path, Dict[str, Any]]) -> Path:
    return single_run[0]


def test_a_process_pool_writes_the_same_bytes(tmp_path: Path, chamber: Path, single: Path) -> None:
    out = tmp_path / "pool"
    with concurrent.futures.ProcessPoolExecutor(max_workers=2) as ex:
        fleet = q.batch(log=chamber, out=out, executor=ex, shards=3, **READER)
    assert _tree(out) == _tree(single)
    assert fleet["units"] == UNITS
    assert sum(fleet["counts"]) == UNITS


def test_a_dask_cluster_writes_the_same_bytes(tmp_path: Path, chamber: Path, single: Path) -> None:
    """The batch on a ``dask.distributed.LocalCluster`` (two worker processes) through
    ``Client.get_executor()``: the same files as the single-process run, byte for byte."""
    if os.environ.get("CI") == "true":
        import dask.distributed as distributed  # CI installs it: missing is a failure there
    else:
        distributed = pytest.importorskip("dask.distributed")
    out = tmp_path / "dask"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            fleet = q.batch(log=chamber, out=out, executor=client.get_executor(), shards=3, **READER)
    assert _tree(out) == _tree(single)
    assert fleet["units"] == UNITS


def test_the_returned_fleet_is_the_file(single_run: Tuple[Path, Dict[str, Any]]) -> None:
    """``batch`` returns ``fleet.json`` itself, and every unit of the log has its
    certificate naming the CRC of a table that exists. (Which units the fleet flags is
    judged against the simulator's truth on 20 units in ``lab/tests/batch.rs``: 4 are too
    few for a robust spread.)"""
    import json

    single, fleet = single_run
    assert fleet == json.loads((single / "fleet.json").read_text())
    assert [u["serial"] for u in fleet["unit"]] == [f"SN{i:04d}" for i in range(1, UNITS + 1)]
    for u in fleet["unit"]:
        cert = json.loads((single / u["serial"] / "certificate.json").read_text())
        name, crc = cert["flash"]
        header = (single / u["serial"] / name).read_bytes()[12:16]
        assert int.from_bytes(header, "little") == int(crc, 16)


def test_mistakes_raise_batch_error(tmp_path: Path, chamber: Path) -> None:
    with pytest.raises(q.BatchError, match="one of them"):
        q.batch(out=tmp_path, **READER)
    bad = tmp_path / "batch.toml"
    bad.write_text('[[unit]]\nserial = "A"\nlog = "a.tsv"\ntime_units = "s"\n')
    with pytest.raises(q.BatchError) as e:
        q.batch(manifest=bad, out=tmp_path / "o", **READER)
    assert e.value.kind == "Manifest" and "time_units" in str(e.value)
    # A keyword every unit of a chamber log needs, forgotten: each unit fails naming the
    # keyword to pass, as Python spells it (not the command line's flag).
    fleet = q.batch(log=chamber, out=tmp_path / "f", accel_unit="g", temp_unit="C")
    reasons = [u["reasons"][0] for u in fleet["unit"]]
    assert all('pass time_unit="' in r and "--time-unit" not in r for r in reasons), reasons


def test_a_qfa_batch_reads_the_units_own_models(tmp_path: Path, lab_bin: Path) -> None:
    """QFA units through the paper's cycling test, from one multi-unit cycling log: each
    unit's fleet figures are its own model's, checked against the simulator's truth (not the
    code under test), and a manifest of one log per unit gives the same tables. A static
    reader option with a cycling chamber log is refused once, with why."""
    import json

    if os.environ.get("CI") == "true":
        import tomllib  # Python 3.11 and later, as CI runs: missing is a failure there
    else:
        tomllib = pytest.importorskip("tomllib", reason="reading the simulator's truth needs Python 3.11's tomllib")
    sim = tmp_path / "qsim"
    run_lab(lab_bin, ["simulate-batch", "--qfa", "--units", "4", "--seed", "2", "--out", str(sim)])
    fleet = q.batch(log=sim / "chamber.csv", out=tmp_path / "by_log", shards=2)
    q.batch(manifest=sim / "batch.toml", out=tmp_path / "by_manifest", shards=1)
    truth = {u["serial"]: u for u in tomllib.loads((sim / "truth.toml").read_text())["unit"]}
    figures = {s["feature"]["name"]: dict(s["values"]) for s in fleet["stats"]}
    for serial, u in truth.items():
        scale = u["truth"]["scale"]
        want = scale["mu"] / scale["gamma"] * 1e6
        assert abs(figures["qfa.mu_ppm_per_c"][serial] - want) < 0.5, (serial, figures["qfa.mu_ppm_per_c"][serial], want)
        a = (tmp_path / "by_log" / serial / "table.bin").read_bytes()
        assert a == (tmp_path / "by_manifest" / serial / "table.bin").read_bytes(), serial
        unit = json.loads((tmp_path / "by_log" / serial / "unit.json").read_text())
        assert unit["outcome"]["calibrated"]["qfa"]["held_out_bias_ug"] > 0
    with pytest.raises(q.BatchError) as e:
        q.batch(log=sim / "chamber.csv", out=tmp_path / "wrong", shards=1, time_unit="s")
    assert e.value.kind == "Chamber" and "cycling log" in str(e.value), str(e.value)
