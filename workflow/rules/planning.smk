# The planning suite (paper Tables IV and VI): config `planning` tasks at one tier with scaled
# currents; heuristic and BC cells (the fused loop) and one LLM-planner cell per configured
# model (config `llm.models`; none configured: no LLM cells, and the tables say so).


LLM_CODE = code_version("oneocean.methods.llm")

if not config["llm"]["models"]:
    print("planning suite: no LLM endpoint configured (llm.models is empty): LLM cells "
          "skipped and their rows omitted", file=sys.stderr)


localrules:
    table_planning,


rule planning_cell:
    conda:
        PY_ENV
    input:
        grid=rules.export_grid.output.npz,
        kernel=rules.compile_kernel.output.record,
        weights=bc_weights,
    output:
        parquet="results/planning/{region}/{variant}/{task}/{method}.parquet",
        prov="results/provenance/planning/{region}/{variant}/{task}/{method}.json",
    log:
        "logs/planning/{region}/{variant}/{task}/{method}.log",
    benchmark:
        "results/benchmarks/planning/{region}/{variant}/{task}/{method}.tsv"
    wildcard_constraints:
        method="heuristic|bc",
    params:
        run=_planning_run,
        code=rollout_code,
    threads: lambda wc: config["rollouts"]["threads"]
    # measured <= 15 s, 300 MB; group "planning": `--group-components planning=6`
    resources:
        mem_mb=1000,
        runtime=15,
    group:
        "planning"
    script:
        "../scripts/planning_cell.py"


rule planning_llm_cell:
    conda:
        PY_ENV
    input:
        grid=rules.export_grid.output.npz,
        kernel=rules.compile_kernel.output.record,
    output:
        parquet="results/planning/{region}/{variant}/{task}/{method}.parquet",
        prov="results/provenance/planning/{region}/{variant}/{task}/{method}.json",
    log:
        "logs/planning/{region}/{variant}/{task}/{method}.log",
    benchmark:
        "results/benchmarks/planning/{region}/{variant}/{task}/{method}.tsv"
    wildcard_constraints:
        method="llm_[A-Za-z0-9_]+",
    params:
        run=_planning_llm_run,
        model=lambda wc: next(m for m in config["llm"]["models"] if llm_method(m) == wc.method),
        every=lambda wc: config["llm"]["every_steps"][wc.task],
        cache_dir=config["llm"]["cache_dir"],
        code=lambda wc: task_code(wc.task) + LLM_CODE,
    threads: lambda wc: config["rollouts"]["threads"]
    # sized conservatively (waits on the LLM endpoint); config/llm/smollm2.yaml (3 episodes,
    # in-process model) measured 36-200 CPU-s, 5-14 min wall on a loaded 2-core machine,
    # up to 970 MB RSS (SPC)
    resources:
        mem_mb=1500,
        runtime=120,
    script:
        "../scripts/planning_llm_cell.py"


rule table_planning:
    conda:
        PY_ENV
    input:
        cells=planning_targets(),
    output:
        perf=report("results/tables/{region}/planning_performance.tex",
                    caption="../report/table.rst", category="Tables"),
        cost=report("results/tables/{region}/planning_cost.tex",
                    caption="../report/table.rst", category="Tables"),
        perf_parquet="results/tables/{region}/planning_performance.parquet",
        cost_parquet="results/tables/{region}/planning_cost.parquet",
        prov="results/provenance/tables/{region}/planning.json",
    log:
        "logs/tables/{region}/planning.log",
    params:
        planning=lambda wc: config["planning"],
        llms=planning_llm_methods(),
        code=code_version("oneocean.reporting.planning", "oneocean.reporting.stats",
                          "oneocean.reporting.latex"),
    threads: 1
    script:
        "../scripts/table_planning.py"
