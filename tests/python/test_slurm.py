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
