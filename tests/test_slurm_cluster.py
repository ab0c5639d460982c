"""The workflow on a real SLURM cluster: a single-node cluster started on this machine
(tests/slurm_cluster.py), a small config run through ``snakemake --profile profiles/slurm``
(the SLURM executor plugin), and its results byte-identical to a local ``--cores 2`` run.

Skipped (one line) only where the machine cannot host the cluster: not root, Debian's
``slurm-wlm``/``munge`` neither installed nor installable, daemons that do not start.
"""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from slurm_cluster import ClusterError, ClusterUnavailable, SlurmCluster
from workflow_helpers import REPO, SMALL_CONFIG

pytestmark = pytest.mark.slow

REGION = SMALL_CONFIG["region"]["name"]
VARIANTS = list(SMALL_CONFIG["variants"])
#: Fetch and the variants table (local rules); the merge, exports and Fig. 3 of every variant
#: (rule group "variant": one cluster job); Fig. 4 (a cluster job of its own). 17 jobs, about
#: a minute on 2 cores, no numba kernel to compile.
TARGETS = ["exports", f"results/tables/{REGION}/dataset_variants.tex",
           f"results/figures/{REGION}/pollution_species.png",
           *(f"results/figures/{REGION}/{v}/current_field.png" for v in VARIANTS)]
TIMEOUT_S = 900


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    c = SlurmCluster(tmp_path_factory.mktemp("slurm"))
    try:
        c.start()
    except ClusterUnavailable as err:
        pytest.skip(f"no single-node SLURM cluster on this machine: {err}")
    yield c
    c.stop()


def _test_profile(cluster: SlurmCluster, path: Path) -> Path:
    """profiles/slurm with this cluster's partition, no account, quick status checks, and the
    variant groups of the small run put into one cluster job (--group-components)."""
    prof = yaml.safe_load((REPO / "profiles" / "slurm" / "config.yaml").read_text())
    prof["default-resources"] = {**prof["default-resources"],
                                 "slurm_partition": cluster.partition}
    prof["group-components"] = [*prof["group-components"], f"variant={len(VARIANTS)}"]
    prof.update({"slurm-no-account": True, "slurm-init-seconds-before-status-checks": 3,
                 "slurm-keep-successful-logs": True})
    path.mkdir(parents=True)
    (path / "config.yaml").write_text(yaml.safe_dump(prof))
    return path


def _snakemake(workdir: Path, *args, env=None, cluster: SlurmCluster | None = None):
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / "test_config.yaml").write_text(yaml.safe_dump(SMALL_CONFIG))
    cmd = [sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile"),
           "--directory", str(workdir), "--configfile", str(REPO / "config" / "config.yaml"),
           str(workdir / "test_config.yaml"), *args, *TARGETS]
    with open(workdir / "snakemake.out", "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                                start_new_session=True)
        t0 = time.monotonic()
        try:
            while proc.poll() is None:
                if cluster is not None:
                    cluster.check_alive()   # a daemon that died: ClusterError with its log
                if time.monotonic() - t0 > TIMEOUT_S:
                    pytest.fail(f"snakemake did not finish in {TIMEOUT_S} s:\n"
                                + (workdir / "snakemake.out").read_text()[-3000:])
                time.sleep(1)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    out = (workdir / "snakemake.out").read_text()
    assert proc.returncode == 0, f"snakemake failed:\n{out[-4000:]}" + (
        f"\n{cluster.logs()}" if cluster else "")
    return out


def _digests(workdir: Path) -> dict[str, str]:
    """sha256 of every file under results/ except the per-job timings (benchmarks)."""
    root = workdir / "results"
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*"))
            if p.is_file() and p.relative_to(root).parts[0] != "benchmarks"}


def test_slurm_run_matches_local_run(cluster, tmp_path):
    profile = _test_profile(cluster, tmp_path / "profile")
    # --cores: what one cluster job (here the variant group) may use: the node's CPUs
    out = _snakemake(tmp_path / "slurm", "--profile", str(profile), "--cores",
                     str(cluster.cpus), env=cluster.env, cluster=cluster)
    jobs = subprocess.run(["squeue", "--states=all", "--noheader", "--format=%T %k"],
                          capture_output=True, text=True, env=cluster.env, check=True)
    submitted = sorted(line.split() for line in jobs.stdout.splitlines())
    # one group job for the three variants' 12 jobs, one job for Fig. 4, no local rule
    assert len(submitted) == 2 and {s for s, _ in submitted} == {"COMPLETED"}, submitted
    assert "pollution_species" in submitted[0][1] + submitted[1][1], submitted
    assert "Group job variant" in out, out[-3000:]

    _snakemake(tmp_path / "local", "--cores", "2")
    slurm, local = _digests(tmp_path / "slurm"), _digests(tmp_path / "local")
    assert len(local) >= 30 and any(k.endswith("grid.npz") for k in local), sorted(local)
    assert sorted(slurm) == sorted(local)
    differ = [k for k in local if slurm[k] != local[k]]
    assert not differ, f"{len(differ)} of {len(local)} files differ: {differ[:10]}"
