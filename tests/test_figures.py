"""The paper's result figures (``oneocean.reporting.figures``): Fig. 3, 4, 6 and 7.

Every figure is written as PNG + PDF, byte-stable (rendered twice: same bytes), readable at
the expected size, and returns the numbers it plotted; those are checked against the inputs.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from oneocean.engine import write_metrics
from oneocean.errors import DataError
from oneocean.reporting.figures import (DPI, ladder_numbers, plot_current_field, plot_ladder,
                              plot_pollution_species, plot_rl_curves, plot_team_sweep,
                              rl_curve_numbers, team_sweep_numbers)
from oneocean.reporting.stats import wilson


def _read_png(path):
    from matplotlib.image import imread

    return imread(path)


def _assert_twice_identical(render, tmp_path, name="fig"):
    """Render into two folders; PNG and PDF bytes identical, valid, no volatile metadata,
    nothing else left in the folders. Returns the first PNG's path."""
    a, b = tmp_path / "a" / f"{name}.png", tmp_path / "b" / f"{name}.png"
    render(a)
    render(b)
    for p, q in ((a, b), (a.with_suffix(".pdf"), b.with_suffix(".pdf"))):
        assert p.read_bytes() == q.read_bytes(), p.name
    png, pdf = a.read_bytes(), a.with_suffix(".pdf").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert pdf[:5] == b"%PDF-"
    assert b"Software" not in png[:4000]
    for key in (b"CreationDate", b"Producer", b"Creator"):
        assert key not in pdf
    assert sorted(x.name for x in a.parent.iterdir()) == [f"{name}.pdf", f"{name}.png"]
    return a


# ------------------------------------------------------------------------------------------
# Fig. 3
# ------------------------------------------------------------------------------------------

def _product(path, wall_east: bool = False):
    """A small product NetCDF (contracts §2 subset Fig. 3 reads): a basin with a land corner
    (NaN currents on land) and a rotating current; ``wall_east``: flat seabed at -100 m with
    a tall land wall along the east edge instead."""
    lat = np.linspace(50.0, 50.1, 31)
    lon = np.linspace(-4.5, -4.35, 41)
    LON, LAT = np.meshgrid(lon, lat)
    x = (LON - lon[0]) / np.ptp(lon)
    y = (LAT - lat[0]) / np.ptp(lat)
    if wall_east:
        elev = np.where(x > 0.85, 300.0, -100.0)
    else:
        elev = -200.0 + 150.0 * np.sin(3 * x) * np.cos(2 * y) + 300.0 * (x + y > 1.6)
    cx, cy = x - 0.4, y - 0.4
    u = np.where(elev < 0, -cy * 0.8 + 0.1, np.nan)
    v = np.where(elev < 0, cx * 0.8, np.nan)
    depth = np.array([0.5, 10.0])
    time = np.array(["2025-01-01T00:00:00"], dtype="datetime64[ns]")
    shape = (1, 2) + u.shape
    ds = xr.Dataset(
        {"elevation": (("latitude", "longitude"), elev),
         "u": (("time", "depth", "latitude", "longitude"), np.broadcast_to(u, shape).copy()),
         "v": (("time", "depth", "latitude", "longitude"),
               np.broadcast_to(v, shape).copy() * np.array([1.0, 0.5])[None, :, None, None])},
        coords={"time": time, "depth": depth, "latitude": lat, "longitude": lon},
        attrs={"region": "test", "variant": "tiny", "source": "synthetic"})
    ds.to_netcdf(path)
    return path


@pytest.fixture(scope="module")
def product(tmp_path_factory):
    return _product(tmp_path_factory.mktemp("product") / "product.nc")


def test_fig3_png_and_pdf_byte_stable_and_sized(product, tmp_path):
    stats = {}

    def render(out):
        stats.update(plot_current_field(product, out, pitch_deg=25, azimuth_deg=45,
                                        depth_m=0.0))

    png = _assert_twice_identical(render, tmp_path, "current_field")
    img = _read_png(png)
    assert img.shape[0] == round(3.6 * DPI) and img.shape[1] > 4 * DPI
    assert img.shape[2] in (3, 4)
    assert img[..., :3].std() > 0.05          # not blank
    assert stats["depth_m"] == 0.5
    assert stats["arrows_3d"] > 0 and stats["arrows_map"] > 0
    assert stats["pdf"].endswith("current_field.pdf")
    # the view and the level reach the image
    other = tmp_path / "other.png"
    plot_current_field(product, other, pitch_deg=40, azimuth_deg=-60, depth_m=10.0)
    assert other.read_bytes() != png.read_bytes()


