"""``flow.cluster_host``: a LocalCluster in a child process, so the client holds no scheduler, and
the cluster ends with its caller however the caller ends."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from shadowflow.flow.cluster_host import local_cluster

distributed = pytest.importorskip("distributed")


def _alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie awaiting its parent counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state != "Z"


def _wait_gone(pids, seconds: float = 60.0) -> set:
    deadline = time.time() + seconds
    left = set(pids)
    while left and time.time() < deadline:
        left = {p for p in left if _alive(p)}
        time.sleep(0.1)
    return left


def test_the_scheduler_and_workers_run_outside_the_caller_and_end_with_the_block():
    with local_cluster(2) as address, distributed.Client(address) as client:
        scheduler = client.run_on_scheduler(os.getpid)
        workers = list(client.run(os.getpid).values())
        assert address.startswith("tcp://127.0.0.1:")
        assert scheduler != os.getpid() and len(workers) == 2 and os.getpid() not in workers
        assert sum(client.gather(client.map(lambda x: x * x, range(10)))) == 285
    assert not _wait_gone([scheduler, *workers]), "the cluster outlived its block"


def test_a_caller_killed_with_sigkill_takes_its_cluster_with_it(tmp_path):
    """No orphaned scheduler or workers after ``kill -9`` of the process that started them."""
    script = tmp_path / "caller.py"
    script.write_text(
        "import os, sys, time\n"
        "import distributed\n"
        "from shadowflow.flow.cluster_host import local_cluster\n"
        "with local_cluster(1) as address, distributed.Client(address) as client:\n"
        "    pids = [client.run_on_scheduler(os.getpid), *client.run(os.getpid).values()]\n"
        "    print(*pids, flush=True)\n"
        "    time.sleep(600)\n")
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        pids = [int(p) for p in proc.stdout.readline().split()]
        assert len(pids) == 2 and all(_alive(p) for p in pids)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        assert not _wait_gone(pids), "a scheduler or worker was left running"
    finally:
        proc.kill()
        proc.stdout.close()


def test_a_cluster_that_does_not_start_in_time_is_an_error_and_is_cleaned_up():
    before = {int(p) for p in os.listdir("/proc") if p.isdigit()}
    with pytest.raises(RuntimeError, match="did not start"):
        with local_cluster(1, start_timeout=0.01):
            pass
    new = {int(p) for p in os.listdir("/proc") if p.isdigit()} - before
    children = [p for p in new if _alive(p) and Path(f"/proc/{p}/cmdline").read_bytes().find(b"cluster_host") >= 0]
    assert not _wait_gone(children, 30)
