"""soft_envs.envs.threads: one compute thread in vector-environment workers, none changed in the
main process. Each check runs in a forked child so that this process keeps its settings."""
from __future__ import annotations

import multiprocessing
import os

import pytest

from soft_envs.envs.threads import limit_threads, limit_threads_in_worker

threadpoolctl = pytest.importorskip("threadpoolctl")


def _in_child(fn, *args):
    ctx = multiprocessing.get_context("fork")
    q = ctx.Queue()

    def target():
        try:
            q.put(("ok", fn(*args)))
        except Exception as exc:            # noqa: BLE001 - sent back to the test
            q.put(("error", repr(exc)))

    p = ctx.Process(target=target)
    p.start()
    result = q.get(timeout=60)
    p.join(timeout=60)
    return result


def _worker_pools(setting: str | None):
    if setting is None:
        os.environ.pop("SOFT_ENVS_WORKER_THREADS", None)
    else:
        os.environ["SOFT_ENVS_WORKER_THREADS"] = setting
    import numpy as np
    import scipy.linalg  # noqa: F401  (its OpenBLAS too)
    np.ones((4, 4)) @ np.ones((4, 4))
    applied = limit_threads_in_worker()
    pools = [(p["internal_api"], p["num_threads"]) for p in threadpoolctl.threadpool_info()]
    return applied, pools, os.environ.get("OMP_NUM_THREADS")


def test_worker_process_gets_one_thread_per_pool():
    status, (applied, pools, omp) = _in_child(_worker_pools, None)
    assert status == "ok" and applied is True
    assert pools and all(n == 1 for _, n in pools), pools
    assert omp == "1"                         # for the processes the worker starts


def test_worker_setting_zero_leaves_the_pools_and_a_number_sets_them():
    status, (applied, _, omp) = _in_child(_worker_pools, "0")
    assert status == "ok" and applied is False and omp == os.environ.get("OMP_NUM_THREADS")
    status, (applied, pools, omp) = _in_child(_worker_pools, "2")
    assert status == "ok" and applied is True and omp == "2"
    assert all(n <= 2 for _, n in pools)
    status, message = _in_child(_worker_pools, "many")
    assert status == "error" and "SOFT_ENVS_WORKER_THREADS must be an integer" in message


def test_main_process_is_left_alone_and_bad_counts_are_refused():
    before = [(p["internal_api"], p["num_threads"]) for p in threadpoolctl.threadpool_info()]
    assert limit_threads_in_worker() is False
    assert [(p["internal_api"], p["num_threads"]) for p in threadpoolctl.threadpool_info()] == before
    with pytest.raises(ValueError, match="must be >= 1"):
        limit_threads(0)
