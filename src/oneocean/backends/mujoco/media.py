"""Offscreen media of a scene episode (Fig. 8): keyframe PNGs and an animated GIF.

The trajectory's vehicles are placed as kinematic bodies in one model (the scene with N copies
of the vehicle, :func:`.mjcf.scene_xml` with ``n_vehicles``; no physics is stepped) and drawn
with :class:`mujoco.Renderer` under ``MUJOCO_GL=egl``: the backend is chosen when MuJoCo is
first imported, so every module of this package imports MuJoCo lazily through
:func:`.mjcf.import_mujoco`, which sets ``MUJOCO_GL=egl`` unless already set. A free camera looks
at the agents' bounding box over the heightfield from a fixed azimuth and elevation; each
vehicle gets a translucent marker sphere (visible at scene scale) and the track it has
travelled so far. The water is drawn as MuJoCo fog fading with range (blue-green, set in the
MJCF, switched on here), an arrow at the surface shows the current's direction, and a surface
field (a slick) can be overlaid as translucent cells. Images are written with Pillow (PNG, GIF), atomically.
"""

from __future__ import annotations

import io
import os

import numpy as np

from ...engine import dynamics as dyn
from ...errors import ConfigError, DataError

__all__ = ["render_media"]

_COLOURS = ((0.95, 0.75, 0.1), (0.9, 0.3, 0.2), (0.2, 0.8, 0.4), (0.3, 0.5, 0.95),
            (0.85, 0.4, 0.85), (0.1, 0.85, 0.85), (0.95, 0.55, 0.2), (0.6, 0.6, 0.9))
#: Largest number of frames put in the GIF (the trajectory is subsampled evenly).
MAX_GIF_FRAMES = 150


