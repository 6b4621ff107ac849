"""diagnose --jobs: the fits run side by side in worker processes and the outputs do not change."""
from __future__ import annotations

import json
import os
import re

import numpy as np
import pytest

from click.testing import CliRunner

from fluidnexus_cli.main import main
from fluidnexus.diagnose.parallel import MAX_JOBS, FitPool, plan_jobs
from fluidnexus.diagnose.plume import PlumeSetup, PlumeSimulator
from fluidnexus.diagnose.search import Fitter
from fluidnexus.memory import RUNTIME_BYTES

from .eulerian_plume import Grid, PlumeEffects, simulate, write_scene


@pytest.mark.slow  # two in-process diagnoses: 101 s in the suite (2026-11-27)
def test_jobs_do_not_change_the_report(template, tmp_path, ti_engine):
    """A short windy plume around a declared ball diagnosed with one process and with two: report.json and
    model.json are identical (same rollouts, the same ball built in each worker, same fits, the search spread over
    the same scored models), and so is report.md but for its wall time."""
    scene = write_scene(template, tmp_path / "scene", simulate(12, PlumeEffects(wind=(0.1, 0.0, 0.0))))
    data, source = json.loads((scene / "scene.json").read_text()), Grid().source
    data["obstacles"] = [{"kind": "sphere", "center": [source[0], source[1] + 0.15, source[2]], "radius": 0.04}]
    (scene / "scene.json").write_text(json.dumps(data))
    outputs = []
    for jobs in ("1", "2"):
        out = tmp_path / f"jobs{jobs}"
        result = CliRunner().invoke(main, ["diagnose", str(scene), "--out", str(out), "--train-frames", "0:8",
                                           "--validate-frames", "8:12", "--evals", "3", "--height", "24",
                                           "--arch", "cpu", "--jobs", jobs])
        assert result.exit_code == 0, result.output + repr(result.exception)
        outputs.append([json.loads((out / name).read_text()) for name in ("report.json", "model.json")])
        outputs[-1].append(re.sub(r"rollouts, \d+ s\.", "rollouts.", (out / "report.md").read_text()))
    assert outputs[0] == outputs[1]


@pytest.mark.parametrize("args", [["--jobs", "0"], ["--jobs", "8", "--max-memory", "2G"]])
def test_bad_jobs_are_refused(template, tmp_path, args):
    """Zero processes, or more worker processes than the memory limit holds (each has a runtime of its own): one
    line naming --jobs, exit 2, nothing written."""
    result = CliRunner().invoke(main, ["diagnose", str(template), "--out", str(tmp_path / "d"), "--arch", "cpu",
                                       *args])
    assert result.exit_code == 2 and "--jobs" in result.output, result.output
    assert "Traceback" not in result.output and not (tmp_path / "d").exists()


def test_default_jobs_follow_cores_memory_and_arch():
    cores = len(os.sched_getaffinity(0))
    assert plan_jobs(None, "cpu", 100 * RUNTIME_BYTES) == min(MAX_JOBS, cores)
    assert plan_jobs(None, "cpu", 2 * RUNTIME_BYTES) == 1  # this process and one worker: no room for a second
    assert plan_jobs(None, "cuda", 100 * RUNTIME_BYTES) == 1
    assert plan_jobs(3, "cpu", 100 * RUNTIME_BYTES) == 3


def _probe(fitter, mark: int) -> tuple[int, int]:
    """A fit task that scores nothing real: (this worker's pid, models its fitter had scored), then one scored."""
    before = len(fitter.scored)
    fitter.scored.append(("probe", (), np.full(1, float(mark))))
    return os.getpid(), before


def test_renewed_workers_start_the_phase_with_an_empty_record(ti_engine):
    """FitPool.renew (diagnose's confirmation): the same worker processes go on, each with a fitter that has
    scored nothing yet, as a new worker's would; the pool's fitter collects only the new phase's models."""
    setup = PlumeSetup((0.0, 0.0, 0.0), 0.05, 0.02, 30.0, 4, (-0.5, -0.5, -0.5), (0.5, 0.5, 0.5), np.zeros((0, 3)),
                       np.zeros((0, 3)))
    cameras, train = [], np.arange(2)
    first = Fitter(PlumeSimulator(setup), np.zeros((1, 4, 2, 2)), cameras, 1.0, train)
    with FitPool(first, 2) as pool:
        before = pool.map(_probe, [(k,) for k in range(6)])
        workers = set(pool._pool._processes)  # both, whichever took the probes (one may have taken all six)
        second = pool.renew()
        after = pool.map(_probe, [(k,) for k in range(6, 12)])
        assert set(pool._pool._processes) == workers and {pid for pid, _ in after} <= workers  # the workers stayed
    assert second is not first and second.sim is first.sim and second.observed is first.observed
    for phase in (before, after):
        for pid in {p for p, _ in phase}:
            assert sorted(n for p, n in phase if p == pid)[0] == 0, phase  # each worker's record starts empty
    assert [float(s[2][0]) for s in first.scored] == list(range(6))
    assert [float(s[2][0]) for s in second.scored] == list(range(6, 12))
