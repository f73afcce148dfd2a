"""The Slurm example under a real single-node Slurm, configured, started and
stopped (by PID) by this test: a job array of shards and a dependent merge
give the same file as a single run."""
import os
import pathlib
import shutil
import socket
import subprocess
import tempfile
import time

import pytest

from conftest import ROOT, run
from test_campaign import SPIN_RADIUS, assert_same_datasets, write

pytestmark = pytest.mark.skipif(
    os.geteuid() != 0 or not all(shutil.which(p) for p in ("slurmctld", "slurmd", "sbatch", "munged")),
    reason="needs root and Debian's slurm-wlm and munge (installed by .ci/setup)")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def slurm():
    # munged wants every directory above its socket open to all (pytest's tmp is 0700)
    home = pathlib.Path(tempfile.mkdtemp(prefix="ellroll-slurm-", dir="/tmp"))
    home.chmod(0o755)
    for d in ("state", "spool", "log"):
        (home / d).mkdir()
    key = home / "munge.key"
    key.write_bytes(os.urandom(128))
    key.chmod(0o600)
    host = socket.gethostname().split(".")[0]
    conf = home / "slurm.conf"
    conf.write_text(f"""ClusterName=ellrolltest
SlurmctldHost={host}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket={home}/munge.sock
CredType=cred/munge
StateSaveLocation={home}/state
SlurmdSpoolDir={home}/spool
SlurmctldPidFile={home}/slurmctld.pid
SlurmdPidFile={home}/slurmd.pid
SlurmctldPort={free_port()}
SlurmdPort={free_port()}
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
SlurmctldLogFile={home}/log/slurmctld.log
SlurmdLogFile={home}/log/slurmd.log
NodeName={host} CPUs=2 State=UNKNOWN
PartitionName=test Nodes={host} Default=YES MaxTime=INFINITE State=UP
""")
    env = dict(os.environ, SLURM_CONF=str(conf))
    daemons = [
        subprocess.Popen(["munged", "-F", f"--socket={home}/munge.sock", f"--key-file={key}",
                          f"--pid-file={home}/munged.pid", f"--seed-file={home}/munge.seed",
                          f"--log-file={home}/log/munge.log"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    time.sleep(0.5)
    for daemon in ("slurmctld", "slurmd"):
        daemons.append(subprocess.Popen([daemon, "-D", "-f", str(conf)], env=env,
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            state = subprocess.run(["sinfo", "-h", "-o", "%t"], env=env, capture_output=True, text=True)
            if state.stdout.strip() == "idle":
                break
            time.sleep(0.5)
        else:
            pytest.fail("Slurm did not come up:\n" + (home / "log" / "slurmctld.log").read_text()[-2000:])
        yield env
    finally:
        for daemon in reversed(daemons):
            daemon.kill()
            daemon.wait()
        shutil.rmtree(home, ignore_errors=True)


def test_job_array_and_merge_job(slurm, ellroll, tmp_path):
    name = write(tmp_path, SPIN_RADIUS)
    assert run(ellroll, "run", name, "-q", "-o", "single.h5", cwd=tmp_path).returncode == 0
    env = dict(slurm, ELLROLL=str(ellroll))
    submit = subprocess.run([str(ROOT / "examples" / "slurm" / "submit.sh"), name, "campaign.h5", "3", "1"],
                            cwd=tmp_path, env=env, capture_output=True, text=True)
    assert submit.returncode == 0, submit.stderr
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        queue = subprocess.run(["squeue", "-h"], env=env, capture_output=True, text=True).stdout
        if not queue.strip():
            break
        time.sleep(1)
    logs = "\n".join(p.read_text() for p in tmp_path.glob("*.log"))
    assert not queue.strip(), "jobs still queued:\n" + queue
    assert (tmp_path / "campaign.h5").exists(), logs
    assert len(list(tmp_path.glob("ellroll-*_*.log"))) == 3
    assert not list(tmp_path.glob("campaign.shard_*"))
    assert "completed           20" in logs
    assert_same_datasets(tmp_path / "single.h5", tmp_path / "campaign.h5")


def test_a_task_stopped_before_its_time_limit_requeues_and_resumes(slurm, ellroll, tmp_path):
    """USR1 to the tasks' scripts, as --signal=B:USR1@120 sends it before the
    time limit, once every shard has finished some cases: each task stops
    ellroll (SIGTERM, exit 143), requeues itself and resumes; the merged file
    equals a single run's, and each task's log (appended) tells the story."""
    name = write(tmp_path, SPIN_RADIUS.replace("count = 4", "count = 40"), t_end=600.0)
    text = (tmp_path / name).read_text().replace("interval = 0.01", "interval = 1.0")
    (tmp_path / name).write_text(text)
    assert run(ellroll, "run", name, "-q", "-o", "single.h5", cwd=tmp_path).returncode == 0
    env = dict(slurm, ELLROLL=str(ellroll))
    submit = subprocess.run([str(ROOT / "examples" / "slurm" / "submit.sh"), "--time", "10", name, "campaign.h5",
                             "2", "1"], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert submit.returncode == 0, submit.stderr
    array = submit.stdout.split()[2].rstrip(",")
    journals = [tmp_path / f"campaign.shard_{i}.h5.journal" for i in range(2)]
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not all(j.exists() and j.stat().st_size > 4096 for j in journals):
        time.sleep(0.05)
    assert all(j.exists() for j in journals), "the tasks did not start"
    subprocess.run(["scancel", "--signal=USR1", "--batch", array], env=env, check=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        queue = subprocess.run(["squeue", "-h", "-o", "%i %r"], env=env, capture_output=True, text=True).stdout
        if not queue.strip():
            break
        for line in queue.splitlines():      # Slurm holds a requeued task for two minutes; no need here
            if line.endswith("BeginTime"):
                subprocess.run(["scontrol", "update", f"JobId={line.split()[0]}", "StartTime=now"], env=env)
        time.sleep(0.5)
    logs = {p.name: p.read_text() for p in tmp_path.glob("ellroll-*_*.log")}
    assert not queue.strip(), "jobs still queued:\n" + queue + "\n".join(logs.values())
    assert len(logs) == 2
    for log in logs.values():
        assert "interrupted by SIGTERM after" in log and "requeued to resume" in log, log
    assert_same_datasets(tmp_path / "single.h5", tmp_path / "campaign.h5")
