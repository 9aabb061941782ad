"""Scale-out on Dask (``--dask``): the same outputs and recordings as the local engine, every
frame done or failed exactly once when a worker dies mid-run."""
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from shadowflow.flow.manifest import RunManifest
from shadowflow.nodes.app.outputs import OUTPUT_FILES
from shadowflow.nodes.evaluation.scenes import write_shadowed_face
from shadowflow.nodes.geometry.reflectance import light_from_angles

distributed = pytest.importorskip("distributed")
pytestmark = pytest.mark.slow  # each case runs whole CLI processes (and clusters)
CLI = [sys.executable, "-m", "shadowflow.nodes.app.cli"]
FAST = ["--max-iterations", "12", "--record", "mcap,rerun", "--quiet"]


def _inputs(folder: Path, n: int) -> None:
    """``n`` faces (copies of 4) with sidecar lights, and three bad inputs."""
    folder.mkdir()
    rng = np.random.default_rng(11)
    base = [write_shadowed_face(folder / f"b{i}.png", rng, light_from_angles(30 + 10 * i)) for i in range(4)]
    for k in range(n):
        shutil.copy(base[k % 4], folder / f"face-{k:02d}.png")
        shutil.copy(base[k % 4].with_suffix(".json"), folder / f"face-{k:02d}.json")
    for p in base:
        p.unlink()
        p.with_suffix(".json").unlink()
    (folder / "garbage.png").write_bytes(b"not an image")
    (folder / "empty.jpg").write_bytes(b"")
    (folder / "tiny.png").write_bytes((folder / "face-00.png").read_bytes()[:60])


def test_a_local_cluster_gives_the_local_engines_outputs_and_recordings(tmp_path):
    src = tmp_path / "in"
    _inputs(src, 6)
    local = subprocess.run(CLI + ["run", str(src), "--out", str(tmp_path / "local")] + FAST,
                           capture_output=True, text=True, timeout=300)
    dask = subprocess.run(CLI + ["run", str(src), "--out", str(tmp_path / "dask"), "--dask", "local:2"] + FAST,
                          capture_output=True, text=True, timeout=300)
    assert local.returncode == dask.returncode == 1, dask.stderr  # the bad inputs failed, alone
    a = json.loads((tmp_path / "local" / "summary.json").read_text())
    b = json.loads((tmp_path / "dask" / "summary.json").read_text())
    strip = lambda recs: [{k: v for k, v in r.items() if k != "seconds"} for r in recs]  # noqa: E731
    assert strip(a) == strip(b) and sum(r["status"] == "ok" for r in b) == 6
    for r in a:
        if r["status"] == "ok":
            for name in OUTPUT_FILES:
                assert (tmp_path / "local" / r["stem"] / name).read_bytes() == \
                    (tmp_path / "dask" / r["stem"] / name).read_bytes(), (r["stem"], name)
    diff = subprocess.run(CLI + ["diff", str(tmp_path / "local"), str(tmp_path / "dask")], capture_output=True,
                          text=True, timeout=300)
    assert diff.returncode == 0 and diff.stdout.startswith("same: 9 frames"), diff.stdout + diff.stderr
    # each worker recorded the frames it ran, in parts of its own that the manifest lists
    listed = RunManifest.load(tmp_path / "dask").recordings
    parts = sorted(p.name for p in (tmp_path / "dask").glob("run.worker-*.mcap"))
    assert parts and set(parts) <= set(listed), (parts, listed)
    assert all(p.replace(".mcap", ".rrd") in listed for p in parts)
    rc = pytest.importorskip("rerun.chunk")
    shown = "".join(str(rc.RrdReader(tmp_path / "dask" / p.replace(".mcap", ".rrd")).store().summary()) for p in parts)
    assert all(f"/status/{r['stem']}" in shown for r in b)  # every frame in the workers' .rrd parts


