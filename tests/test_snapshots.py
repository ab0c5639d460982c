"""Fig. 5 (``oneocean.reporting.snapshots``): one-episode snapshots of SPC, UPL, AS and FH.

The frames are the episode of ``Cell.reset`` (start = its start positions, the rollout cell's
row), the run in segments ends exactly where an uninterrupted run ends, what is read from the
task's work arrays agrees with the episode's own metrics, the figure is byte-stable and
returns those numbers, a task the region cannot host gets a note row, and the workflow
script writes the figure and its provenance."""

from __future__ import annotations

import json
import logging
import runpy
from pathlib import Path

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.errors import ConfigError, NotApplicable
from oneocean.reporting.figures import DPI, PAGE_IN
from oneocean.io import write_npz_atomic
from oneocean.reporting.snapshots import (FIG5_TASKS, TRAIL_EVERY, area_of_interest, episode_frames,
                                plot_snapshots)
from oneocean.tasks import Cell, spc
from oneocean.tasks.episodes import Episodes
from oneocean.testing import make_test_grid

TIER, SEED, METHOD, DYN = 2, 1000, "heuristic", "6dof"
TIMES = (0.0, 0.5, 1.0)
SCRIPT = Path(__file__).parents[1] / "workflow" / "scripts" / "figure_snapshots.py"


@pytest.fixture(scope="module")
def coast_path(tmp_path_factory):
    """A small analytic coast (hosts all four tasks at tier 2), as a grid export file."""
    path = tmp_path_factory.mktemp("grid") / "coast.npz"
    write_npz_atomic(path, make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
    return path


@pytest.fixture(scope="module")
def shallow_path(tmp_path_factory):
    """The same coast at most ~37 m deep: UPL (45-60 m sites) and AS (a shelf >= 30 m deep
    with relief) are not applicable at tier 2, FH is."""
    path = tmp_path_factory.mktemp("grid") / "shallow.npz"
    write_npz_atomic(path, make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0,
                                          max_depth_m=30.0))
    return path


@pytest.fixture(scope="module")
def coast(coast_path):
    return E.load_grid(coast_path)


@pytest.fixture(scope="module")
def frames(coast):
    """Episode 0 of each task's (tier 2, heuristic, seed 1000) cell, at 0, 1/2 and 1."""
    return {t: episode_frames(coast, t, TIER, METHOD, SEED, 0, TIMES, DYN) for t in FIG5_TASKS}


def _uninterrupted(coast, task, episodes=1):
    cell = Cell(coast, task, TIER)
    init = cell.reset(episodes, SEED)
    ep = Episodes(cell.mod, cell.grid, cell.params, init, METHOD, DYN, cell.vehicle, SEED)
    return init, ep.run()


# ------------------------------------------------------------------------------------------
# the frames
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("task", FIG5_TASKS)
def test_first_frame_is_the_episodes_start(coast, frames, task):
    ef = frames[task]
    init = Cell(coast, task, TIER).reset(1, SEED)
    f0 = ef.frames[0]
    assert (f0.frac, f0.k, f0.t_s) == (0.0, 0, 0.0)
    assert ef.candidate == int(init["candidate"][0])
    np.testing.assert_array_equal(f0.xz, init["pos0"][0][:, [0, 2]])
    np.testing.assert_array_equal(f0.depth, init["pos0"][0][:, 1])
    assert f0.trail.shape == (len(f0.xz), 1, 2) and list(f0.trail_k) == [0]
    if task == "SPC":
        np.testing.assert_array_equal(f0.field["C"], init["C0"][0, 0])
        assert f0.stats["initial_kg"] == pytest.approx(spc.SPILL_MASS_KG, rel=1e-9)
        assert f0.stats["removed_kg"] == 0.0 and f0.stats["escaped_kg"] == 0.0
    elif task == "UPL":
        np.testing.assert_array_equal(f0.field["obj"], init["obj0"][0])
        np.testing.assert_array_equal(f0.field["slots"], init["obj0"][0] + init["slot_off"][0])
        assert f0.stats["attached"] == 0.0 and f0.stats["drift_m"] == 0.0
    elif task == "AS":
        assert not f0.field["cov"].any() and f0.stats["coverage"] == 0.0
        np.testing.assert_array_equal(ef.static["region"], init["region"][0])
    else:
        np.testing.assert_array_equal(f0.field["fish"], init["fish0"][0].T)
        np.testing.assert_allclose(f0.field["centroid"], init["fish0"][0].mean(axis=1),
                                   rtol=0, atol=1e-9)
        np.testing.assert_array_equal(ef.static["zone"], init["zone"][0])


