"""One compute thread per worker process.

A simulation step is a chain of small sparse solves and numba kernels: it runs on one core.
The native libraries behind it start thread pools sized to the machine anyway (numpy's and
scipy's OpenBLAS, the OpenBLAS inside cvxopt's CHOLMOD, numba, PyTorch), and OpenBLAS threads
spin while they wait for work. In one process that is harmless; with one process per core
(``gym.make_vec(..., vectorization_mode="async")``, SB3's ``SubprocVecEnv``, Ray tasks) the
pools of all workers compete for the same cores. :func:`limit_threads` caps every pool of the
calling process (through :mod:`threadpoolctl`, plus numba and PyTorch, and the environment
variables for the processes it starts); :func:`limit_threads_in_worker` does so only in a
child process, which is where vector-environment workers build their environments.
"""
from __future__ import annotations

import multiprocessing
import os
import sys

__all__ = ["limit_threads", "limit_threads_in_worker", "in_worker_process", "THREAD_ENV_VARS"]

#: environment variables that size the thread pools of processes started afterwards
THREAD_ENV_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                   "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")

_applied: int | None = None


def limit_threads(n: int = 1) -> int:
    """Cap the BLAS/OpenMP pools (threadpoolctl), numba and PyTorch of this process at ``n``
    threads, and set :data:`THREAD_ENV_VARS` for its children. Returns ``n``. Libraries loaded
    later are capped by the environment variables (OpenBLAS and OpenMP read them on load).
    Without threadpoolctl only the environment variables, numba and PyTorch are set."""
    global _applied
    n = int(n)
    if n < 1:
        raise ValueError(f"the number of threads must be >= 1, got {n}")
    for var in THREAD_ENV_VARS:
        os.environ[var] = str(n)
    try:
        from threadpoolctl import threadpool_limits
        threadpool_limits(limits=n)          # not used as a context manager: stays in force
    except ImportError:                      # pragma: no cover - threadpoolctl comes with the extras
        pass
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    if parallel is not None and getattr(parallel, "_is_initialized", False):
        import numba                          # its pool is running: shrink it
        numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))
    elif "numba" not in sys.modules:          # read when numba is imported
        os.environ["NUMBA_NUM_THREADS"] = str(n)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(n)
    _applied = n
    return n


def in_worker_process() -> bool:
    """True in a child process started by :mod:`multiprocessing` (the workers of
    ``AsyncVectorEnv`` and ``SubprocVecEnv``)."""
    return multiprocessing.parent_process() is not None


def limit_threads_in_worker(n: int = 1) -> bool:
    """:func:`limit_threads` (once) when called in a multiprocessing child process; nothing in
    the main process, where the user's own thread settings stay. Returns whether it applied.
    Set ``SOFT_ENVS_WORKER_THREADS=0`` to leave the workers' thread pools alone, or to a number
    of threads per worker."""
    env = os.environ.get("SOFT_ENVS_WORKER_THREADS", "")
    if env:
        try:
            n = int(env)
        except ValueError:
            raise ValueError(f"SOFT_ENVS_WORKER_THREADS must be an integer, got {env!r}") from None
        if n <= 0:
            return False
    if not in_worker_process():
        return False
    if _applied != n:
        limit_threads(n)
    return True
