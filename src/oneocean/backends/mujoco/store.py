"""Scene files on disk (what the workflow's ``scene_build`` writes and later jobs read) and the
scene jobs' pure functions: build a scene's files, load a scene back, render its media."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Mapping

import numpy as np

from ...errors import ConfigError, DataError
from ...product.zarrio import read_npz


def build_scene_files(spec: Mapping, grid_path, temporal_path, meta_out) -> dict:
    """Build a scene from a grid export and a temporal export and write its files.

    The scene is :func:`.scenes.build_scene` of ``spec``; its files (:func:`.scenes.scene_files`:
    ``scene.xml``, ``grid.npz``, ``scene.json``) go into the folder of ``meta_out``.

    Parameters
    ----------
    spec : mapping
        Scene spec (:func:`.scenes.build_scene`); its ``name`` must be the output folder's name.
    grid_path : path-like
        The product's grid export (``grid.npz``).
    temporal_path : path-like
        The product's temporal export.
    meta_out : path-like
        The ``scene.json`` to write; its folder receives every file.

    Returns
    -------
    dict
        The written paths, ``{"xml": path, "grid": path, "meta": path}``.

    Raises
    ------
    ConfigError
        If the spec's name does not match the folder, or the spec is invalid.
    DataError
        If an export is missing or malformed.
    """
    from .scenes import build_scene, scene_files

    out_dir = Path(meta_out).parent
    if spec.get("name") != out_dir.name:
        raise ConfigError(f"scenes.list: scene name {spec.get('name')!r} does not match its "
                          f"folder {out_dir.name!r}")
    scene = build_scene(spec, read_npz(grid_path, "grid export"),
                        read_npz(temporal_path, "temporal export"))
    return scene_files(scene, out_dir)


def load_scene(meta_path):
    """The :class:`.scenes.Scene` whose ``scene.json`` is ``meta_path``.

    Parameters
    ----------
    meta_path : path-like
        A ``scene.json`` written by :func:`build_scene_files` (its ``grid.npz`` beside it).

    Returns
    -------
    Scene
        The scene.

    Raises
    ------
    DataError
        If a file is missing or malformed (one line naming it).
    """
    from .scenes import Scene, Structure

    meta_path = Path(meta_path)
    try:
        meta = json.loads(meta_path.read_text())
    except FileNotFoundError:
        raise DataError(f"{meta_path}: scene file not found (built by the workflow's "
                        "scene_build rule)") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise DataError(f"{meta_path}: not a scene file ({exc.__class__.__name__})") from None
    try:
        structures = tuple(Structure(name=s["name"], centre=tuple(s["centre"]),
                                     half=tuple(s["half"]), yaw_rad=float(s["yaw_rad"]),
                                     kind=s["kind"]) for s in meta["structures"])
        clock = meta["clock"]
        return Scene(name=meta["name"], kind=meta["kind"], label=meta["label"],
                     grid_data=read_npz(meta_path.with_name("grid.npz"), "scene grid"),
                     structures=structures, extent=tuple(meta["extent_m"]),
                     anchor=(meta["anchor"]["lat"], meta["anchor"]["lon"]),
                     currents=meta["currents"],
                     clock=(float(clock["start_s"]), float(clock["rate"])), meta=meta)
    except (KeyError, TypeError) as exc:
        raise DataError(f"{meta_path}: scene file lacks {exc}") from None


def scene_media(scene, tasks, tiers, seed: int, dynamics: str, frames, media: Mapping,
                physics_step_s: float | None = None) -> dict:
    """Fig. 8's media of one scene: an episode of the heuristic, rendered offscreen.

    Episode 0 of ``seed`` of the heuristic in ``scene`` (the scene backend, every step's state
    traced), on the first (task, tier) of ``tasks`` x ``tiers`` (in that order: each task, its
    tiers from the highest) that the scene can host; the scene alone when it hosts none.
    Rendered by :func:`.media.render_media`.

    Parameters
    ----------
    scene : Scene
        The scene (:func:`load_scene`).
    tasks : sequence of str
        Task ids, in order of preference.
    tiers : iterable of int
        Tiers to try per task (highest first).
    seed : int
        Run seed.
    dynamics : str
        Dynamics model name (:data:`oneocean.vocab.DYNAMICS`).
    frames : sequence of path-like
        Output files: the keyframe PNGs ``<dir>/keyframe_<k>.png`` (k = 0, 1, ...), then the GIF.
    media : mapping
        The config's ``scenes.media`` (``width``, ``height`` in pixels, ``fps``).
    physics_step_s : float, optional
        MuJoCo's step, s; default: the scene backend's.

    Returns
    -------
    dict
        The renderer's record (``png``, ``gif``, ``frames``) plus ``task`` and ``tier`` (None:
        the scene alone).

    Raises
    ------
    ConfigError
        If the keyframe paths are not ``keyframe_<k>.png`` in order.
    """
    from ...engine.dynamics import STATE_DIM
    from ...errors import NotApplicable
    from ...tasks import Cell
    from .media import render_media

    frames = [Path(f) for f in frames]
    pngs, gif = frames[:-1], frames[-1]
    stem = pngs[0].with_name("keyframe")
    if [p.name for p in pngs] != [f"keyframe_{k}.png" for k in range(len(pngs))]:
        raise ConfigError(f"scene_media: keyframe paths must be {stem}_<k>.png, got "
                          f"{', '.join(map(str, pngs))}")
    traj, vehicle, which, current = None, "remus100", (None, None), None
    for task in tasks:
        for tier in sorted((int(k) for k in tiers), reverse=True):
            try:
                cell = Cell(None, task, tier, backend="mujoco", scene=scene,
                            physics_step_s=physics_step_s)
                init = cell.reset(1, int(seed))
            except NotApplicable:
                continue
            ep = cell.episodes(init, "heuristic", dynamics, int(seed), trace=True).run()
            traj, vehicle, which = ep.traced()[: int(ep.k[0]) + 1, 0], cell.vehicle, (task, tier)
            current = scene_current(scene, float(init["t0"][0]), cell.current_gain)
            break
        if traj is not None:
            break
    if traj is None:   # the scene alone: no vehicle shown (non-finite rows hide it)
        traj = np.full((2, 1, STATE_DIM), np.nan)
    out = render_media(scene, vehicle, traj, stem, gif, keyframes=len(pngs),
                       size=(int(media["width"]), int(media["height"])), fps=int(media["fps"]),
                       current=current)
    return {**out, "task": which[0], "tier": which[1]}


def scene_current(scene, t: float, gain: float = 1.0) -> tuple[float, float]:
    """The scene's mean surface current at a scene time (Fig. 8's arrow).

    Parameters
    ----------
    scene : Scene
        The scene (its ``grid_data``).
    t : float
        Scene time, s: the nearest earlier node of the scene's time axis is used.
    gain : float, optional
        Factor on the current (default 1).

    Returns
    -------
    tuple of float
        ``(east, north)``, m s-1: the mean over the scene's water nodes (0, 0 without water).
    """
    g = scene.grid_data
    ts = np.asarray(g["time_s"], dtype=np.float64)
    k = int(np.clip(np.searchsorted(ts, t, side="right") - 1, 0, ts.size - 1))
    water = np.asarray(g["valid_mask"])[0] == 1
    if not water.any():
        return (0.0, 0.0)
    u = float(np.mean(np.asarray(g["u"])[k, 0][water], dtype=np.float64))
    v = float(np.mean(np.asarray(g["v"])[k, 0][water], dtype=np.float64))
    return (gain * u, gain * v)


#: Fig. 8's panels: (task, tier, step) -- the team panel (formation transit, its episode's last
#: step) and the cleanup panel (surface pollution cleanup with its slick, at step 90).
PANELS = {"team": ("FT", 2, None), "cleanup": ("SPC", 1, 90)}


def scene_panel(scene, panel: str, seed: int, dynamics: str, png, media: Mapping,
                physics_step_s: float | None = None) -> dict:
    """One of Fig. 8's panels: episode 0 of ``seed`` of the heuristic in ``scene``, rendered.

    ``team``: formation transit (FT, Tier 2, the whole team) at its last step; ``cleanup``:
    surface pollution cleanup (SPC, Tier 1) at step 90 with its slick, the task's own
    scene-local field (the scene's grid, its structures land cells of the field), drawn at
    the surface. Both with the fog, the textured seafloor and the current's arrow.

    Parameters
    ----------
    scene : Scene
        The scene (:func:`load_scene`).
    panel : str
        ``"team"`` or ``"cleanup"`` (:data:`PANELS`).
    seed : int
        Run seed.
    dynamics : str
        Dynamics model name.
    png : path-like
        The PNG written.
    media : mapping
        The config's ``scenes.media`` (``width``, ``height``).
    physics_step_s : float, optional
        MuJoCo's step, s.

    Returns
    -------
    dict
        ``{"png", "task", "tier", "step", "agents"}``.
    """
    from ...tasks import Cell
    from .media import render_media

    if panel not in PANELS:
        raise ConfigError(f"scene_panel: panel must be one of {', '.join(PANELS)}, got "
                          f"{panel!r}")
    task, tier, step = PANELS[panel]
    png = Path(png)
    cell = Cell(None, task, tier, backend="mujoco", scene=scene, physics_step_s=physics_step_s)
    init = cell.reset(1, int(seed))
    ep = cell.episodes(init, "heuristic", dynamics, int(seed), trace=True)
    ep.run(step)
    k = int(ep.k[0])
    traj = ep.traced()[: k + 1, 0]
    field = None
    if task == "SPC":
        from ...tasks.spc import FIELD_H_M

        field = {"C": np.asarray(ep.W.C[0, 0]), "origin": np.asarray(ep.W.origin[0]),
                 "h": FIELD_H_M}
    stem = png.with_name(png.stem)
    out = render_media(scene, cell.vehicle, traj, stem, None, keyframes=1,
                       size=(int(media["width"]), int(media["height"])),
                       current=scene_current(scene, float(init["t0"][0]) + k * float(
                           cell.params["dt_s"]), cell.current_gain),
                       field=field, elevation_deg=-50.0)
    written = out["png"][0]
    written.replace(png)
    return {"png": png, "task": task, "tier": tier, "step": k, "agents": int(traj.shape[1])}
