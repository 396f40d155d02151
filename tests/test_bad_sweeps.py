"""Sweeps that lose their executor, are killed or point at the wrong folder (issue 12).

A lost scheduler or worker must leave its runs unrecorded and end the sweep with
:class:`SweepIncomplete` (a resume then runs exactly those); workers must not outlive the
sweep's process, even after a SIGKILL; SIGTERM stops the sweep with one line and exit 2; a
folder with results whose ``sweep.json`` is missing or unreadable is refused unless forced;
an address that does not speak Dask's protocol is refused within the probe's timeout.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
from concurrent.futures import Executor, Future
from pathlib import Path

import pytest

from pbvs_pin.exceptions import PbvsError, ScenarioError, SweepIncomplete
from pbvs_pin.study.sweep import TABLE, TIMINGS, load_sweep, run_sweep
from pbvs_pin.study.sweep import driver as sweep_driver
from pbvs_pin.study.sweep.executors import execute, probe_scheduler
from pbvs_pin.study.sweep.table import check_folder

REPO_ROOT = Path(__file__).resolve().parents[1]

SPEC = """
[sweep]
scenario = "experiment1"
seed = 3
timeout = 120.0

[fixed]
duration = 0.5
"camera.noise_px" = 0.0

[grid]
estimator.alpha = [0.4, 0.5, 0.6]
"""


@pytest.fixture
def spec(tmp_path) -> Path:
    path = tmp_path / "spec.toml"
    path.write_text(SPEC)
    return path


class LosingExecutor(Executor):
    """Runs tasks in the calling thread; the ones in ``lost`` fail as a lost scheduler does."""

    def __init__(self, lost: set[str]) -> None:
        self.lost = lost
        self.submitted: list[str] = []

    def submit(self, fn, task):
        future: Future = Future()
        self.submitted.append(task.run_id)
        if task.run_id in self.lost:
            future.set_exception(OSError("lost connection to the scheduler"))
        else:
            future.set_result(fn(task))
        return future


def fake_result(task):
    return {"run_id": task.run_id, "status": "ok", "reason": ""}, {"run_id": task.run_id}


def test_a_lost_executor_records_nothing_and_stops_submitting(spec):
    tasks = load_sweep(spec).tasks(None)
    executor = LosingExecutor({tasks[0].run_id})
    unfinished: list = []
    done = [row["run_id"] for row, _ in execute(lambda: executor, tasks, 1, unfinished)]
    assert done == []
    assert [task.run_id for task, _ in unfinished] == [t.run_id for t in tasks]
    assert "lost connection" in unfinished[0][1]
    assert executor.submitted == [tasks[0].run_id]  # nothing new after the failure


def test_a_resume_reruns_every_run_the_lost_executor_did_not_finish(spec, tmp_path, monkeypatch):
    tasks = load_sweep(spec).tasks(None)
    lost = {tasks[1].run_id}
    monkeypatch.setattr(sweep_driver, "process_pool", lambda count: LosingExecutor(lost))
    out = tmp_path / "out"
    with pytest.raises(SweepIncomplete, match=r"2 of 3 runs did not finish") as err:
        run_sweep(spec, out, workers=1, progress=False)
    assert "\n" not in str(err.value)
    recorded = [row["run_id"] for row in csv.DictReader((out / TABLE).open())]
    assert recorded == [tasks[0].run_id]  # the lost run and the one never started are absent
    executor = LosingExecutor(set())
    monkeypatch.setattr(sweep_driver, "process_pool", lambda count: executor)
    run_sweep(spec, out, workers=1, progress=False)
    assert sorted(executor.submitted) == sorted(t.run_id for t in tasks[1:])
    rows = list(csv.DictReader((out / TABLE).open()))
    assert sorted(row["run_id"] for row in rows) == sorted(t.run_id for t in tasks)
    assert all(row["status"] == "ok" for row in rows)


@pytest.mark.parametrize(
    ("files", "problem"),
    [
        ({TABLE: "run_id,status\n"}, "no sweep.json"),
        ({TIMINGS: "run_id,worker\n"}, "no sweep.json"),
        ({TABLE: "run_id,status\n", "sweep.json": ""}, "unreadable"),
        ({"sweep.json": "{not json"}, "unreadable"),
        ({"sweep.json": "[1, 2]"}, "unreadable"),
        ({"sweep.json": '{"name": "x"}'}, "no fingerprint"),
    ],
    ids=["table-only", "timings-only", "empty-json", "broken-json", "json-list", "no-fingerprint"],
)
def test_a_folder_without_a_readable_sweep_json_is_refused_unless_forced(
    spec, tmp_path, files, problem
):
    out = tmp_path / "out"
    out.mkdir()
    for name, text in files.items():
        (out / name).write_text(text)
    sweep = load_sweep(spec)
    with pytest.raises(ScenarioError, match=problem) as err:
        check_folder(sweep, out)
    assert "--force" in str(err.value)
    check_folder(sweep, out, force=True)
    assert json.loads((out / "sweep.json").read_text())["fingerprint"] == sweep.fingerprint


def test_an_empty_new_folder_needs_no_force(spec, tmp_path):
    sweep = load_sweep(spec)
    check_folder(sweep, tmp_path)
    assert json.loads((tmp_path / "sweep.json").read_text())["runs"] == 3


def _serve(server: socket.socket, greeting: bytes) -> None:
    connection, _ = server.accept()
    with connection:
        connection.sendall(greeting)
        time.sleep(1.0)


@pytest.mark.parametrize(
    "greeting",
    [None, b"SSH-2.0-OpenSSH_9.2\r\n", b"HTTP/1.1 400 Bad Request\r\n\r\n", b"\x05\x00"],
    ids=["silent", "ssh-banner", "http", "short-and-closed"],
)
def test_a_service_that_is_not_a_dask_scheduler_is_refused_in_time(greeting):
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        if greeting is not None:
            threading.Thread(target=_serve, args=(server, greeting), daemon=True).start()
        started = time.monotonic()
        with pytest.raises(PbvsError, match="Dask") as err:
            probe_scheduler(f"tcp://127.0.0.1:{server.getsockname()[1]}", timeout=0.5)
        assert time.monotonic() - started < 5.0
    assert type(err.value) is PbvsError and "--scheduler" in str(err.value)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as handle:  # a zombie is dead too
        return handle.read().split(")")[-1].split()[0] != "Z"


def _wait_dead(pids: list[int], seconds: float) -> list[int]:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and any(_alive(p) for p in pids):
        time.sleep(0.1)
    return [p for p in pids if _alive(p)]


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO_ROOT),
                                                        os.environ.get("PYTHONPATH", "")]))  # fmt: skip


def test_pool_workers_exit_when_the_sweep_process_is_killed(tmp_path):
    script = tmp_path / "killed_sweep.py"
    script.write_text(
        textwrap.dedent(
            """
            import os
            import signal

            from pbvs_pin.study.sweep.executors import process_pool

            if __name__ == "__main__":
                pool = process_pool(2)
                pids = {pool.submit(os.getpid).result() for _ in range(8)}
                print(" ".join(map(str, sorted(pids))), flush=True)
                os.kill(os.getpid(), signal.SIGKILL)
            """
        )
    )
    result = subprocess.run(
        [sys.executable, str(script)], env=_env(), capture_output=True, text=True, timeout=120
    )
    workers = [int(pid) for pid in result.stdout.split()]
    assert result.returncode == -signal.SIGKILL and workers
    assert _wait_dead(workers, 10.0) == []


def test_sigterm_stops_the_sweep_and_its_workers(spec, tmp_path):
    out = tmp_path / "out"
    process = subprocess.Popen(
        [sys.executable, "-m", "pbvs_pin.cli", "sweep", str(spec), "--out", str(out),
         "--workers", "2"],
        env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 120
    children: set[int] = set()
    while time.monotonic() < deadline and process.poll() is None:
        children |= {int(pid) for pid in _children(process.pid)}
        if len(children) >= 2 and (out / "sweep.json").exists():
            break
        time.sleep(0.05)
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    if process.returncode == 0:
        pytest.skip("the sweep finished before SIGTERM landed (a fast machine)")
    assert process.returncode == 2
    assert "Traceback" not in err
    assert "interrupted" in err.strip().splitlines()[-1]
    assert _wait_dead(sorted(children), 10.0) == []


def _children(pid: int) -> list[str]:
    """Process ids whose parent is ``pid`` and their descendants (Linux /proc)."""
    found = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            found += (task / "children").read_text().split()
        except OSError:
            continue
    return found + [grandchild for child in found for grandchild in _children(int(child))]
