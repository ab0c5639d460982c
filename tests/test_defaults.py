"""A working env in a fresh install, without the workflow: the default grid built into the
cache (oneocean.product.defaults), resolve_grid's inputs and errors, the Gymnasium and PettingZoo ids
(oneocean.registration) and the CLI's one-line errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import oneocean
from oneocean.product import defaults
from oneocean.errors import ConfigError, DataError
from oneocean.io import sha256_file

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """A fresh cache folder (ONEOCEAN_CACHE_DIR) with the default grid built in it once."""
    root = tmp_path_factory.mktemp("oneocean_cache")
    mp = pytest.MonkeyPatch()
    mp.setenv(defaults.CACHE_ENV, str(root))
    # built from an empty folder: the build reads no file by the workflow's relative paths
    # it records (the checkout's results/ would otherwise be found)
    mp.chdir(tmp_path_factory.mktemp("empty_cwd"))
    t0 = time.perf_counter()
    path = defaults.default_grid_path()
    built_s = time.perf_counter() - t0
    mp.chdir(REPO)
    yield {"root": root, "path": path, "mtime": path.stat().st_mtime_ns, "built_s": built_s}
    mp.undo()


def _one_line(exc_info, *names) -> str:
    msg = str(exc_info.value)
    assert "\n" not in msg and msg.strip() == msg, msg
    for n in names:
        assert str(n) in msg, (n, msg)
    return msg


# ------------------------------------------------------------------------------ the default grid

def test_default_grid_builds_into_the_cache_and_records_its_hash(cache):
    path, root = cache["path"], cache["root"]
    assert path.is_relative_to(root) and path.name == "grid.npz"
    rel = path.relative_to(root).parts
    assert rel[:4] == ("grids", "synthetic_coast", "scene", path.parent.name)
    rec = json.loads((path.parent / "grid.json").read_text())
    assert rec["sha256"] == sha256_file(path)
    assert rec["bytes"] == path.stat().st_size
    assert rec["key"].startswith(path.parent.name) and len(rec["key"]) == 64
    assert (rec["region"], rec["variant"]) == ("synthetic_coast", "scene")
    assert rec["oneocean_version"] == oneocean.__version__
    assert rec["built"]["steps"] == list(defaults._STEPS)
    # the grid records the workflow's product path and config hash, like the workflow's export
    from oneocean.engine.grid import grid_metadata, load_grid

    meta = grid_metadata(path)
    assert meta["source_path"] == "results/product/synthetic_coast/scene/product.nc"
    assert meta["config_hash"] == rec["config_hash"]
    assert (meta["region"], meta["variant"], meta["source_kind"]) == (
        "synthetic_coast", "scene", "synthetic")
    g = load_grid(path)
    assert (g.nx, g.ny) == (161, 121) and g.uv.shape[:2] == (25, 6) and g.tide_layers == 1
    # nothing but the entry and its lock is left in the cache (no product, no temp folder)
    left = sorted(p.name for p in path.parent.parent.iterdir())
    assert left == [path.parent.name, f"{path.parent.name}.lock"]


def test_second_call_returns_the_cached_file_without_rebuilding(cache):
    t0 = time.perf_counter()
    again = defaults.default_grid_path()
    dt = time.perf_counter() - t0
    assert again == cache["path"]
    assert again.stat().st_mtime_ns == cache["mtime"]
    assert dt < 0.1, f"cached call took {dt:.3f} s"


def test_the_cache_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(defaults.CACHE_ENV, str(tmp_path / "c"))
    assert defaults.cache_dir() == tmp_path / "c"
    monkeypatch.delenv(defaults.CACHE_ENV)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert defaults.cache_dir() == tmp_path / ".cache" / "oneocean"


def test_the_key_changes_with_the_config_variant_and_version(monkeypatch):
    cfg = defaults.region_config()
    key = defaults.grid_key(cfg, "scene")
    assert defaults.grid_key(defaults.region_config(), "scene") == key     # deterministic
    assert defaults.grid_key(cfg, "tiny") != key
    other = defaults.region_config()
    other["synthetic"]["seed"] += 1
    assert defaults.grid_key(other, "scene") != key
    monkeypatch.setattr(defaults, "__version__", "9.9.9")
    assert defaults.grid_key(cfg, "scene") != key


def test_the_embedded_region_is_the_workflows_default():
    """config/config.yaml (the workflow's default) and the packaged region config give the
    same product configuration, and the default region's override file maps onto it."""
    from oneocean.config import DATA_SECTIONS, validate_config, validate_data_config
    from oneocean.product.build import product_config

    workflow = validate_config(yaml.safe_load((REPO / "config" / "config.yaml").read_text()))
    embedded = defaults.region_config()
    assert embedded == {k: workflow[k] for k in DATA_SECTIONS}
    assert validate_data_config(yaml.safe_load(defaults.DEFAULT_CONFIG.read_text())) == embedded
    for v in ("tiny", "scene", "public"):
        assert defaults._snapshot(embedded, v) == product_config(workflow, v)
    region = defaults.region_config(REPO / "config" / "regions" / "synthetic_coast.yaml")
    assert defaults.grid_key(region, "scene") == defaults.grid_key(embedded, "scene")


@pytest.fixture(scope="module")
def concurrent_tiny(tmp_path_factory):
    """Two processes asking for the tiny default grid at once, in an empty cache."""
    root = tmp_path_factory.mktemp("concurrent_cache")
    env = {**os.environ, defaults.CACHE_ENV: str(root)}
    code = ("import logging, sys; logging.basicConfig(level=logging.INFO, stream=sys.stderr);"
            " from oneocean.product.defaults import default_grid_path;"
            " print(default_grid_path('tiny'))")
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err
    return root, outs


def test_concurrent_first_uses_build_one_valid_grid(concurrent_tiny):
    from oneocean.engine.grid import load_grid

    root, outs = concurrent_tiny
    paths = {Path(out.strip()) for out, _ in outs}
    assert len(paths) == 1
    (path,) = paths
    builds = sum("building the tiny grid" in err for _, err in outs)
    assert builds == 1, [err for _, err in outs]
    rec = json.loads((path.parent / "grid.json").read_text())
    assert rec["sha256"] == sha256_file(path)
    assert sorted(p.name for p in path.parent.parent.iterdir()) == [
        path.parent.name, f"{path.parent.name}.lock"]
    assert load_grid(path).uv.shape[:2] == (13, 4)


def test_the_cached_grid_is_the_workflows_grid(concurrent_tiny, tmp_path, monkeypatch):
    """The workflow's steps (fetch_*, merge_variant, export_grid, as workflow/scripts call them,
    on config/config.yaml, in the workflow's folder layout) give the cached file byte for
    byte."""
    from oneocean.config import validate_config
    from oneocean.product.exports import export_grid
    from oneocean.product.build import build_product
    from oneocean.sources import fetch_bathymetry, fetch_currents

    root, outs = concurrent_tiny
    cached = Path(outs[0][0].strip())
    cfg = validate_config(yaml.safe_load((REPO / "config" / "config.yaml").read_text()))
    sec = lambda *k: {x: cfg[x] for x in k}   # noqa: E731  (config_section)
    monkeypatch.chdir(tmp_path)
    raw = "results/raw/synthetic_coast"
    fetch_currents(sec("region", "sources", "synthetic", "cmems", "files"),
                   f"{raw}/currents.nc", f"{raw}/download")
    fetch_bathymetry(sec("region", "sources", "synthetic", "gebco", "etopo", "files"),
                     f"{raw}/bathymetry.nc", f"{raw}/download")
    prod = "results/product/synthetic_coast/tiny"
    build_product(f"{raw}/currents.nc", f"{raw}/bathymetry.nc",
                  sec("region", "sources", "synthetic", "cmems", "gebco", "etopo", "files",
                      "variants"), "tiny", f"{prod}/product.nc", f"{prod}/metadata.json")
    out = "results/exports/synthetic_coast/tiny/grid.npz"
    export_grid(f"{prod}/product.nc", out, {"region": "synthetic_coast", "variant": "tiny"})
    assert sha256_file(out) == sha256_file(cached)


def test_an_unwritable_cache_is_a_one_line_error(monkeypatch, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(defaults.CACHE_ENV, str(blocker))
    with pytest.raises(DataError) as exc:
        defaults.default_grid_path("tiny")
    _one_line(exc, defaults.CACHE_ENV)


def test_unknown_variant_is_a_config_error():
    with pytest.raises(ConfigError) as exc:
        defaults.default_grid_path("huge")
    _one_line(exc, "'huge'", "tiny, scene, public")


# ------------------------------------------------------------------------------ resolve_grid

def test_resolve_grid_inputs(cache, tmp_path):
    from oneocean.engine.grid import Grid, load_grid
    from oneocean.testing import make_test_grid

    g = defaults.resolve_grid(None)
    assert isinstance(g, Grid) and (g.nx, g.ny) == (161, 121)
    assert defaults.resolve_grid(g) is g
    same = defaults.resolve_grid(str(cache["path"]))
    assert np.array_equal(same.uv, g.uv) and same.x0 == g.x0
    assert defaults.resolve_grid(cache["path"]).nx == 161
    m = make_test_grid(nt=2, nz=2, ny=5, nx=6)
    assert defaults.resolve_grid(m).nx == load_grid(m).nx == 6
    # a grid export stored as zarr (exports.format: zarr) gives the same grid
    from oneocean.product.zarrio import read_npz
    from oneocean.product.zarrio import write_arrays_zarr

    store = tmp_path / "grid.zarr"
    write_arrays_zarr(store, read_npz(cache["path"], "grid export"))
    z = defaults.resolve_grid(store)
    assert np.array_equal(z.uv, g.uv) and np.array_equal(z.elevation, g.elevation)
    assert (z.x0, z.nx, z.ny) == (g.x0, g.nx, g.ny)
    # the default region's override file is the same cache entry as the default
    assert defaults.region_grid_path(REPO / "config" / "regions" / "synthetic_coast.yaml") \
        == cache["path"]
    assert cache["path"].stat().st_mtime_ns == cache["mtime"]


def test_resolve_grid_errors_are_one_line_and_name_the_path(cache, tmp_path):
    missing = tmp_path / "nothere.npz"
    with pytest.raises(DataError) as exc:
        defaults.resolve_grid(missing)
    _one_line(exc, missing, "not found", "snakemake --cores 2", "grid=None")

    wf = tmp_path / "results" / "exports" / "my_region" / "scene" / "grid.npz"
    with pytest.raises(DataError) as exc:
        defaults.resolve_grid(wf)
    _one_line(exc, wf, "snakemake --cores 2 results/exports/my_region/scene/grid.npz "
              "--configfile config/regions/my_region.yaml")

    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip archive\n" * 10)
    with pytest.raises(DataError) as exc:
        defaults.resolve_grid(junk)
    _one_line(exc, junk, "not an .npz archive")

    partial = tmp_path / "partial.npz"
    np.savez(partial, u=np.zeros((1, 1, 2, 2), np.float32))
    with pytest.raises(DataError) as exc:
        defaults.resolve_grid(partial)
    _one_line(exc, partial, "missing fields")

    for bad in (tmp_path / "grid.nc", REPO / "README.md"):
        with pytest.raises(ConfigError) as exc:
            defaults.resolve_grid(bad)
        _one_line(exc, bad, "not a grid source", ".npz", ".yaml")

    with pytest.raises(DataError) as exc:
        defaults.resolve_grid(tmp_path)
    _one_line(exc, tmp_path, "folder")

    wz = tmp_path / "results" / "exports" / "my_region" / "scene" / "grid.zarr"
    with pytest.raises(DataError) as exc:
        defaults.resolve_grid(wz)
    _one_line(exc, wz, "not found", "results/exports/my_region/scene/grid.zarr",
              "\"format\": \"zarr\"")

    with pytest.raises(DataError) as exc:
        defaults.resolve_grid(tmp_path / "region.yaml")
    _one_line(exc, tmp_path / "region.yaml", "not found")

    with pytest.raises(ConfigError) as exc:
        defaults.resolve_grid(42)
    _one_line(exc, "int")


def _region(tmp_path, doc, name="r.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc) if isinstance(doc, dict) else doc)
    return path


def test_region_configs_that_cannot_be_built_offline(cache, tmp_path):
    cmems = _region(tmp_path, {"region": {"name": "remote"}, "sources": {"currents": "cmems"}})
    with pytest.raises(ConfigError) as exc:
        defaults.resolve_grid(cmems)
    _one_line(exc, cmems, "sources.currents is 'cmems'", "network")

    gebco = _region(tmp_path, {"region": {"name": "remote"},
                               "sources": {"bathymetry": "gebco"},
                               "gebco": {"url": "https://example.invalid/gebco"}}, "g.yaml")
    with pytest.raises(ConfigError) as exc:
        defaults.resolve_grid(gebco)
    _one_line(exc, gebco, "gebco.url", "network")

    files = _region(tmp_path, {
        "region": {"name": "local"},
        "sources": {"currents": "files", "bathymetry": "files", "tides": False},
        "files": {"currents": str(tmp_path / "cur.nc"), "bathymetry": str(tmp_path / "b.nc")}},
        "f.yaml")
    with pytest.raises(DataError) as exc:
        defaults.resolve_grid(files)
    _one_line(exc, files, "files.currents", tmp_path / "cur.nc", "not found")


def test_bad_region_configs_are_one_line_config_errors(cache, tmp_path):
    cases = {
        "typo.yaml": ({"regoin": {"name": "x"}}, "unknown key 'regoin'"),
        "type.yaml": ({"synthetic": {"seed": "abc"}}, "synthetic.seed"),
        "bbox.yaml": ({"region": {"name": "x", "bbox": {"west": 1.0, "east": 0.0}}},
                      "west must be less than east"),
        "list.yaml": ("- a\n- b\n", "top level must be a mapping"),
        "broken.yaml": ("region: {name: [\n", "not valid YAML"),
    }
    for name, (doc, needle) in cases.items():
        path = _region(tmp_path, doc, name)
        with pytest.raises(ConfigError) as exc:
            defaults.resolve_grid(path)
        _one_line(exc, path, needle)


# ------------------------------------------------------------------------------ registration

def test_import_registers_every_task_and_tier_cheaply():
    code = ("import sys, oneocean, gymnasium as gym;"
            " ids = sorted(e for e in gym.registry if e.startswith('OneOcean/'));"
            " bad = [m for m in sys.modules if m == 'numba' or m.startswith(("
            "'oneocean.envs', 'oneocean.tasks', 'oneocean.kernels', 'oneocean.engine'))];"
            " assert not bad, bad; print(len(ids))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True, cwd=REPO)
    from oneocean.registry import builtin_task_ids

    assert int(out.stdout) == 3 * len(builtin_task_ids())


def test_registered_specs_and_idempotence():
    import gymnasium as gym

    from oneocean.registration import env_ids, register_envs
    from oneocean.registry import builtin_task_ids, packaged_task_ids

    assert packaged_task_ids() == builtin_task_ids()
    ids = register_envs()
    assert register_envs() == ids == env_ids()                  # twice is fine
    assert ids[:3] == ("OneOcean/G2G-T1-v0", "OneOcean/G2G-T2-v0", "OneOcean/G2G-T3-v0")
    assert {i.split("/")[1].split("-")[0] for i in ids} == set(builtin_task_ids())
    spec = gym.spec("OneOcean/FT-T3-v0")
    assert spec.entry_point == "oneocean.envs:OceanEnv"
    assert spec.vector_entry_point == "oneocean.envs:OceanVectorEnv"
    assert spec.kwargs == {"task": "FT", "tier": 3}
    assert spec.max_episode_steps is None and spec.disable_env_checker is False


def _env_accepts_no_grid() -> bool:
    import inspect

    try:
        from oneocean import envs

        p = inspect.signature(envs.OceanEnv.__init__).parameters.get("grid")
    except Exception:   # noqa: BLE001 - the env module is not importable: the test fails
        return False
    return p is not None and p.default is None


@pytest.mark.xfail(not _env_accepts_no_grid(), strict=False,
                   reason="oneocean.envs.OceanEnv does not default grid to None yet")
def test_gymnasium_make_after_import(cache):
    import gymnasium as gym

    env = gym.make("OneOcean/SK-T1-v0")
    assert env.spec.id == "OneOcean/SK-T1-v0"
    obs, _ = env.reset(seed=3)
    assert obs.shape == env.observation_space.shape and np.isfinite(obs).all()
    obs, reward, term, trunc, _ = env.step(np.zeros(env.action_space.shape))
    assert obs.shape == env.observation_space.shape and reward == 0.0
    env.close()
    assert cache["path"].stat().st_mtime_ns == cache["mtime"]       # the cached grid


def test_parallel_ids_are_the_team_tasks(cache):
    from oneocean.registration import PARALLEL_IDS, make_parallel
    from oneocean.registry import builtin_task_ids, task_spec

    teams = [t for t in builtin_task_ids() if task_spec(t).agents_default > 1]
    assert teams and "G2G" not in teams and "FT" in teams
    assert dict(PARALLEL_IDS) == {f"OneOcean/{t}-T{k}-parallel-v0": (t, k)
                                  for t in teams for k in (1, 2, 3)}
    env = make_parallel("OneOcean/FT-T2-parallel-v0")
    n = task_spec("FT").agents_default
    assert env.possible_agents == [f"vehicle_{i}" for i in range(n)]
    env = make_parallel("OneOcean/FT-T2-parallel-v0", n_agents=3)
    assert env.possible_agents == ["vehicle_0", "vehicle_1", "vehicle_2"]


def test_unknown_parallel_id_lists_valid_ones():
    from oneocean.registration import make_parallel

    for bad in ("OneOcean/G2G-T1-parallel-v0", "OneOcean/FT-T2-v0", "nope"):
        with pytest.raises(ConfigError) as exc:
            make_parallel(bad)
        _one_line(exc, repr(bad), "OneOcean/FT-T1-parallel-v0")


# ------------------------------------------------------------------------------ CLI

def test_cli_missing_grid_is_one_line_and_exit_2(capsys, tmp_path):
    from oneocean.cli import main

    missing = tmp_path / "nothere.npz"
    rc = main(["evaluate", "--task", "G2G", "--tier", "1", "--policy", "numpy:zeros_like",
               "--grid", str(missing), "--out", str(tmp_path / "o.parquet")])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and err.startswith("oneocean evaluate: ")
    assert str(missing) in err and "not found" in err and "Traceback" not in err


@pytest.mark.parametrize("args, needle", [
    (["--policy", "nope_module_x:act"], "cannot import module 'nope_module_x'"),
    (["--policy", "numpy"], "expected 'module:callable'"),
    (["--grid", "README.md"], "not a grid source"),
    (["--out", "."], "is a folder"),
    (["--task", "NOPE"], "'NOPE'"),
])
def test_cli_expected_errors_are_one_line(cache, capsys, tmp_path, args, needle):
    from oneocean.cli import main

    base = {"--task": "G2G", "--policy": "numpy:zeros_like", "--grid": str(cache["path"]),
            "--out": str(tmp_path / "o.parquet")}
    base.update(dict(zip(args[::2], args[1::2])))
    argv = ["evaluate", "--tier", "1"] + [x for kv in base.items() for x in kv]
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and needle in err, err
    assert "Traceback" not in err


def test_cli_entry_point_prints_one_line(tmp_path):
    res = subprocess.run([sys.executable, "-m", "oneocean.cli", "evaluate", "--task", "G2G",
                          "--tier", "1", "--policy", "numpy:zeros_like", "--grid",
                          "/nonexistent/grid.npz", "--out", str(tmp_path / "o.parquet")],
                         capture_output=True, text=True)
    assert res.returncode == 2
    assert res.stderr.splitlines() == [res.stderr.strip()]
    assert res.stderr.startswith("oneocean evaluate: /nonexistent/grid.npz: grid export not found")


def test_evaluate_defaults_to_no_grid():
    import inspect

    from oneocean.evaluate import evaluate, evaluate_to_file

    assert inspect.signature(evaluate).parameters["grid"].default is None
    assert inspect.signature(evaluate_to_file).parameters["grid_path"].default is None

