# Stage 4b: the scene backend (MuJoCo). Scenes built from a variant's grid and temporal
# exports (scene_build), every scene task run in every scene (scene_cells, backend mujoco)
# and, on the compare scene, by the core on the same local grid (backend core), Fig. 8's
# media (scene_media) and the scene tables (table_scenes: Table VII and core vs scene).

SCENE_CFG = config["scenes"]
SCENE_NAMES = [s["name"] for s in SCENE_CFG["list"]]
SCENE_BACKENDS = ("mujoco", "core")


wildcard_constraints:
    scene="|".join(map(re.escape, SCENE_NAMES)) or "NONE",


def scene_spec(name):
    return next(s for s in SCENE_CFG["list"] if s["name"] == name)


def _scene_method_ok(task, method):
    """bc runs in a scene only on the tasks its network is trained on (the rollouts' tasks,
    when bc is one of the rollouts' methods)."""
    r = config["rollouts"]
    return method != "bc" or ("bc" in r["methods"] and task in r["tasks"])


def scene_cell_list(scene, backend):
    """(task, tier, method) cells of one scene on one backend: every scene cell on mujoco;
    on the core only the compare scene's."""
    if backend == "core" and scene != SCENE_CFG["compare"]:
        return []
    return [{"task": t, "tier": int(k), "method": m} for t in SCENE_CFG["tasks"]
            for k in SCENE_CFG["tiers"] for m in SCENE_CFG["methods"] if _scene_method_ok(t, m)]


def _scene_cell_path(kind, scene, backend, c):
    if kind == "parquet":
        return (f"results/scene_rollouts/{{region}}/{{variant}}/{scene}/{backend}/"
                f"{c['task']}/tier{c['tier']}/{c['method']}.parquet")
    return (f"results/provenance/scene_rollouts/{{region}}/{{variant}}/{scene}/{backend}/"
            f"{c['task']}/tier{c['tier']}/{c['method']}.json")


def scene_runs():
    """(scene, backend) pairs that have cells."""
    return [(s, b) for s in SCENE_NAMES for b in SCENE_BACKENDS if scene_cell_list(s, b)]


def scene_cell_targets(kind="parquet"):
    if not SCENE_CFG["enabled"]:
        return []
    v = SCENE_CFG["variant"]
    return [_scene_cell_path(kind, s, b, c).format(region=REGION, variant=v)
            for s, b in scene_runs() for c in scene_cell_list(s, b)]


def scene_media_files(scene):
    m = SCENE_CFG["media"]
    base = f"results/figures/{{region}}/scenes/{{variant}}/{scene}"
    return ([f"{base}/keyframe_{i}.png" for i in range(int(m["keyframes"]))]
            + [f"{base}/episode.gif"])


def scene_panel_files():
    """Fig. 8's team and cleanup panels (the config's scenes.media.panels_scene; none when it
    is null, not a configured scene, or the media are off)."""
    m = SCENE_CFG["media"]
    if not SCENE_CFG["enabled"] or not m["enabled"] or m.get("panels_scene") not in SCENE_NAMES:
        return []
    v = SCENE_CFG["variant"]
    return [f"results/figures/{REGION}/scenes/{v}/panels/{p}.png" for p in ("team", "cleanup")]


def scene_targets():
    """Everything paper_tables needs from the scene backend (nothing when disabled)."""
    if not SCENE_CFG["enabled"]:
        return []
    v = SCENE_CFG["variant"]
    out = [f"results/tables/{REGION}/{n}" for n in
           ("scene_backend.tex", "scene_vs_core.tex", "scene_backend.md")]
    out += [f"results/scenes/{REGION}/{v}/{s}/scene.xml" for s in SCENE_NAMES]
    if SCENE_CFG["media"]["enabled"]:
        out += [p.format(region=REGION, variant=v) for s in SCENE_NAMES
                for p in scene_media_files(s)]
    out += scene_panel_files()
    return out


