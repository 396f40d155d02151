"""Tests of pbvs_pin.study.sweep: specs, run ids, executors, resume and failure recording.

One small sweep (4 runs of 1 s, two of them with an invalid filter gain) is run on the local
process pool, on a Dask LocalCluster on loopback, after a run limit and after a SIGKILL; every
table must equal the uninterrupted process-pool table byte for byte.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pbvs_pin.cli import main
from pbvs_pin.exceptions import ScenarioError
from pbvs_pin.sim.log import RunLog
from pbvs_pin.sim.scenario import load_scenario
from pbvs_pin.study.sweep import (
    TABLE,
    TIMINGS,
    RunTask,
    derive_seed,
    divergence,
    load_sweep,
    run_id_of,
    run_one,
    run_sweep,
)

REPO_ROOT = Path(__file__).resolve().parents[1]

SPEC = """
[sweep]
scenario = "experiment1"
seed = 5
timeout = 120.0

[fixed]
duration = 1.0
"camera.noise_px" = 0.0

[grid]
"motion.velocity" = [[0.05, 0.02, 0.0], [0.10, 0.04, 0.0]]
estimator.alpha = [0.5, 1.5]  # 1.5 is outside (0, 1]: two runs fail
"""


def write_spec(folder: Path, text: str = SPEC, name: str = "spec.toml") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text)
    return path


def rows(table: Path) -> list[dict[str, str]]:
    with table.open(newline="") as handle:
        return list(csv.DictReader(handle))


def executed(out: Path) -> list[str]:
    """Run ids in timings.csv: one line per run actually executed."""
    return [row["run_id"] for row in rows(out / TIMINGS)] if (out / TIMINGS).exists() else []


@pytest.fixture(scope="module")
def spec(tmp_path_factory) -> Path:
    return write_spec(tmp_path_factory.mktemp("spec"))


@pytest.fixture(scope="module")
def reference(spec, tmp_path_factory) -> Path:
    """The sweep, uninterrupted, on a local pool of two processes."""
    out = tmp_path_factory.mktemp("pool")
    return run_sweep(spec, out, workers=2, progress=False)


# ------------------------------------------------------------------------ the spec
def test_grid_runs_ids_and_seeds(spec):
    sweep = load_sweep(spec)
    assert sweep.fields == ("motion.velocity", "estimator.alpha")
    assert sweep.runs == (
        {"motion.velocity": [0.05, 0.02, 0.0], "estimator.alpha": 0.5},
        {"motion.velocity": [0.05, 0.02, 0.0], "estimator.alpha": 1.5},
        {"motion.velocity": [0.1, 0.04, 0.0], "estimator.alpha": 0.5},
        {"motion.velocity": [0.1, 0.04, 0.0], "estimator.alpha": 1.5},
    )
    assert sweep.scenario.camera.noise_px == 0.0
    params = {"motion.velocity": [0.1, 0.04, 0.0], "estimator.alpha": 0.5}
    canonical = '{"estimator.alpha":0.5,"motion.velocity":[0.1,0.04,0.0]}'
    expected = hashlib.sha256(canonical.encode()).hexdigest()[:16]
    assert run_id_of(params) == expected
    assert run_id_of(dict(reversed(params.items()))) == expected
    task = next(t for t in sweep.tasks() if t.run_id == expected)
    digest = hashlib.sha256(f"5/{expected}".encode()).digest()
    assert task.seed == derive_seed(5, expected) == int.from_bytes(digest[:4], "little")


def test_random_sample_is_reproducible_and_grows(tmp_path):
    text = """