def test_fig3_terrain_hides_arrows_behind_a_wall(tmp_path):
    walled = _product(tmp_path / "wall.nc", wall_east=True)
    # viewer in the east, looking west over the wall: arrows close behind it are hidden
    behind = plot_current_field(walled, tmp_path / "east.png", pitch_deg=15, azimuth_deg=0)
    # viewer in the west over the flat seabed: nothing in the way
    front = plot_current_field(walled, tmp_path / "west.png", pitch_deg=15, azimuth_deg=180)
    assert behind["arrows_hidden"] > 0
    assert front["arrows_hidden"] == 0
    assert behind["arrows_3d"] + behind["arrows_hidden"] == front["arrows_3d"]


def test_fig3_no_current_raises_and_writes_nothing(tmp_path):
    p = _product(tmp_path / "p.nc")
    with xr.open_dataset(p) as ds:
        ds = ds.load()
    ds["u"][:] = np.nan
    ds.to_netcdf(tmp_path / "dry.nc")
    with pytest.raises(DataError, match="no current"):
        plot_current_field(tmp_path / "dry.nc", tmp_path / "out" / "f.png")
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())


# ------------------------------------------------------------------------------------------
# Fig. 4
# ------------------------------------------------------------------------------------------

_SMALL4 = {"times_s": (60.0, 300.0, 600.0), "dt_s": 20.0, "nx": 40, "nz": 28, "h_m": 20.0}


def test_fig4_deterministic_for_a_seed_and_masses_match_fields(tmp_path):
    from oneocean.models.pollution import species_mass

    out = {}

    def render(path):
        out["r"] = plot_pollution_species(path, seed=3, **_SMALL4)

    png = _assert_twice_identical(render, tmp_path, "pollution")
    r = out["r"]
    img = _read_png(png)
    assert img.shape[1] == round(7.2 * DPI) and img.shape[0] > 3 * DPI
    f = r["fields"]
    assert f.shape == (3, 3, 28, 40) and (f >= 0).all()
    assert np.allclose(r["times_s"], [60.0, 300.0, 600.0])
    for c in range(3):
        for s in range(3):
            assert r["mass_kg"][s, c] == pytest.approx(species_mass(f[c], s, 20.0), rel=1e-12)
    # the reaction moves mass from fresh oil to the other species over time
    assert r["mass_kg"][0, -1] < r["mass_kg"][0, 0]
    assert r["mass_kg"][1, -1] > r["mass_kg"][1, 0] > 0 and r["mass_kg"][2, -1] > 0
    # budget terms: leak grows linearly, escaped and degraded are non-negative, non-decreasing
    assert np.allclose(r["emitted_kg"], 0.15 * (np.asarray(r["times_s"]) - 0.0))
    for key in ("escaped_kg", "degraded_kg"):
        assert (np.diff(r[key]) >= -1e-9).all() and r[key][0] >= -1e-9
    assert r["initial_kg"] == pytest.approx(1000.0, rel=1e-9)
    # another seed: another spill, other bytes
    other = plot_pollution_species(tmp_path / "s4.png", seed=4, **_SMALL4)
    assert not np.array_equal(other["fields"], f)
    assert (tmp_path / "s4.png").read_bytes() != png.read_bytes()


# ------------------------------------------------------------------------------------------
# Fig. 6
# ------------------------------------------------------------------------------------------

def _cell(path, task, tier, k, n, *, method="heuristic", currents=True, applicable=True,
          extra=None, **meta):
    df = pd.DataFrame({"success": np.arange(n) < k, "T_s": np.full(n, 100.0),
                       "E": np.full(n, 1.0), "coll_ratio": np.zeros(n)})
    for key, val in (extra or {}).items():
        df[key] = val
    rec = {"task": task, "tier": tier, "method": method, "currents": currents,
           "applicable": applicable, "n_agents": 1, **meta}
    if not applicable:
        rec["reason"] = "no site"
    write_metrics(df, path, meta=rec)
    return path