def scene_provenance():
    if not SCENE_CFG["enabled"]:
        return []
    v = SCENE_CFG["variant"]
    out = [f"results/provenance/scenes/{REGION}/{v}/{s}.json" for s in SCENE_NAMES]
    out += scene_cell_targets("prov")
    out.append(f"results/provenance/tables/{REGION}/scene_backend.json")
    if SCENE_CFG["media"]["enabled"]:
        out += [f"results/provenance/figures/{REGION}/scenes/{v}/{s}.json" for s in SCENE_NAMES]
    out += [f.replace("results/figures/", "results/provenance/figures/").replace(".png", ".json")
            for f in scene_panel_files()]
    return out


def scene_weights(wc):
    if not any(_scene_method_ok(t, "bc") for t in SCENE_CFG["tasks"]) or \
            "bc" not in SCENE_CFG["methods"]:
        return []
    return [f"results/bc/{wc.region}/{config['rollouts']['variant']}/weights.npz"]


def scene_kernels(wc):
    return [f"results/kernels/{wc.region}/{config['rollouts']['variant']}/{t}.json"
            for t in SCENE_CFG["tasks"] if t in config["rollouts"]["tasks"]]


SCENE_CODE = code_version("oneocean.backends", "oneocean.tasks", "oneocean.methods",
                          "oneocean.sensing", "oneocean.engine", "oneocean.data")


localrules:
    table_scenes,


rule scene_build:
    conda:
        PY_ENV
    input:
        grid=EXPORT_GRID_PATH,
        temporal=EXPORT_TEMPORAL_PATH,
    output:
        xml="results/scenes/{region}/{variant}/{scene}/scene.xml",
        grid="results/scenes/{region}/{variant}/{scene}/grid.npz",
        meta="results/scenes/{region}/{variant}/{scene}/scene.json",
        prov="results/provenance/scenes/{region}/{variant}/{scene}.json",
    log:
        "logs/scenes/{region}/{variant}/{scene}/build.log",
    params:
        spec=lambda wc: scene_spec(wc.scene),
        code=code_version("oneocean.backends"),
    threads: 1
    # no benchmark recorded: sized conservatively; group "scenes": a scene's build and media
    resources:
        mem_mb=2000,
        runtime=15,
    group:
        "scenes"
    script:
        "../scripts/scene_build.py"


# Every (task, tier, method) cell of one scene on one backend in one job: one rule per
# (scene, backend), scene_cells_<scene>_<backend>, because each has its own list of files.
def _scene_cell_params(scene, backend):
    return [{**c, "wildcards": {"task": c["task"], "tier": str(c["tier"]),
                                "method": c["method"], "scene": scene, "backend": backend},
             "params": {"code": SCENE_CODE,
                        "run": {"episodes": SCENE_CFG["episodes"],
                                "seed": config["rollouts"]["seed"],
                                "dynamics": config["rollouts"]["dynamics"],
                                "physics_step_s": SCENE_CFG["physics_step_s"]}}}
            for c in scene_cell_list(scene, backend)]


for _scene, _backend in scene_runs():

    rule:
        name:
            f"scene_cells_{_scene}_{_backend}"
        conda:
            PY_ENV
        input:
            scene=f"results/scenes/{{region}}/{{variant}}/{_scene}/scene.json",
            scene_grid=f"results/scenes/{{region}}/{{variant}}/{_scene}/grid.npz",
            xml=f"results/scenes/{{region}}/{{variant}}/{_scene}/scene.xml",
            temporal=EXPORT_TEMPORAL_PATH,
            kernels=scene_kernels,
            weights=scene_weights,
        output:
            parquet=[_scene_cell_path("parquet", _scene, _backend, c)
                     for c in scene_cell_list(_scene, _backend)],
            prov=[_scene_cell_path("prov", _scene, _backend, c)
                  for c in scene_cell_list(_scene, _backend)],
        log:
            f"logs/scene_rollouts/{{region}}/{{variant}}/{_scene}/{_backend}.log",
        benchmark:
            f"results/benchmarks/scene_rollouts/{{region}}/{{variant}}/{_scene}/{_backend}.tsv"
        params:
            cells=_scene_cell_params(_scene, _backend),
            backend=_backend,
        threads: 1
        # measured <= 451 s, 710 MB (MuJoCo), 27 s (core)
        resources:
            mem_mb=2000,
            runtime=60,
        script:
            "../scripts/scene_cells.py"


