"""Worker processes that end with their parent, however the parent ends.

A process pool's workers (``multiprocessing``'s spawn method) outlive a parent killed by a
signal it does not handle, or by SIGKILL: re-parented to pid 1, they hold the parent's stdout
(a pipeline reading it never ends) and keep computing. :func:`die_with_parent`, run first in
a worker (:func:`start_worker`, a pool's ``initializer``), ends the worker when its parent
ends: the kernel's parent-death signal on Linux (``prctl(PR_SET_PDEATHSIG, SIGKILL)``), and on
every system a daemon thread that polls ``os.getppid()`` (a process whose parent died is
re-parented, so the pid changes).

This module needs only the standard library: a worker imports it, and starts watching, before
it imports the work it is given (numba, the simulator: seconds on a loaded machine).
"""
from __future__ import annotations

import importlib
import os
import signal
import sys
import threading
import time

__all__ = ["die_with_parent", "start_worker", "worker_pool", "PARENT_POLL_S"]

#: how often [s] a worker looks whether its parent still lives
PARENT_POLL_S = 0.25


def die_with_parent(parent: int) -> None:
    """End this process when process ``parent`` (its parent) ends, even by SIGKILL."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)     # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:                  # it died before we asked
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def start_worker(parent: int, setup: str | None = None) -> None:
    """A pool worker's ``initializer``: Ctrl-C is the parent's to handle (it ends the workers),
    the worker ends with ``parent``, then ``setup`` runs (``"module:function"``, imported only
    now: e.g. one compute thread per worker)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent)
    if setup:
        module, _, name = setup.partition(":")
        getattr(importlib.import_module(module), name)()


def worker_pool(workers: int, setup: str | None = None):
    """A :class:`concurrent.futures.ProcessPoolExecutor` of ``workers`` processes started by
    ``spawn`` (a fork would copy numba's and the BLAS's threads), each ending with this process and
    running ``setup`` first (:func:`start_worker`; e.g. ``"soft_envs.envs.threads:limit_threads"``,
    one compute thread per worker)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    return ProcessPoolExecutor(int(workers), mp_context=multiprocessing.get_context("spawn"), initializer=start_worker,
                               initargs=(os.getpid(), setup))