@pytest.fixture
def ladder_cells(tmp_path):
    d = tmp_path / "cells"
    d.mkdir()
    k = {("G2G", 1): 20, ("G2G", 2): 18, ("G2G", 3): 11,
         ("SK", 1): 19, ("SK", 2): 12, ("SK", 3): 5,
         ("RF", 1): 20, ("RF", 2): 20}
    files = [_cell(d / f"{t}{tier}.parquet", t, tier, kk, 20) for (t, tier), kk in k.items()]
    files += [
        _cell(d / "RF3.parquet", "RF", 3, 0, 20, applicable=False),        # n/a: skipped
        _cell(d / "SK3off.parquet", "SK", 3, 20, 20, currents=False),      # ablation: skipped
        _cell(d / "SK3oracle.parquet", "SK", 3, 20, 20, method="oracle"),  # other method
    ]
    return files, k


def _render(plot, files, tmp_path, name):
    """``plot(files, path)`` rendered twice (byte-identical); its result as ``{"r": ...}``
    and the PNG read back."""
    out = {}

    def render(path):
        out["r"] = plot(files, path)

    png = _assert_twice_identical(render, tmp_path, name)
    return out, _read_png(png)


def test_fig6_plots_the_wilson_rates_of_the_cells(ladder_cells, tmp_path):
    files, k = ladder_cells
    out, img = _render(plot_ladder, files, tmp_path, "ladder")
    assert img.shape[:2] == (round(2.7 * DPI), round(7.2 * DPI))
    rates, drops = out["r"]["rates"], out["r"]["drops"]
    # registry order, only the heuristic's applicable cells with currents on
    assert list(drops["task"]) == ["G2G", "SK", "RF"]
    assert len(rates) == len(k)
    for row in rates.itertuples():
        kk = k[(row.task, row.tier)]
        lo, hi = wilson(kk, 20)
        assert (row.k, row.n) == (kk, 20)
        assert row.sr == pytest.approx(100.0 * kk / 20)
        assert row.lo == pytest.approx(100.0 * lo) and row.hi == pytest.approx(100.0 * hi)
    d = drops.set_index("task")
    assert list(d.columns) == ["T1-T2", "T2-T3"]
    assert d.loc["G2G", "T1-T2"] == pytest.approx(10.0)
    assert d.loc["SK", "T2-T3"] == pytest.approx(35.0)
    assert d.loc["RF", "T1-T2"] == pytest.approx(0.0)
    assert math.isnan(d.loc["RF", "T2-T3"])            # Tier 3 not applicable


def test_fig6_task_selection_method_and_duplicates(ladder_cells, tmp_path):
    files, _ = ladder_cells
    rates, drops = ladder_numbers(files, tasks=["SK", "G2G"])
    assert list(drops["task"]) == ["SK", "G2G"]
    assert list(rates["task"].unique()) == ["SK", "G2G"]
    r = plot_ladder(files, tmp_path / "oracle.png", method="oracle")
    assert r["rates"][["task", "tier", "k"]].values.tolist() == [["SK", 3, 20]]
    dup = _cell(tmp_path / "dup.parquet", "SK", 2, 3, 20)
    with pytest.raises(DataError, match="more than one"):
        ladder_numbers(files + [dup])


# ------------------------------------------------------------------------------------------
# Fig. 7
# ------------------------------------------------------------------------------------------

@pytest.fixture
def sweep_cells(tmp_path):
    rng = np.random.default_rng(0)
    d = tmp_path / "sweep"
    d.mkdir()
    files, frames = [], {}
    for n_agents in (2, 3, 5, 4):           # file order must not matter
        n = 8
        cr = np.clip(0.4 + 0.05 * n_agents + 0.05 * rng.standard_normal(n), 0, 1)
        succ = cr >= 0.6
        df = pd.DataFrame({"success": succ, "cleanup_rate": cr,
                           "T_s": np.where(succ, 500.0 - 20 * n_agents + rng.uniform(0, 50, n),
                                           850.0),
                           "coll_ratio": rng.uniform(0, 0.02 * n_agents, n),
                           "E": 1000.0 * n_agents + rng.uniform(0, 100, n)})
        p = d / f"n{n_agents}.parquet"
        write_metrics(df, p, meta={"task": "SPC", "tier": 2, "method": "heuristic",
                                   "n_agents": n_agents, "applicable": True, "currents": True,
                                   "tier_params": {"target_fraction": 0.65}})
        files.append(p)
        frames[n_agents] = df
    return files, frames