def test_sigint_then_resume_on_a_cluster_completes_the_job(tmp_path):
    """SIGINT stops a Dask run as it stops a local one (exit 130, finished frames kept), and
    ``--resume`` on the cluster completes it: outputs and the merged recordings equal one
    uninterrupted local run."""
    src = tmp_path / "in"
    _inputs(src, 30)
    out = tmp_path / "out"
    proc = subprocess.Popen(CLI + ["run", str(src), "--out", str(out), "--dask", "local:2"] + FAST,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline:
        man = RunManifest.load(out)
        if man is not None and len(man.entries) >= 5:  # the three bad inputs come first
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 130 and "--resume" in err, err
    stopped_at = len(RunManifest.load(out).entries)
    assert 5 <= stopped_at < 33, stopped_at
    resumed = subprocess.run(CLI + ["run", str(src), "--out", str(out), "--dask", "local:2", "--resume"] + FAST,
                             capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 1, resumed.stderr  # the three bad inputs fail again, alone
    summary = json.loads((out / "summary.json").read_text())
    assert sorted(Path(r["source"]).name for r in summary) == sorted(p.name for p in src.iterdir()
                                                                       if p.suffix != ".json")
    fresh = tmp_path / "fresh"
    assert subprocess.run(CLI + ["run", str(src), "--out", str(fresh)] + FAST, timeout=300).returncode == 1
    for r in summary:
        if r["status"] == "ok":
            assert (out / r["stem"] / "normals.npy").read_bytes() == (fresh / r["stem"] / "normals.npy").read_bytes()
    # Not asserted: the merged recordings equal the fresh run's. A task cancelled by the stop but
    # already running on a worker still records its frame there, and the resumed run gives that
    # input a new frame id, so `diff` can see it twice (a known defect, see the README's Dask section).


def test_frame_timeout_holds_on_a_cluster(tmp_path):
    src = tmp_path / "in"
    _inputs(src, 2)
    out = tmp_path / "out"
    proc = subprocess.run(CLI + ["run", str(src), "--out", str(out), "--dask", "local:1", "--frame-timeout", "0.01"]
                          + FAST, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    faces = [r for r in summary if Path(r["source"]).name.startswith("face-")]
    assert len(faces) == 2 and all("timed out after 0.01 s" in r["status"] for r in faces), summary
    assert not any((out / r["stem"] / "normals.npy").exists() for r in faces)
    from shadowflow.flow.replay import open_frames

    recorded = {Path(f.record["source"]).name: f.record["status"] for f in open_frames(out, arrays=False) if f.finished}
    assert recorded == {Path(r["source"]).name: r["status"] for r in summary}


def _started_run(src: Path, out: Path, address: str, frames: int, timeout: float = 180.0) -> subprocess.Popen:
    """``run SRC --dask ADDRESS`` started, once its journal holds ``frames`` finished frames (or ``timeout``)."""
    proc = subprocess.Popen(CLI + ["run", str(src), "--out", str(out), "--dask", address] + FAST,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + timeout
    while time.time() < deadline:
        man = RunManifest.load(out)
        if man is not None and len(man.entries) >= frames:
            break
        time.sleep(0.05)
    return proc


def test_a_worker_killed_mid_run_loses_no_frame_and_writes_none_twice(tmp_path):
    src = tmp_path / "in"
    _inputs(src, 24)
    out = tmp_path / "out"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        pids = list(client.run(os.getpid).values())
        proc = _started_run(src, out, cluster.scheduler_address, frames=4)
        os.kill(pids[0], signal.SIGKILL)  # a worker dies with frames in hand
        killed_at = len(RunManifest.load(out).entries)
        _, err = proc.communicate(timeout=300)
    assert killed_at < 27, "the kill came after the run had finished"
    assert proc.returncode == 1, err
    summary = json.loads((out / "summary.json").read_text())
    sources = [Path(r["source"]).name for r in summary]
    assert sorted(sources) == sorted(p.name for p in src.iterdir() if p.suffix != ".json")  # each once
    assert sum(r["status"] == "ok" for r in summary) == 24, [r["status"] for r in summary if r["status"] != "ok"]
    assert all(not p.name.endswith(".tmp") for p in out.rglob("*"))  # no partial file left
    fresh = tmp_path / "fresh"
    assert subprocess.run(CLI + ["run", str(src), "--out", str(fresh)] + FAST, timeout=300).returncode == 1
    diff = subprocess.run(CLI + ["diff", str(out), str(fresh)], capture_output=True, text=True, timeout=300)
    assert diff.returncode == 0 and diff.stdout.startswith("same: 27 frames"), diff.stdout + diff.stderr


def test_dask_arguments_are_checked_before_any_work(tmp_path):
    for spec, says in [("local:0", "local:N needs N >= 1"), ("mars", "--dask takes local"),
                       ("env", "DASK_SCHEDULER_ADDRESS is not set")]:
        env = {k: v for k, v in os.environ.items() if k != "DASK_SCHEDULER_ADDRESS"}
        proc = subprocess.run(CLI + ["run", "x.png", "--out", str(tmp_path / "o"), "--dask", spec],
                              capture_output=True, text=True, timeout=60, env=env)
        assert proc.returncode == 2 and says in proc.stderr and not (tmp_path / "o").exists(), proc.stderr


def test_eval_spread_over_a_cluster_reports_the_same_figures(tmp_path):
    """``eval --dask`` runs each (face, light) as a task: the report equals the local one's."""
    base = ["eval", "--source", "procedural", "--n-train", "24", "--n-test", "6", "--modes", "12",
            "--size", "64,64", "--angles", "45,70"]
    reports = {}
    for name, extra in (("local", []), ("dask", ["--dask", "local:2"])):
        path = tmp_path / f"{name}.json"
        proc = subprocess.run(CLI + base + extra + ["--json", str(path)], capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr
        reports[name] = json.loads(path.read_text())
    for angle in ("45", "70"):
        a, b = reports["local"]["results"]["gauss-newton"][angle], reports["dask"]["results"]["gauss-newton"][angle]
        a.pop("seconds_per_face")
        b.pop("seconds_per_face")
        assert a == b, (angle, a, b)
    assert 0 < reports["dask"]["results"]["gauss-newton"]["45"]["err_all"] < 30


def test_local_runs_its_scheduler_outside_the_client():
    """``--dask local:N``: the scheduler keeps state per task, so it runs in a process of its own and
    the client's memory does not grow with the stream (``flow.cluster_host``)."""
    from shadowflow.nodes.app.cluster import dask_client

    with dask_client("local:1") as client:
        assert client.run_on_scheduler(os.getpid) != os.getpid()
        assert os.getpid() not in client.run(os.getpid).values()


def test_the_scheduler_dying_mid_run_ends_in_one_line_and_resume_completes(tmp_path):
    """Issue 39 #20: the Dask scheduler killed mid-run ended the run in a traceback. Now the frames out
    are left for ``--resume`` and the run says why in one line, exit 1."""
    import socket

    src = tmp_path / "in"
    _inputs(src, 16)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "start_new_session": True}
    scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                  "--port", str(port), "--no-dashboard"], **quiet)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                               "--nworkers", "1", "--no-dashboard"], **quiet)
    out = tmp_path / "out"
    try:
        proc = _started_run(src, out, address, frames=4)
        scheduler.kill()
        killed_at = len(RunManifest.load(out).entries)
        _, err = proc.communicate(timeout=300)
    finally:
        for p in (scheduler, worker):
            p.kill()
            p.wait()
    assert killed_at < 19, "the kill came after the run had finished"
    assert proc.returncode == 1, err
    lines = [line for line in err.strip().splitlines() if "empty.jpg" not in line]  # a bad input's own line
    assert len(lines) == 1 and "the Dask scheduler at " + address + " went away" in lines[0] and "--resume" in lines[0]
    summary = json.loads((out / "summary.json").read_text())
    assert 4 <= len(summary) < 19
    resumed = subprocess.run(CLI + ["run", str(src), "--out", str(out), "--resume"] + FAST, capture_output=True,
                             text=True, timeout=300)
    assert resumed.returncode == 1, resumed.stderr  # the three bad inputs
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary) == 19 and sum(r["status"] == "ok" for r in summary) == 16
    fresh = tmp_path / "fresh"
    assert subprocess.run(CLI + ["run", str(src), "--out", str(fresh)] + FAST, timeout=300).returncode == 1
    diff = subprocess.run(CLI + ["diff", str(out), str(fresh)], capture_output=True, text=True, timeout=300)
    assert diff.returncode == 0 and diff.stdout.startswith("same: 19 frames"), diff.stdout + diff.stderr