[sweep]
scenario = "experiment1"
[random]
n = {n}
seed = 3
"camera.noise_px" = {{ range = [0.0, 2.0] }}
"estimator.beta" = {{ range = [0.01, 0.5], log = true }}
"motion.velocity" = {{ range = [[0.0, 0.0, 0.0], [0.2, 0.1, 0.0]] }}
"estimator.kind" = {{ choices = ["alpha_beta", "exact"] }}
"camera.width" = {{ range = [600, 640] }}
"""
    small = load_sweep(write_spec(tmp_path, text.format(n=3), "a.toml"))
    again = load_sweep(write_spec(tmp_path, text.format(n=3), "b.toml"))
    large = load_sweep(write_spec(tmp_path, text.format(n=6), "c.toml"))
    assert small.runs == again.runs
    assert large.runs[:3] == small.runs
    for run in large.runs:
        assert 0.0 <= run["camera.noise_px"] <= 2.0
        assert 0.01 <= run["estimator.beta"] <= 0.5
        assert len(run["motion.velocity"]) == 3 and run["motion.velocity"][2] == 0.0
        assert run["estimator.kind"] in ("alpha_beta", "exact")
        assert isinstance(run["camera.width"], int) and 600 <= run["camera.width"] <= 640


@pytest.mark.parametrize(
    ("text", "field"),
    [
        (
            '[sweep]\nscenario = "experiment1"\n[grid]\n"motion.speed" = [1.0]\n',
            "grid.motion.speed",
        ),
        ('[sweep]\nscenario = "experiment1"\n[grid]\nduration = 3.0\n', "grid.duration"),
        (
            '[sweep]\nscenario = "experiment1"\n[fixed]\nfoo = 1\n[grid]\nduration = [1.0]\n',
            "fixed.foo",
        ),
        ('[sweep]\nscenario = "experiment1"\n', ""),
        (
            '[sweep]\nscenario = "experiment1"\nepsilon = 2.0\n[grid]\nduration = [1.0]\n',
            "sweep.epsilon",
        ),
        ('[sweep]\nscenario = "nope"\n[grid]\nduration = [1.0]\n', "sweep.scenario"),
        (
            '[sweep]\nscenario = "experiment1"\n[random]\nn = 2\nduration = { range = [3.0, 1.0] }\n',
            "random.duration.range",
        ),
        (
            '[sweep]\nscenario = "experiment1"\n[random]\nn = 0\nduration = { range = [1.0, 3.0] }\n',
            "random.n",
        ),
    ],
)
def test_spec_errors_name_the_file_and_field(tmp_path, text, field):
    path = write_spec(tmp_path, text)
    with pytest.raises(ScenarioError) as info:
        load_sweep(path)
    assert str(path) in str(info.value)
    assert info.value.field == field


def test_shipped_spec_loads():
    sweep = load_sweep("target_speed")
    assert len(sweep.runs) == 6
    assert sweep.scenario.duration == 12.0


# ------------------------------------------------------------------------ one run
def small_task(**params) -> RunTask:
    scenario = load_scenario("experiment1").with_values(duration=0.2)
    return RunTask(run_id_of(params), params, 1, scenario, 0.5, 60.0)


def test_a_raising_run_is_recorded(monkeypatch):
    import pbvs_pin.sim.loop

    def boom(*args, **kwargs):
        raise RuntimeError("forced failure")

    monkeypatch.setattr(pbvs_pin.sim.loop, "simulate", boom)
    row, _ = run_one(small_task())
    assert row["status"] == "failed"
    assert row["reason"] == "RuntimeError: forced failure"


def test_a_run_past_its_timeout_is_recorded():
    task = small_task()
    task = RunTask(task.run_id, task.params, task.seed, task.scenario, 0.5, timeout=1e-6)
    row, _ = run_one(task)
    assert row["status"] == "failed"
    assert row["reason"].startswith("timeout:")


def test_divergence_is_detected():
    t = np.linspace(0.0, 1.0, 5)
    log = RunLog(
        {
            "t": t,
            "q": np.zeros((5, 6)),
            "v": np.zeros((5, 5)),
            "xi_true": np.tile([0.0, 60.0, -60.0], (5, 1)),
        },
        {"camera": {"width": 628, "height": 582}},
    )
    assert divergence(log) is None
    log.channels["xi_true"][-1] = [400.0, 60.0, -60.0]
    assert "outside the image" in divergence(log)
    log.channels["v"][3, 2] = np.inf
    assert "non-finite v from t = 0.75 s" in divergence(log)


# ------------------------------------------------------------------------ whole sweeps
def test_failed_runs_are_recorded_and_the_sweep_goes_on(reference):
    table = rows(reference)
    assert [row["run_id"] for row in table] == sorted(row["run_id"] for row in table)
    assert len(table) == 4
    by_alpha = {}
    for row in table:
        by_alpha.setdefault(row["estimator.alpha"], []).append(row)
    assert all(row["status"] == "ok" and row["reason"] == "" for row in by_alpha["0.5"])
    for row in by_alpha["1.5"]:
        assert row["status"] == "failed"
        assert "alpha" in row["reason"] and "1.5" in row["reason"]
    for row in by_alpha["0.5"]:
        assert float(row["lambda"]) > 0
        assert row["passivity9_holds"] in ("true", "false")
        assert float(row["max_abs_error_final_window_px"]) >= 0
    assert sorted(executed(reference.parent)) == sorted(row["run_id"] for row in table)
    assert (reference.parent / "results.parquet").stat().st_size > 0
    assert (reference.parent / "final_error_vs_speed.png").stat().st_size > 0


def test_dask_local_cluster_gives_the_same_table(spec, reference, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        table = run_sweep(spec, tmp_path, scheduler=cluster.scheduler_address, progress=False)
    assert table.read_bytes() == reference.read_bytes()


def test_resume_after_a_run_limit_redoes_nothing(spec, reference, tmp_path):
    run_sweep(spec, tmp_path, workers=1, max_runs=1, progress=False)
    first = executed(tmp_path)
    assert len(rows(tmp_path / TABLE)) == len(first) == 1
    run_sweep(spec, tmp_path, workers=2, progress=False)
    runs = executed(tmp_path)
    assert len(runs) == len(set(runs)) == 4
    assert (tmp_path / TABLE).read_bytes() == reference.read_bytes()


def interrupt_cli_sweep(spec: Path, out: Path) -> None:
    """Start ``pbvs-pin sweep`` in a new session; SIGKILL it and its workers after one run."""
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(REPO_ROOT), os.environ.get("PYTHONPATH", "")])
    )
    command = [
        sys.executable,
        "-m",
        "pbvs_pin.cli",
        "sweep",
        str(spec),
        "--out",
        str(out),
        "--workers",
        "1",
    ]
    process = subprocess.Popen(
        command,
        env=env,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 60.0
    try:
        while time.monotonic() < deadline and not executed(out) and process.poll() is None:
            time.sleep(0.01)
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()


def test_resume_after_a_kill_loses_nothing(spec, reference, tmp_path):
    for attempt in range(3):  # on a loaded machine the sweep may end before the kill lands
        out = tmp_path / f"attempt{attempt}"
        interrupt_cli_sweep(spec, out)
        recorded = [row["run_id"] for row in rows(out / TABLE)] if (out / TABLE).exists() else []
        if 1 <= len(recorded) < 4:
            break
    else:
        pytest.fail(f"could not interrupt the sweep part-way: {len(recorded)} rows recorded")
    before = executed(out)
    with (out / TABLE).open("a") as handle:  # a line torn by the kill
        handle.write("0123456789abcdef,ok,,12")
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "2"]) == 0
    after = executed(out)[len(before) :]
    assert not set(recorded) & set(after), f"finished runs {recorded} run again: {after}"
    assert sorted(recorded + after) == sorted(row["run_id"] for row in rows(reference))
    assert (out / TABLE).read_bytes() == reference.read_bytes()


def test_a_folder_of_another_sweep_is_refused(reference, tmp_path):
    other = write_spec(tmp_path, SPEC.replace("seed = 5", "seed = 6"))
    with pytest.raises(ScenarioError, match="another output folder"):
        run_sweep(other, reference.parent, workers=1, progress=False)
    meta = json.loads((reference.parent / "sweep.json").read_text())
    assert meta["seed"] == 5 and meta["runs"] == 4