def test_fig7_plots_the_per_team_size_numbers(sweep_cells, tmp_path):
    files, frames = sweep_cells
    out, img = _render(plot_team_sweep, files, tmp_path, "team_sweep")
    assert img.shape[:2] == (round(2.6 * DPI), round(7.2 * DPI))
    sw = out["r"]["sweep"]
    assert list(sw["n_agents"]) == [2, 3, 4, 5]
    for row in sw.itertuples():
        df = frames[row.n_agents]
        kk, n = int(df["success"].sum()), len(df)
        lo, hi = wilson(kk, n)
        assert (row.k, row.n) == (kk, n)
        assert row.sr == pytest.approx(100.0 * kk / n)
        assert row.sr_lo == pytest.approx(100.0 * lo) and row.sr_hi == pytest.approx(100.0 * hi)
        assert row.cleanup == pytest.approx(100.0 * df["cleanup_rate"].mean())
        assert row.cleanup_lo <= row.cleanup <= row.cleanup_hi
        assert row.T_s == pytest.approx(df["T_s"].mean())
        assert row.T_lo <= row.T_s <= row.T_hi
        assert row.coll_pct == pytest.approx(100.0 * df["coll_ratio"].mean())
        assert row.E == pytest.approx(df["E"].mean())
    assert (sw["task"] == "SPC").all() and (sw["tier"] == 2).all()
    assert sw["target_pct"].iloc[0] == pytest.approx(65.0)
    # the same numbers whatever the file order
    pd.testing.assert_frame_equal(team_sweep_numbers(files[::-1]), sw)


def test_fig7_rejects_mixed_or_duplicate_cells(sweep_cells, tmp_path):
    files, frames = sweep_cells
    dup = tmp_path / "dup.parquet"
    write_metrics(frames[2], dup, meta={"task": "SPC", "tier": 2, "method": "heuristic",
                                        "n_agents": 2, "applicable": True, "currents": True})
    with pytest.raises(DataError, match="more than one cell per team size"):
        team_sweep_numbers(files + [dup])
    other = tmp_path / "t3.parquet"
    write_metrics(frames[2], other, meta={"task": "SPC", "tier": 3, "method": "heuristic",
                                          "n_agents": 7, "applicable": True, "currents": True})
    with pytest.raises(DataError, match="more than one"):
        team_sweep_numbers(files + [other])
    na = tmp_path / "na.parquet"
    write_metrics(frames[2], na, meta={"task": "SPC", "tier": 2, "method": "heuristic",
                                       "n_agents": 9, "applicable": False, "currents": True})
    assert 9 not in set(team_sweep_numbers(files + [na])["n_agents"])


def test_team_sweep_in_a_region_that_cannot_host_it_is_a_note_not_a_crash(tmp_path):
    import pandas as pd

    from oneocean.engine.recording import write_metrics
    from oneocean.reporting.figures import plot_team_sweep

    f = tmp_path / "na.parquet"
    write_metrics(pd.DataFrame({"success": pd.Series([], dtype=bool)}), f,
                  meta={"task": "SPC", "tier": 2, "method": "heuristic", "n_agents": 2,
                        "applicable": False, "reason": "no water", "currents": True})
    out = plot_team_sweep([f], tmp_path / "fig7.png")
    assert out["sweep"].empty
    assert out["png"] == str(tmp_path / "fig7.png") and out["pdf"] == str(tmp_path / "fig7.pdf")
    assert (tmp_path / "fig7.png").stat().st_size > 1000 and (tmp_path / "fig7.pdf").is_file()


def _report(path, task, selected, curves):
    """A training report as ``train_to_files`` writes it: one run per seed of ``curves``
    (``{seed: [(timesteps, episodes, success_rate, mean_reward), ...]}``)."""
    import json

    runs = [{"seed": s, "curve": [
        {"rollout": j, "timesteps": ts, "episodes": n, "success_rate": (sr if n else None),
         "mean_episode_return": (-5.0 + j if n else None), "mean_reward": mr}
        for j, (ts, n, sr, mr) in enumerate(c)]} for s, c in curves.items()]
    path.write_text(json.dumps({"method": "ppo", "task": task, "selected_seed": selected,
                                "runs": runs}))
    return path


