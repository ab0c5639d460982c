"""`oneocean verify` on a corrupted results tree: every bad artifact is one line naming it and
what is wrong, the other artifacts are still checked, and the exit status is non-zero."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from oneocean.cli import main
from oneocean.engine.recording import write_metrics
from oneocean.errors import DataError
from oneocean.io import write_json_atomic
from oneocean.pipeline.manifest import collect_manifest, verify, write_job_provenance
from oneocean.product.ncio import netcdf_encoding, write_netcdf_atomic

NC = "results/product/ci/tiny/product.nc"
PARQUET = "results/rollouts/ci/cell.parquet"
JSON = "results/product/ci/tiny/metadata.json"
OK_JSON = "results/tables/ci/ok.json"


def _tree(root):
    """A small manifest-tracked results tree written by the project's own writers."""
    rng = np.random.default_rng(0)
    ds = xr.Dataset(
        {"u": (("time", "latitude", "longitude"), rng.normal(size=(4, 30, 40)))},
        coords={"time": np.arange(4.0), "latitude": np.linspace(50, 50.3, 30),
                "longitude": np.linspace(-4.6, -4.2, 40)},
        attrs={"Conventions": "CF-1.11"})
    write_netcdf_atomic(ds, root / NC, netcdf_encoding(ds))
    write_metrics(pd.DataFrame({"episode": np.arange(50), "success": rng.random(50) > 0.5,
                                "energy_j": rng.normal(size=50)}), root / PARQUET)
    write_json_atomic(root / JSON, {"region": "ci", "grid": {"nx": 40, "ny": 30}})
    write_json_atomic(root / OK_JSON, {"untouched": True})
    prov = root / "results/provenance/job.json"
    write_job_provenance(prov, "product", {"region": "ci"}, [NC, JSON, PARQUET, OK_JSON], [],
                         {"k": 1})
    collect_manifest([prov], root / "results/manifest/ci.json")
    return root / "results"


def _flip(path, at):
    data = bytearray(path.read_bytes())
    data[at] ^= 0xFF
    path.write_bytes(bytes(data))


def _corrupt(root):
    nc = root / NC
    _flip(nc, nc.stat().st_size // 2)          # inside the compressed chunk of `u`
    _flip(root / PARQUET, (root / PARQUET).stat().st_size // 2)
    _flip(root / JSON, 5)


@pytest.fixture
def tree(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return _tree(tmp_path)


def test_verify_names_each_corrupt_artifact_on_one_line(tree, tmp_path, capsys):
    assert main(["verify", str(tree)]) == 0
    capsys.readouterr()
    _corrupt(tmp_path)

    problems = verify(tree / "manifest/ci.json", tmp_path)
    by_path = {p.split(":")[0]: p for p in problems}
    assert sorted(by_path) == sorted([NC, PARQUET, JSON])
    assert by_path[NC].startswith(f"{NC}: cannot be decoded (")
    assert "HDF error" in by_path[NC]
    assert by_path[PARQUET] == f"{PARQUET}: sha256 differs from the manifest (written by rule " \
                               "'product')"
    assert by_path[JSON].startswith(f"{JSON}: sha256 differs from the manifest")

    assert main(["verify", str(tree)]) == 1
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert len(lines) == 3 and all(line.startswith("MISMATCH results/") for line in lines)
    assert sorted(line.split()[1].rstrip(":") for line in lines) == sorted([NC, PARQUET, JSON])
    assert "3 artifact(s) do not match" in err and "Traceback" not in out + err


def test_verify_cli_subprocess_exits_nonzero_without_traceback(tree, tmp_path):
    _corrupt(tmp_path)
    res = subprocess.run([sys.executable, "-m", "oneocean.cli", "verify", "results"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert res.returncode == 1, res.stderr
    assert "Traceback" not in res.stderr
    mismatches = [line for line in res.stdout.splitlines() if line.startswith("MISMATCH")]
    assert len(mismatches) == 3
    assert any(NC in line and "cannot be decoded" in line for line in mismatches)


def test_verify_netcdf_that_decodes_to_other_values(tree, tmp_path):
    # a re-written product with other numbers: bytes and decoded content both differ
    ds = xr.load_dataset(tmp_path / NC)
    ds["u"][:] = ds["u"] + 1.0
    write_netcdf_atomic(ds, tmp_path / NC, netcdf_encoding(ds))
    (line,) = verify(tree / "manifest/ci.json", tmp_path)
    assert line == f"{NC}: content hash differs from the manifest (written by rule 'product')"


def test_verify_names_missing_and_corrupt_input(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = _tree(tmp_path)
    out = res / "exports/grid.json"
    write_json_atomic(out, {"a": 1})
    prov = res / "provenance/export.json"
    write_job_provenance(prov, "export", {}, ["results/exports/grid.json"], [NC], {})
    collect_manifest([res / "provenance/job.json", prov], res / "manifest/ci.json")
    _flip(tmp_path / NC, (tmp_path / NC).stat().st_size // 2)
    problems = verify(res / "manifest/ci.json", tmp_path)
    assert f"results/exports/grid.json: input {NC} changed since it was made: cannot be " \
           "decoded (NetCDF: HDF error)" in problems
    (tmp_path / PARQUET).unlink()
    assert f"{PARQUET}: missing" in verify(res / "manifest/ci.json", tmp_path)


def test_verify_unreadable_manifest_is_one_line(tmp_path, capsys):
    man = tmp_path / "results/manifest/ci.json"
    man.parent.mkdir(parents=True)
    man.write_text('{"artifacts": ')
    with pytest.raises(DataError, match=r"ci.json: not a oneocean manifest"):
        verify(man, tmp_path)
    good = tmp_path / "results/manifest/other.json"
    good.write_text(json.dumps({"schema": "oneocean-manifest/1", "artifacts": {}}))
    assert main(["verify", str(tmp_path / "results")]) == 1
    out, err = capsys.readouterr()
    assert "ci.json: not a oneocean manifest" in err and len(err.splitlines()) == 1
    assert "all 0 artifacts in" in out and "other.json" in out