@pytest.mark.parametrize("task", FIG5_TASKS)
def test_last_frame_is_the_uninterrupted_run(coast, frames, task):
    """Segments do not change the physics: the last frame is the end state of one
    uninterrupted run, and what it reads from W equals the episode's own metrics."""
    ef = frames[task]
    _, ep = _uninterrupted(coast, task)
    res = ep.results()
    last = ef.frames[-1]
    assert last.k == ef.k_end == int(ep.k[0])
    assert last.t_s == pytest.approx(ef.k_end * ef.dt)
    np.testing.assert_array_equal(last.xz, ep.state[0][:, [0, 2]])
    np.testing.assert_array_equal(last.depth, ep.state[0][:, 1])
    assert ef.success == bool(res["success"][0])
    assert ef.metrics == {k: float(v[0]) for k, v in res.items()}
    s, m = last.stats, ef.metrics
    if task == "SPC":
        np.testing.assert_array_equal(last.field["C"], ep.W.C[0, 0])
        assert s["mass_kg"] / s["initial_kg"] == pytest.approx(m["remaining_fraction"],
                                                               rel=1e-12)
        assert s["removed_kg"] / s["initial_kg"] == pytest.approx(m["cleanup_rate"], rel=1e-12)
        assert s["escaped_kg"] / s["initial_kg"] == pytest.approx(m["escaped_fraction"],
                                                                  rel=1e-12, abs=1e-15)
    elif task == "UPL":
        assert s["object_depth_m"] == pytest.approx(m["final_object_depth_m"], rel=1e-12)
        assert s["drift_m"] == pytest.approx(m["object_drift_m"], rel=1e-12, abs=1e-12)
        np.testing.assert_array_equal(last.track[-1], last.field["obj"][[0, 2]])
    elif task == "AS":
        assert s["coverage"] == pytest.approx(m["coverage_fraction"], rel=1e-12)
        assert int(last.field["cov"].sum()) == round(m["coverage_fraction"]
                                                      * last.field["cov"].size)
    else:
        assert s["centroid_dist_m"] == pytest.approx(m["final_centroid_distance_m"],
                                                     rel=1e-12)
        assert s["fraction_inside"] == pytest.approx(m["fraction_inside"], abs=1e-12)
        np.testing.assert_array_equal(last.track[-1], last.field["centroid"])


@pytest.mark.parametrize("task", FIG5_TASKS)
def test_frames_at_fractions_of_the_actual_length_with_trails(frames, task):
    ef = frames[task]
    assert [f.k for f in ef.frames] == [round(f * ef.k_end) for f in TIMES]
    assert [f.t_s for f in ef.frames] == [f.k * ef.dt for f in ef.frames]
    assert 0 < ef.k_end <= ef.n_steps
    if task == "SPC":                      # runs to its metric horizon
        assert ef.k_end == ef.n_steps
    for f in ef.frames:
        assert f.trail_k[0] == 0 and f.trail_k[-1] == f.k
        assert np.all(np.diff(f.trail_k) > 0) and np.all(np.diff(f.trail_k) <= TRAIL_EVERY)
        np.testing.assert_array_equal(f.trail[:, -1], f.xz)
        assert f.track.shape == ((len(f.trail_k), 2) if task in ("UPL", "FH") else (0, 2))
    a, b = ef.frames[1], ef.frames[2]
    np.testing.assert_array_equal(b.trail[:, :a.trail.shape[1]], a.trail)   # trails grow