# Fig. 8: keyframes and an animated GIF of episode 0 of the heuristic on route following at the
# last scene tier (else the next task or tier the scene hosts), rendered offscreen.
rule scene_media:
    conda:
        PY_ENV
    input:
        scene=rules.scene_build.output.meta,
        scene_grid=rules.scene_build.output.grid,
        kernels=scene_kernels,
    output:
        frames=scene_media_files("{scene}"),
        prov="results/provenance/figures/{region}/scenes/{variant}/{scene}.json",
    log:
        "logs/figures/{region}/scenes/{variant}/{scene}.log",
    params:
        tasks=sorted(SCENE_CFG["tasks"], key=lambda t: t != "RF"),   # RF first
        tiers=SCENE_CFG["tiers"],
        seed=config["rollouts"]["seed"],
        dynamics=config["rollouts"]["dynamics"],
        media=SCENE_CFG["media"],
        physics_step_s=SCENE_CFG["physics_step_s"],
        code=SCENE_CODE,
    threads: 1
    # no benchmark recorded: sized conservatively (offscreen rendering; group: see scene_build)
    resources:
        mem_mb=2000,
        runtime=30,
    group:
        "scenes"
    script:
        "../scripts/scene_media.py"


# Fig. 8's panels in the scenes.media.panels_scene scene: the team (FT, Tier 2, ten vehicles,
# its last step) and the cleanup (SPC, Tier 1, at step 90, its slick on the task's field of
# the scene's grid), episode 0 of the heuristic, with the water's fog and the current's arrow.
rule scene_panel:
    conda:
        PY_ENV
    input:
        scene=lambda wc: f"results/scenes/{wc.region}/{wc.variant}/"
                         f"{SCENE_CFG['media']['panels_scene']}/scene.json",
        scene_grid=lambda wc: f"results/scenes/{wc.region}/{wc.variant}/"
                              f"{SCENE_CFG['media']['panels_scene']}/grid.npz",
    output:
        png="results/figures/{region}/scenes/{variant}/panels/{panel}.png",
        prov="results/provenance/figures/{region}/scenes/{variant}/panels/{panel}.json",
    log:
        "logs/figures/{region}/scenes/{variant}/panels/{panel}.log",
    params:
        seed=config["rollouts"]["seed"],
        dynamics=config["rollouts"]["dynamics"],
        media=SCENE_CFG["media"],
        physics_step_s=SCENE_CFG["physics_step_s"],
        code=SCENE_CODE,
    wildcard_constraints:
        panel="team|cleanup",
    threads: 1
    # no benchmark recorded: the FT panel took 527 s on shared cores with its kernel compiled
    resources:
        mem_mb=2000,
        runtime=30,
    script:
        "../scripts/scene_panel.py"


rule table_scenes:
    conda:
        PY_ENV
    input:
        cells=scene_cell_targets(),
    output:
        tex=report("results/tables/{region}/scene_backend.tex",
                   caption="../report/table.rst", category="Tables"),
        compare=report("results/tables/{region}/scene_vs_core.tex",
                       caption="../report/table.rst", category="Tables"),
        md="results/tables/{region}/scene_backend.md",
        prov="results/provenance/tables/{region}/scene_backend.json",
    log:
        "logs/tables/{region}/scene_backend.log",
    params:
        compare=SCENE_CFG["compare"],
        code=code_version("oneocean.reporting.scene_tables", "oneocean.reporting.stats",
                          "oneocean.reporting.cells", "oneocean.reporting.tables",
                          "oneocean.reporting.latex"),
    threads: 1
    script:
        "../scripts/table_scenes.py"
