"""A pool worker started with ``exit_with_parent`` leaves when its parent is killed outright."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

PARENT = textwrap.dedent(
    """
    import multiprocessing, os, sys, time
    from concurrent.futures import ProcessPoolExecutor
    from handeye._shared.processes import exit_with_parent

    if __name__ == "__main__":
        kwargs = {"initializer": exit_with_parent} if sys.argv[1] == "watch" else {}
        pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), **kwargs)
        print(pool.submit(os.getpid).result(), flush=True)
        time.sleep(600)
    """
)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ")[1][0] != "Z"  # a zombie has exited
    except FileNotFoundError:
        return False


def _worker_after_parent_killed(tmp_path, mode: str, seconds: float) -> tuple[int, bool]:
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    parent = subprocess.Popen([sys.executable, str(script), mode], stdout=subprocess.PIPE, text=True)
    try:
        worker_pid = int(parent.stdout.readline())
    finally:
        parent.kill()
        parent.wait(30)
    end = time.monotonic() + seconds
    while _alive(worker_pid) and time.monotonic() < end:
        time.sleep(0.1)
    alive = _alive(worker_pid)
    if alive:
        os.kill(worker_pid, signal.SIGKILL)  # leave nothing behind, whatever the outcome
    return worker_pid, alive


@pytest.mark.slow
@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc")
def test_a_worker_leaves_when_its_parent_is_killed(tmp_path):
    _, alive = _worker_after_parent_killed(tmp_path, "watch", 5)
    assert not alive, "the worker outlived its killed parent"
    # without the watch the worker waits for ever (here: still there after 4 of the watch's periods)
    _, alive = _worker_after_parent_killed(tmp_path, "plain", 2)
    assert alive