def test_spc_plume_shrinks_and_its_budget_closes(frames):
    ef = frames["SPC"]
    s = {k: np.array(v) for k, v in
         zip(ef.frames[0].stats, zip(*[f.stats.values() for f in ef.frames]))}
    h = ef.static["h"]
    assert np.all(np.diff(s["mass_kg"]) < 0)               # the heuristic cleans
    assert np.all(np.diff(s["removed_kg"]) > 0) and s["removed_kg"][-1] > 100.0
    np.testing.assert_allclose(s["mass_kg"] + s["removed_kg"] + s["escaped_kg"],
                               s["initial_kg"], rtol=1e-9)
    np.testing.assert_allclose(s["mass_kg"], [f.field["C"].sum() * h * h for f in ef.frames],
                               rtol=1e-12)


def test_coverage_grows_and_the_school_approaches_the_zone(frames):
    cov = [f.stats["coverage"] for f in frames["AS"].frames]
    assert cov[0] == 0.0 and cov[0] < cov[1] <= cov[2]
    covered = [f.field["cov"] for f in frames["AS"].frames]
    assert np.all(covered[1] <= covered[2])                  # a covered cell stays covered
    fh = frames["FH"]
    d = [f.stats["centroid_dist_m"] for f in fh.frames]
    assert d[-1] < d[0]
    if fh.success:
        assert d[-1] <= fh.static["zone_r"]
        assert fh.frames[-1].stats["hold_s"] >= fh.static["hold_s"] - 1e-9


@pytest.mark.parametrize("task", ["UPL", "AS"])
def test_the_episode_is_the_rollout_cells_episode(coast, task):
    """Episode 1 of a 3-episode cell: the same start, candidate and results as that cell's
    row 1 (AS and UPL judge their current regime on depths that vary by candidate)."""
    ef = episode_frames(coast, task, TIER, METHOD, SEED, episode=1, times=(0.0, 1.0),
                        episodes=3)
    init = Cell(coast, task, TIER).reset(3, SEED)
    df = Cell(coast, task, TIER).run(METHOD, 3, SEED, DYN)
    row = df.iloc[1]
    np.testing.assert_array_equal(ef.frames[0].xz, init["pos0"][1][:, [0, 2]])
    assert ef.candidate == int(row["candidate"]) == int(init["candidate"][1])
    assert ef.success == bool(row["success"])
    for col in ("T_s", "E", "primary"):
        key = df.attrs["primary"] if col == "primary" else col
        assert ef.metrics[key] == float(row[col]), col


def test_bad_requests_are_config_errors(coast):
    with pytest.raises(ConfigError, match="fractions"):
        episode_frames(coast, "FH", times=(0.0, 1.5))
    with pytest.raises(ConfigError, match="episode 3"):
        episode_frames(coast, "FH", episode=3, episodes=3)


# ------------------------------------------------------------------------------------------
# the figure
# ------------------------------------------------------------------------------------------

def test_figure_is_byte_stable_and_returns_its_numbers(coast_path, frames, tmp_path):
    a, b = tmp_path / "a" / "snap.png", tmp_path / "b" / "snap.png"
    out = plot_snapshots(coast_path, a, tier=TIER, seed=SEED, method=METHOD)
    out_b = plot_snapshots(coast_path, b, tier=TIER, seed=SEED, method=METHOD)
    for p, q in ((a, b), (a.with_suffix(".pdf"), b.with_suffix(".pdf"))):
        assert p.read_bytes() == q.read_bytes(), p.name
    png, pdf = a.read_bytes(), a.with_suffix(".pdf").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and pdf[:5] == b"%PDF-"
    assert b"Software" not in png[:4000]
    for key in (b"CreationDate", b"Producer", b"Creator"):
        assert key not in pdf
    assert sorted(x.name for x in a.parent.iterdir()) == ["snap.pdf", "snap.png"]
    from matplotlib.image import imread

    assert imread(a).shape[1] == round(PAGE_IN * DPI)
    # the numbers: the frames' times, the episodes' outcomes, JSON-able for a provenance file
    drop = ("png", "pdf")
    assert json.loads(json.dumps({k: v for k, v in out.items() if k not in drop})) == \
        {k: v for k, v in out_b.items() if k not in drop}
    assert (out["png"], out["pdf"]) == (str(a), str(a.with_suffix(".pdf")))
    assert list(out["tasks"]) == list(FIG5_TASKS)
    for task, ef in frames.items():
        row = out["tasks"][task]
        assert row["applicable"] is True
        assert row["times_s"] == [f.t_s for f in ef.frames]
        assert row["steps"] == [f.k for f in ef.frames]
        assert row["success"] == ef.success and row["k_end"] == ef.k_end
        assert row["metrics"] == ef.metrics
        for k, v in row["stats"].items():
            assert v == [f.stats[k] for f in ef.frames]
        # the crop holds every agent's trail
        cx, cz, half = area_of_interest(ef)
        assert row["aoi"] == {"cx_m": cx, "cz_m": cz, "half_m": half}
        pts = ef.frames[-1].trail.reshape(-1, 2)
        assert np.all(np.abs(pts - [cx, cz]) <= half)
    assert out["tasks"]["SPC"]["stats"]["mass_kg"][-1] < out["tasks"]["SPC"]["stats"][
        "mass_kg"][0]