def render_media(scene, vehicle, trajectory, out_png_stem, gif_path, *, keyframes: int = 3,
                 size: tuple = (480, 360), fps: int = 10, azimuth_deg: float = 135.0,
                 elevation_deg: float = -35.0, current=None, field=None) -> dict:
    """Render keyframe PNGs and an animated GIF of agents moving through a scene.

    Parameters
    ----------
    scene : Scene
        The scene (:class:`oneocean.backends.mujoco.scenes.Scene`).
    vehicle : str, Vehicle or VehicleModel
        The vehicle drawn for every agent (:func:`.mjcf.vehicle_model`).
    trajectory : (T, N, STATE_DIM) float64
        Core states over time (positions and attitudes are used; non-finite rows hide the
        vehicle).
    out_png_stem : path-like
        Keyframes are written to ``<stem>_<k>.png``, k = 0..keyframes-1 (evenly spaced over T,
        first and last included).
    gif_path : path-like or None
        Animated GIF of the whole trajectory (at most :data:`MAX_GIF_FRAMES` frames); None:
        no GIF.
    keyframes : int, default 3
        Number of keyframe PNGs (>= 1; a trajectory shorter than that repeats frames, so
        the scene alone, with no task to fly, still gives every keyframe).
    size : (width, height), default (480, 360)
        Image size, pixels (16..1280 x 16..960).
    fps : int, default 10
        GIF frame rate, frames per second.
    azimuth_deg, elevation_deg : float
        Camera azimuth and elevation (MuJoCo's free-camera convention, degrees; defaults 135
        and -35).
    current : (float, float), optional
        The current (east, north), m s-1, drawn as an arrow at the surface above the view's
        centre (length 0.2 of the camera distance per m s-1, at least 0.3 m s-1 of it).
    field : dict, optional
        A surface field drawn as translucent dark cells at the surface: ``C`` (nz, nx) values
        (kg m-2), ``origin`` (x, z) of cell (0, 0)'s centre (world m), ``h`` the cell size (m);
        cells above 2 % of the maximum are drawn, opacity growing with the value.

    Returns
    -------
    dict
        ``{"png": [paths], "gif": path, "frames": int}``.

    Raises
    ------
    DataError
        Offscreen rendering is unavailable (no EGL / OpenGL context).
    ConfigError
        Bad shapes or sizes.
    """
    from pathlib import Path

    from PIL import Image

    from ...io import write_bytes_atomic
    from . import mjcf

    traj = np.asarray(trajectory, dtype=np.float64)
    if traj.ndim != 3 or traj.shape[2] != dyn.STATE_DIM or traj.shape[0] < 1 or traj.shape[1] < 1:
        raise ConfigError(f"render_media: trajectory must be (T, N, {dyn.STATE_DIM}), "
                          f"got {traj.shape}")
    width, height = int(size[0]), int(size[1])
    if not (16 <= width <= 1280 and 16 <= height <= 960):
        raise ConfigError(f"render_media: size must be within 16..1280 x 16..960, got {size}")
    if keyframes < 1 or fps < 1:
        raise ConfigError("render_media: keyframes and fps must be >= 1")
    T, N = traj.shape[:2]
    if current is not None:
        current = np.asarray(current, dtype=np.float64).reshape(2)
    mujoco = mjcf.import_mujoco()
    model = mujoco.MjModel.from_xml_string(mjcf.scene_xml(scene, vehicle, n_vehicles=N,
                                                          physics=False))
    data = mujoco.MjData(model)
    try:
        renderer = mujoco.Renderer(model, height, width)
    except Exception as exc:  # noqa: BLE001 - any GL failure means no offscreen rendering
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DataError(f"render_media: offscreen rendering unavailable under MUJOCO_GL="
                        f"{os.environ.get('MUJOCO_GL')} ({msg}); MUJOCO_GL must be set (egl) "
                        "before MuJoCo is first imported in the process; or switch the media "
                        "off: config scenes.media.enabled: false") from None
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_FOG] = 1    # the water's fog (scene_xml)
    adr = [int(model.jnt_qposadr[model.joint(f"vehicle{k}_joint").id]) for k in range(N)]
    ok = np.all(np.isfinite(traj[..., :6]), axis=2)  # (T, N)
    pos = mjcf.core_to_mj(np.where(ok[..., None], traj[..., :3], 0.0))
    quat = mjcf.euler_to_quat(*(np.where(ok, traj[..., c], 0.0)
                                for c in (dyn.PHI, dyn.THETA, dyn.PSI)))
    if ok.any():
        lo, hi = pos[ok].min(axis=0), pos[ok].max(axis=0)
    else:
        lo = hi = np.array([0.5 * (scene.extent[0] + scene.extent[1]),
                            0.5 * (scene.extent[2] + scene.extent[3]), -5.0])
    if field is not None:   # frame the slick too: its cells above 2 % of the maximum
        C = np.asarray(field["C"], dtype=np.float64)
        if C.size and float(np.nanmax(C)) > 0:
            jj, ii = np.nonzero(C > 0.02 * float(np.nanmax(C)))
            h = float(field["h"])
            fx = float(field["origin"][0]) + h * ii
            fz = float(field["origin"][1]) + h * jj
            lo = np.minimum(lo, [fx.min(), fz.min(), lo[2]])
            hi = np.maximum(hi, [fx.max(), fz.max(), hi[2]])
    span = float(np.max(hi - lo))
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = 0.5 * (lo + hi)
    cam.distance = max(1.6 * span, 12.0)
    cam.azimuth = azimuth_deg
    cam.elevation = elevation_deg
    marker = max(0.6, 0.012 * cam.distance)

    def frame(t: int) -> np.ndarray:
        for k in range(N):
            a = adr[k]
            if ok[t, k]:
                data.qpos[a:a + 3] = pos[t, k]
                data.qpos[a + 3:a + 7] = quat[t, k]
            else:
                data.qpos[a:a + 3] = (0.0, 0.0, -1.0e4)
                data.qpos[a + 3:a + 7] = (1.0, 0.0, 0.0, 0.0)
        mujoco.mj_kinematics(model, data)
        renderer.update_scene(data, camera=cam)
        scn = renderer.scene
        for k in range(N):
            rgb = _COLOURS[k % len(_COLOURS)]
            track = pos[:t + 1, k][ok[:t + 1, k]]
            step = max(1, len(track) // 60)
            pts = track[::step]
            if len(track) and not np.array_equal(pts[-1], track[-1]):
                pts = np.vstack([pts, track[-1:]])
            for p0, p1 in zip(pts[:-1], pts[1:]):
                if scn.ngeom >= scn.maxgeom or np.array_equal(p0, p1):
                    continue
                g = scn.geoms[scn.ngeom]
                mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3),
                                    np.eye(3).ravel(), np.array([*rgb, 0.9], dtype=np.float32))
                mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_CAPSULE, 0.25 * marker, p0, p1)
                scn.ngeom += 1
            if ok[t, k] and scn.ngeom < scn.maxgeom:
                g = scn.geoms[scn.ngeom]
                mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_SPHERE, np.array([marker, 0, 0]),
                                    pos[t, k], np.eye(3).ravel(),
                                    np.array([*rgb, 0.35], dtype=np.float32))
                scn.ngeom += 1
        if current is not None and scn.ngeom < scn.maxgeom:
            speed = float(np.hypot(*current))
            if speed > 1e-9:
                length = 0.2 * cam.distance * max(speed, 0.3)
                d = np.array([current[0], current[1], 0.0]) / speed
                p0 = np.array([cam.lookat[0], cam.lookat[1], 0.5]) - 0.5 * length * d
                g = scn.geoms[scn.ngeom]
                mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3),
                                    np.eye(3).ravel(),
                                    np.array([0.95, 0.95, 1.0, 0.95], dtype=np.float32))
                mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_ARROW, 0.01 * cam.distance,
                                     p0, p0 + length * d)
                scn.ngeom += 1
        if field is not None:
            C = np.asarray(field["C"], dtype=np.float64)
            cmax = float(np.nanmax(C)) if C.size else 0.0
            h = float(field["h"])
            ox, oz = (float(v) for v in field["origin"])
            if cmax > 0:
                for j, i in zip(*np.nonzero(C > 0.02 * cmax)):
                    if scn.ngeom >= scn.maxgeom:
                        break
                    a = 0.25 + 0.65 * min(C[j, i] / cmax, 1.0)
                    g = scn.geoms[scn.ngeom]
                    mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_BOX,
                                        np.array([0.5 * h, 0.5 * h, 0.05]),
                                        np.array([ox + i * h, oz + j * h, 0.05]),
                                        np.eye(3).ravel(),
                                        np.array([0.12, 0.08, 0.04, a], dtype=np.float32))
                    scn.ngeom += 1
        return renderer.render().copy()

    stem = Path(out_png_stem)
    keys = np.linspace(0, T - 1, keyframes).round().astype(int).tolist()
    pngs = []
    for k, t in enumerate(keys):
        buf = io.BytesIO()
        Image.fromarray(frame(t)).save(buf, format="PNG")
        path = stem.parent / f"{stem.name}_{k}.png"
        write_bytes_atomic(path, buf.getvalue())
        pngs.append(path)
    if gif_path is None:
        renderer.close()
        return {"png": pngs, "gif": None, "frames": 0}
    idx = np.unique(np.linspace(0, T - 1, min(T, MAX_GIF_FRAMES)).round().astype(int))
    images = [Image.fromarray(frame(int(t))).convert("P", palette=Image.Palette.ADAPTIVE)
              for t in idx]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:],
                   duration=int(round(1000 / fps)), loop=0)
    write_bytes_atomic(Path(gif_path), buf.getvalue())
    renderer.close()
    return {"png": pngs, "gif": Path(gif_path), "frames": len(images)}
