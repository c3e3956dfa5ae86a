"""Many sessions at once (issue 19): handeye calibrate S1 S2 ... --out DIR, in local processes and on a
Dask LocalCluster with the same results; a failing session reported, the others done."""

from __future__ import annotations

import json

import numpy as np
import pytest

from handeye.cli import main
from handeye.simulate import simulate_session
from handeye.workflows.fleet import calibrate_many


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    for k in range(3):
        simulate_session(root / f"cell{k}", seed=k, n_poses=6, robot_noise=(0.02, 0.1))
    (root / "broken").mkdir()
    return root


@pytest.mark.slow
def test_fleet_local_and_dask_give_the_same_calibrations(fleet, capsys):
    cells = [str(fleet / f"cell{k}") for k in range(3)]
    status = main(["calibrate", *cells, str(fleet / "broken"), "--out", str(fleet / "local"), "--jobs", "2",
                   "--no-progress"])
    text = capsys.readouterr().out
    assert status == 2 and "FAILED" in text and "no session.yaml" in text  # the others are done
    summary = json.loads((fleet / "local" / "fleet.json").read_text())
    assert [s["error"] is None for s in summary] == [True, True, True, False]
    dask = calibrate_many(cells, fleet / "dask", scheduler="local", jobs=2, progress=False)
    for k, item in enumerate(dask):
        a = json.loads((fleet / "local" / f"cell{k}" / "result.json").read_text())["X"]["matrix"]
        b = json.loads((fleet / "dask" / f"cell{k}" / "result.json").read_text())["X"]["matrix"]
        assert np.array_equal(a, b) and item.verdict == summary[k]["verdict"]


def test_fleet_needs_out_and_scheduler_needs_several(fleet, capsys):
    assert main(["calibrate", str(fleet / "cell0"), str(fleet / "cell1")]) == 2
    assert "several sessions need --out" in capsys.readouterr().err
    assert main(["calibrate", str(fleet / "cell0"), "--scheduler", "local"]) == 2
    assert "give more than one session folder" in capsys.readouterr().err


@pytest.mark.slow
def test_fleet_passes_the_write_options_to_every_session(fleet, capsys):
    cells = [str(fleet / f"cell{k}") for k in range(2)]
    status = main(["calibrate", *cells, "--out", str(fleet / "named"), "--jobs", "1", "--no-progress",
                   "--child-frame", "wrist_cam_optical", "--export", "ros2-launch"])
    assert status in (0, 1) and "FAILED" not in capsys.readouterr().out  # 1: a weak verdict, not a failure
    for k in range(2):
        folder = fleet / "named" / f"cell{k}"
        assert "wrist_cam_optical" in (folder / "result.yaml").read_text()
        assert any("launch" in p.name for p in folder.iterdir())


def _worker_environment() -> tuple[str | None, str | None, bool, str]:
    import os

    import dask

    return (os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("OPENBLAS_NUM_THREADS"),
            dask.config.get("distributed.worker.profile.enabled"), dask.config.get("distributed.admin.tick.interval"))


@pytest.mark.slow
def test_sessions_side_by_side_run_one_thread_each():
    # two workers each spreading OpenCV and OpenBLAS over both cores fight over them; Dask's
    # eager malloc trimming cost its workers ~15%, its profiler ~5%, its 20 ms ticks more (issue 37's fleet)
    import cv2
    from threadpoolctl import threadpool_info, threadpool_limits

    from handeye._shared.cluster import dask_client, single_threaded

    saved = cv2.getNumThreads()
    cv2.setNumThreads(3)
    try:
        with threadpool_limits(2, user_api="blas"):  # the suite runs BLAS on one thread (conftest.py): two here
            with single_threaded():
                assert cv2.getNumThreads() == 1
                assert all(pool["num_threads"] == 1 for pool in threadpool_info())
        assert cv2.getNumThreads() == 3
    finally:
        cv2.setNumThreads(saved)
    pytest.importorskip("distributed")
    with dask_client("local", 1) as client:
        environments = list(client.run(_worker_environment).values())
    assert environments == [(None, "1", False, "500ms")]  # Dask's other settings kept