def test_a_task_the_region_cannot_host_gets_a_note_row(shallow_path, tmp_path):
    with pytest.raises(NotApplicable, match="UPL tier 2"):
        episode_frames(E.load_grid(shallow_path), "UPL", TIER)
    out = plot_snapshots(shallow_path, tmp_path / "na.png", tasks=("UPL", "FH"))
    assert out["tasks"]["UPL"]["applicable"] is False
    assert "UPL tier 2" in out["tasks"]["UPL"]["reason"]
    assert out["tasks"]["FH"]["applicable"] is True and len(out["tasks"]["FH"]["times_s"]) == 3
    assert (tmp_path / "na.png").stat().st_size > 0 and (tmp_path / "na.pdf").stat().st_size > 0
    # a figure of note rows only is still a figure
    only = plot_snapshots(shallow_path, tmp_path / "none.png", tasks=("UPL",))
    assert only["tasks"] == {"UPL": {"applicable": False,
                                     "reason": out["tasks"]["UPL"]["reason"]}}
    assert (tmp_path / "none.pdf").is_file()


class _Named(dict):
    """A stand-in for Snakemake's named lists: attributes, ``items()``, values on iteration."""

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None

    def __iter__(self):
        return iter(self.values())


def test_workflow_script_writes_the_figure_and_its_provenance(shallow_path, tmp_path):
    out = tmp_path / "results" / "figures" / "snapshots.png"
    prov = tmp_path / "results" / "provenance" / "snapshots.json"
    smk = type("Snakemake", (), {})()
    smk.rule = "figure_snapshots"
    smk.config = {}
    smk.input = _Named(grid=str(shallow_path))
    smk.output = _Named(png=str(out), pdf=str(out.with_suffix(".pdf")), prov=str(prov))
    smk.params = _Named(tasks=["FH", "UPL"], tier=TIER, seed=SEED, method=METHOD, episode=0,
                        episodes=2, dynamics="6dof")
    smk.wildcards = _Named()
    smk.log = [str(tmp_path / "logs" / "snapshots.log")]
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    try:
        runpy.run_path(str(SCRIPT), init_globals={"snakemake": smk}, run_name="__main__")
    finally:
        for h in root.handlers:
            if h not in handlers:
                h.close()
        root.handlers[:] = handlers
        root.setLevel(level)
    assert out.is_file() and out.with_suffix(".pdf").is_file()
    rec = json.loads(prov.read_text())
    assert rec["rule"] == "figure_snapshots"
    assert sorted(Path(o["path"]).name for o in rec["outputs"]) == ["snapshots.pdf",
                                                                    "snapshots.png"]
    assert rec["params"] == {"tasks": ["FH", "UPL"], "tier": TIER, "seed": SEED,
                             "method": METHOD, "episode": 0, "episodes": 2,
                             "dynamics": "6dof"}
    direct = tmp_path / "direct.png"
    plot_snapshots(shallow_path, direct, tasks=("FH", "UPL"), tier=TIER, seed=SEED,
                   method=METHOD, episode=0, episodes=2, dynamics="6dof")
    assert direct.read_bytes() == out.read_bytes()
