"""A real single-node SLURM cluster on this machine, for tests: munge, slurmctld and slurmd
started as root from a minimal ``slurm.conf`` in a scratch directory, stopped afterwards.

``SlurmCluster(workdir).start()`` raises :class:`ClusterUnavailable` (one line) when the
machine cannot host it (not root, Debian's ``slurm-wlm``/``munge`` neither installed nor
installable, a daemon that does not come up); the test turns that into its skip reason.
A daemon that dies after start-up raises :class:`ClusterError` with the tail of its log.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
from pathlib import Path

#: Debian packages that provide the daemons and client commands.
PACKAGES = ("slurm-wlm", "munge")
BINARIES = ("slurmctld", "slurmd", "sinfo", "sbatch", "srun", "squeue", "scontrol", "scancel",
            "munged", "munge")
MUNGE_KEY = Path("/etc/munge/munge.key")
MUNGE_SOCKET = Path("/run/munge/munge.socket.2")


class ClusterUnavailable(RuntimeError):
    """This machine cannot host the test cluster (the reason is one line)."""


class ClusterError(RuntimeError):
    """The cluster started but misbehaved (the message carries the daemon logs' tails)."""


def _run(cmd, timeout=60, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, **kw)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _tail(path: Path, n: int = 20) -> str:
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError:
        return f"  ({path} not written)"
    return "\n".join(f"  {line}" for line in lines[-n:]) or f"  ({path} empty)"


def ensure_packages(install_timeout: float = 900.0) -> None:
    """The SLURM and munge binaries on PATH, installed with apt-get when missing (root only)."""
    if os.geteuid() != 0:
        raise ClusterUnavailable("needs root to run slurmctld/slurmd")
    if all(shutil.which(b) for b in BINARIES):
        return
    if shutil.which("apt-get") is None:
        raise ClusterUnavailable(f"{' and '.join(PACKAGES)} not installed and no apt-get")
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    try:
        _run(["apt-get", "update", "-qq"], timeout=install_timeout, env=env)
        r = _run(["apt-get", "install", "-y", "-qq", "--no-install-recommends", *PACKAGES],
                 timeout=install_timeout, env=env)
    except subprocess.TimeoutExpired:
        raise ClusterUnavailable(f"apt-get install {' '.join(PACKAGES)} timed out") from None
    missing = [b for b in BINARIES if not shutil.which(b)]
    if r.returncode != 0 or missing:
        why = (r.stderr.strip().splitlines() or ["?"])[-1]
        raise ClusterUnavailable(f"apt-get install {' '.join(PACKAGES)} failed: {why}")


def ensure_munge(timeout: float = 20.0) -> None:
    """A munge key and a running ``munged`` (started as the munge user if none answers)."""
    if _run(["munge", "-n"], timeout=10).returncode == 0:
        return
    if not MUNGE_KEY.exists():
        make = (["mungekey", "--create", "--keyfile", str(MUNGE_KEY)] if shutil.which("mungekey")
                else ["create-munge-key", "-f"])
        r = _run(make)
        if r.returncode != 0:
            raise ClusterUnavailable(f"cannot create {MUNGE_KEY}: {r.stderr.strip()}")
    # munged runs as the owner of its key (Debian: user munge); root needs --force
    owner = MUNGE_KEY.owner()
    MUNGE_SOCKET.parent.mkdir(parents=True, exist_ok=True)
    shutil.chown(MUNGE_SOCKET.parent, owner, owner)
    cmd = ["munged"] if owner == "root" else ["runuser", "-u", owner, "--", "munged"]
    if owner == "root":
        cmd.append("--force")
    r = _run(cmd)
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if _run(["munge", "-n"], timeout=10).returncode == 0:
            return
        time.sleep(0.5)
    raise ClusterUnavailable(f"munged does not start: {(r.stderr or r.stdout).strip()}")


class SlurmCluster:
    """One node (this host, ``cpus`` CPUs) in one partition ``debug``; the configuration, state,
    spool and logs live under ``root``. Client commands need ``env`` (it sets SLURM_CONF)."""

    partition = "debug"

    def __init__(self, root: Path, cpus: int | None = None, memory_margin_mb: int = 1024):
        self.root = Path(root)
        self.host = socket.gethostname().split(".")[0]
        self.cpus = cpus or os.cpu_count() or 1
        avail = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2**20
        self.memory_mb = max(512, int(avail) - memory_margin_mb)
        self.conf = self.root / "slurm.conf"
        self.procs: dict[str, subprocess.Popen] = {}
        # Client commands find the configuration through SLURM_CONF; inside a job, Snakemake's
        # job step (snakemake-executor-plugin-slurm-jobstep) runs srun with every SLURM_*
        # variable but a few removed, SLURM_CONF included: an srun on PATH sets it again.
        self.bin = self.root / "bin"
        self.env = {**os.environ, "SLURM_CONF": str(self.conf),
                    "PATH": os.pathsep.join([str(self.bin), os.environ.get("PATH", "")])}

    # ---- configuration
    def write_conf(self) -> None:
        for d in ("state", "spool", "log"):
            (self.root / d).mkdir(parents=True, exist_ok=True)
        r = self.root
        self.conf.write_text(f"""\
ClusterName=oneocean-test
SlurmctldHost={self.host}
SlurmctldPort={_free_port()}
SlurmdPort={_free_port()}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation={r}/state
SlurmdSpoolDir={r}/spool
SlurmctldPidFile={r}/slurmctld.pid
SlurmdPidFile={r}/slurmd.pid
SlurmctldLogFile={r}/log/slurmctld.log
SlurmdLogFile={r}/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
# finished jobs stay visible to squeue (the executor's status command here) for 10 min
MinJobAge=600
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName={self.host} CPUs={self.cpus} RealMemory={self.memory_mb} State=UNKNOWN
PartitionName={self.partition} Nodes=ALL Default=YES MaxTime=INFINITE State=UP
""")

    def write_srun(self) -> None:
        self.bin.mkdir(parents=True, exist_ok=True)
        srun = self.bin / "srun"
        srun.write_text(f'#!/bin/sh\nSLURM_CONF={self.conf} exec {shutil.which("srun")} "$@"\n')
        srun.chmod(0o755)

    # ---- daemons
    def _start(self, name: str) -> None:
        out = open(self.root / "log" / f"{name}.stdout", "w")
        self.procs[name] = subprocess.Popen(
            [name, "-D", "-f", str(self.conf)], stdout=out, stderr=subprocess.STDOUT,
            env=self.env, start_new_session=True)

    def logs(self) -> str:
        parts = []
        for name in ("slurmctld", "slurmd"):
            for f in (f"{name}.log", f"{name}.stdout"):
                parts.append(f"--- {f}\n{_tail(self.root / 'log' / f)}")
        return "\n".join(parts)

    def check_alive(self) -> None:
        for name, p in self.procs.items():
            if p.poll() is not None:
                raise ClusterError(f"{name} exited with {p.returncode}\n{self.logs()}")

    def sinfo_state(self) -> str:
        r = _run(["sinfo", "--noheader", "--format=%T", "--nodes", self.host],
                 timeout=15, env=self.env)
        return r.stdout.strip() if r.returncode == 0 else ""

    def start(self, timeout: float = 60.0) -> "SlurmCluster":
        ensure_packages()
        ensure_munge()
        self.write_conf()
        self.write_srun()
        self._start("slurmctld")
        self._start("slurmd")
        t0 = time.monotonic()
        state = ""
        while time.monotonic() - t0 < timeout:
            for name, p in self.procs.items():
                if p.poll() is not None:
                    self.stop()
                    raise ClusterUnavailable(
                        f"{name} exited with {p.returncode} at start-up: "
                        f"{_tail(self.root / 'log' / f'{name}.log', 1).strip()}")
            state = self.sinfo_state()
            if state == "idle":
                return self
            time.sleep(0.5)
        logs = self.logs()
        self.stop()
        raise ClusterUnavailable(
            f"node {self.host} not idle after {timeout:.0f} s (state {state or '?'})"
            + (f"; {logs.splitlines()[-1].strip()}" if logs else ""))

    def stop(self, timeout: float = 20.0) -> None:
        _run(["scancel", "--full", "--partition", self.partition], timeout=15, env=self.env)
        for name in ("slurmd", "slurmctld"):
            p = self.procs.pop(name, None)
            if p is None or p.poll() is not None:
                continue
            p.terminate()
            try:
                p.wait(timeout)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()

    def __enter__(self) -> "SlurmCluster":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
