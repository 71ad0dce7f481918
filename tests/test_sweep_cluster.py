"""fccgen sweep against a real Dask cluster: a ``dask scheduler`` and two ``dask
worker`` processes on 127.0.0.1, started here and stopped however the test ends."""
from __future__ import annotations

import csv
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.cli import main

DOUBLE = EXAMPLES / "double_pendulum.yaml"
MASSES = [0.4, 0.6, 0.9, 1.2]
T_END = 0.2


def dask_command() -> str | None:
    """The dask command line of this interpreter's environment, else of the PATH."""
    here = Path(sys.executable).parent / "dask"
    return str(here) if here.exists() else shutil.which("dask")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stop(procs) -> None:
    """Workers first (they would wait to reconnect to a scheduler that has gone), then
    the scheduler; SIGTERM, then SIGKILL for one that does not end."""
    for p in reversed(procs):
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


@pytest.mark.skipif(dask_command() is None,
                    reason="the dask command line (pip install 'dask[distributed]') is "
                           "not installed")
def test_sweep_on_a_scheduler_and_two_worker_processes(build_dir, tmp_path, capsys):
    from dask.distributed import Client
    solver = fccgen.load(DOUBLE, build_dir)             # compiled once, here
    dask = dask_command()
    address = f"tcp://127.0.0.1:{free_port()}"
    env = {**os.environ,
           "PYTHONPATH": str(Path(fccgen.__file__).resolve().parent.parent)}
    logs = open(tmp_path / "dask.log", "w")
    procs = []
    try:
        procs.append(subprocess.Popen(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1],
             "--no-dashboard"], stdout=logs, stderr=subprocess.STDOUT, cwd=tmp_path,
            env=env))
        for k in range(2):
            procs.append(subprocess.Popen(
                [dask, "worker", address, "--host", "127.0.0.1", "--nthreads", "1",
                 "--no-nanny", "--no-dashboard", "--name", f"w{k}",
                 "--local-directory", str(tmp_path / f"w{k}")],
                stdout=logs, stderr=subprocess.STDOUT, cwd=tmp_path, env=env))
        with Client(address, timeout=60) as client:   # guards against a hang only
            client.wait_for_workers(2, timeout=60)
            pids = set(client.run(os.getpid).values())
        assert len(pids) == 2 and os.getpid() not in pids   # two other processes

        out = tmp_path / "sweep.csv"
        code = main(["sweep", str(DOUBLE), "--build-dir", str(build_dir), "-q",
                     "--scheduler", address, "--set",
                     "bodies.rod2.mass=" + ",".join(map(str, MASSES)),
                     "--set", f"simulate.t_end={T_END}", "--out", str(out)])
        text = capsys.readouterr()
        assert code == 0, text.err
        assert f"4 runs (0 failed) on {address}" in text.out
        with open(out, newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert [float(r["bodies.rod2.mass"]) for r in rows] == MASSES
        for row, mass in zip(rows, MASSES):
            r = solver.with_parameters({"bodies.rod2.mass": mass}).simulate(t_end=T_END)
            assert row["status"] == "ok", row["error"]
            # other processes, the same module file and inputs: the same bits
            assert float(row["final.P2.x"]) == r["P2.x"][-1]
            assert float(row["final.P2.y"]) == r["P2.y"][-1]
    finally:
        stop(procs)
        logs.close()
    assert all(p.returncode is not None for p in procs)