def test_rl_curves_plot_the_kept_run_with_wilson_bands(tmp_path):
    g2g = _report(tmp_path / "g2g.json", "G2G", 3,
                  {0: [(100, 4, 0.0, -1.0)],
                   3: [(100, 0, None, -0.08), (200, 8, 0.25, -0.05), (300, 5, 0.6, -0.02)]})
    sk = _report(tmp_path / "sk.json", "SK", 0, {0: [(50, 2, 1.0, -0.1), (100, 3, 0.0, -0.3)]})
    out, img = _render(plot_rl_curves, [g2g, sk], tmp_path, "rl_curves")
    assert img.shape[:2] == (round(2.4 * DPI), round(7.2 * DPI))
    cv = out["r"]["curves"]
    # the kept run (seed 3) of G2G, then SK, in the reports' order
    assert list(cv["task"]) == ["G2G"] * 3 + ["SK"] * 2 and set(cv["seed"]) == {3, 0}
    assert list(cv["timesteps"]) == [100, 200, 300, 50, 100]
    assert list(cv["mean_reward"]) == [-0.08, -0.05, -0.02, -0.1, -0.3]
    assert list(cv["successes"]) == [0, 2, 3, 2, 0] and list(cv["episodes"]) == [0, 8, 5, 2, 3]
    # no episode ended: no rate, no interval
    assert cv[["success_pct", "success_lo", "success_hi"]].iloc[0].isna().all()
    for row in cv.iloc[1:].itertuples():
        lo, hi = wilson(row.successes, row.episodes)
        assert row.success_pct == pytest.approx(100.0 * row.successes / row.episodes)
        assert (row.success_lo, row.success_hi) == pytest.approx((100.0 * lo, 100.0 * hi))
    assert cv["mean_episode_return"].iloc[1] == -4.0


def test_rl_curves_name_the_bad_report(tmp_path):
    good = _report(tmp_path / "g.json", "SK", 0, {0: [(50, 2, 1.0, -0.1)]})
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(DataError, match=r"broken\.json: not a training report"):
        rl_curve_numbers([good, tmp_path / "broken.json"])
    (tmp_path / "nosel.json").write_text('{"task": "G2G", "runs": []}')
    with pytest.raises(DataError, match=r"nosel\.json: training report without 'selected_seed'"):
        rl_curve_numbers([tmp_path / "nosel.json"])
    lost = _report(tmp_path / "lost.json", "G2G", 7, {0: [(50, 2, 1.0, -0.1)]})
    with pytest.raises(DataError, match="without the run of its selected seed 7"):
        rl_curve_numbers([lost])
    with pytest.raises(DataError, match="a second training report of task SK"):
        rl_curve_numbers([good, good])
    import json

    rep = json.loads(good.read_text())
    del rep["runs"][0]["curve"][0]["mean_reward"]
    (tmp_path / "row.json").write_text(json.dumps(rep))
    with pytest.raises(DataError,
                       match=r"row\.json: a learning-curve row without \['mean_reward'\]"):
        rl_curve_numbers([tmp_path / "row.json"])
    with pytest.raises(DataError, match="no training report"):
        plot_rl_curves([], tmp_path / "none.png")
    assert not (tmp_path / "none.png").exists()


def test_saved_figures_have_a_frozen_rounded_layout(tmp_path):
    """save_figure runs constrained layout once, rounds every axes position to 1e-6 of the
    figure and switches the engine off: the solver's last-bit noise (it depends on what the
    process allocated before) cannot reach the PDF's coordinates. Two figures built with
    allocations in between give identical bytes."""
    from oneocean.reporting.figures import new_figure, paper_style, save_figure

    def build(path, junk):
        keep = [np.empty(3 * k + 1) for k in range(junk)]      # shifts later allocations
        with paper_style():
            fig = new_figure(6.0, 3.0)
            axs = fig.subplots(1, 2)
            for i, ax in enumerate(axs):
                ax.plot([0, 1, 2], [i, 2 * i + 1, 0.3], label=f"line {i}")
                ax.set_title(f"panel {i}")
                ax.legend(loc="upper right")
            fig.suptitle("frozen layout")
            save_figure(fig, path)
        del keep
        return fig

    fig = build(tmp_path / "a.png", 1)
    assert fig.get_layout_engine() is None or type(fig.get_layout_engine()).__name__ == \
        "PlaceHolderLayoutEngine"
    for ax in fig.axes:
        for v in ax.get_position().bounds:
            assert v == round(v, 6)
    x, y = fig._suptitle.get_position()
    assert (x, y) == (round(x, 6), round(y, 6))
    for junk in (7, 29, 113):
        build(tmp_path / f"b{junk}.png", junk)
        for ext in (".png", ".pdf"):
            assert (tmp_path / f"a{ext}").read_bytes() == \
                (tmp_path / f"b{junk}{ext}").read_bytes(), (junk, ext)
