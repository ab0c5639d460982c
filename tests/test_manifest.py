"""Provenance records, manifest collection and `oneocean verify`."""

import json

import numpy as np
import xarray as xr

from oneocean.cli import main
from oneocean.io import write_npz_atomic
from oneocean.pipeline.manifest import collect_manifest, verify, write_job_provenance


def _make_job(tmp_path):
    res = tmp_path / "results"
    (res / "raw").mkdir(parents=True)
    inp = res / "raw" / "in.txt"
    inp.write_text("input")
    out = res / "exports" / "grid.npz"
    write_npz_atomic(out, {"a": np.arange(4)})
    nc = res / "product" / "p.nc"
    nc.parent.mkdir(parents=True)
    xr.Dataset({"u": ("x", np.arange(3.0))}).to_netcdf(nc)
    prov = res / "provenance" / "job.json"
    write_job_provenance(prov, "export_grid", {"variant": "tiny"},
                         [out.relative_to(tmp_path), nc.relative_to(tmp_path)],
                         [inp.relative_to(tmp_path)], {"k": 1})
    return res, prov, inp, out, nc


def test_provenance_record_fields(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res, prov, inp, out, nc = _make_job(tmp_path)
    job = json.loads(prov.read_text())
    assert job["rule"] == "export_grid" and job["wildcards"] == {"variant": "tiny"}
    rec = {o["path"]: o for o in job["outputs"]}
    assert set(rec) == {"results/exports/grid.npz", "results/product/p.nc"}
    assert rec["results/exports/grid.npz"]["bytes"] == out.stat().st_size
    assert "content_sha256" in rec["results/product/p.nc"]
    assert job["inputs"][0]["path"] == "results/raw/in.txt"
    assert job["packages"]["numpy"] == np.__version__
    assert "git_commit" in job and job["params"] == {"k": 1}


def test_verify_passes_then_names_changed_artifact_and_input(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    res, prov, inp, out, nc = _make_job(tmp_path)
    man = res / "manifest" / "region.json"   # the workflow's layout: one per region
    collect_manifest([prov], man)
    assert verify(man, tmp_path) == []
    assert main(["verify", str(res)]) == 0
    assert main(["verify", str(man)]) == 0

    write_npz_atomic(out, {"a": np.arange(5)})  # artifact bytes changed
    problems = verify(man, tmp_path)
    assert len(problems) == 1 and "results/exports/grid.npz" in problems[0]
    assert main(["verify", str(res)]) == 1
    assert "results/exports/grid.npz" in capsys.readouterr().out


def test_verify_names_artifact_whose_input_changed(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res, prov, inp, out, nc = _make_job(tmp_path)
    collect_manifest([prov], res / "manifest.json")
    inp.write_text("different input")
    problems = verify(res / "manifest.json", tmp_path)
    assert any("input results/raw/in.txt changed" in p for p in problems)


def test_verify_accepts_netcdf_with_same_content_but_other_bytes(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res, prov, inp, out, nc = _make_job(tmp_path)
    collect_manifest([prov], res / "manifest.json")
    # rewrite with a different on-disk format but identical decoded content
    ds = xr.load_dataset(nc)
    ds.to_netcdf(nc, format="NETCDF3_64BIT")
    assert verify(res / "manifest.json", tmp_path) == []
    ds["u"][:] = 7.0
    ds.to_netcdf(nc)
    assert any("p.nc" in p for p in verify(res / "manifest.json", tmp_path))


def test_verify_without_manifest_exits_2(tmp_path):
    assert main(["verify", str(tmp_path)]) == 2
