"""Where numba caches the simulator's kernels: a folder named after a hash of their sources.

Every kernel is ``@njit(cache=True)``. numba keys a cached kernel on its own source file only,
so a kernel compiled with a function it calls from another module (``coulomb.py`` calling
``penalty.py``'s ``Q``) is not recompiled when that function changes: after an edit or a
``git pull`` the old machine code would run, silently. :func:`use_source_keyed_cache` points
numba's cache at ``soft_envs/__pycache__/numba-<hash>/`` (or, when the package folder is not
writable, ``$XDG_CACHE_HOME/soft_envs/numba-<hash>/``), the hash over every source file of
:mod:`soft_envs.sim`: any change there starts an empty cache, and an unchanged checkout keeps its
compiled kernels. A ``NUMBA_CACHE_DIR`` set by the user is left as it is (its kernels are then
the user's to clear). Each use touches the folder; folders of other sources beside it that no
process has used for :data:`STALE_DAYS` days are removed (:func:`prune_stale_caches`: a folder in
use by a running process of older sources is younger than that).
"""
from __future__ import annotations

import hashlib
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["kernel_sources_hash", "kernel_cache_dir", "use_source_keyed_cache", "prune_stale_caches", "STALE_DAYS"]

PACKAGE = Path(__file__).resolve().parent
#: the environment variable that says ``NUMBA_CACHE_DIR`` was set here (a child process of
#: another checkout, e.g. a benchmark's, computes its own folder instead of inheriting ours)
MARKER = "SOFT_ENVS_KERNEL_CACHE"
#: a kernel cache folder of other sources unused for this many days is removed
STALE_DAYS = 14.0


def kernel_sources_hash(root: Path = PACKAGE / "sim") -> str:
    """The first 16 hex digits of the SHA-256 over the names and bytes of every ``.py`` file
    under ``root``, in sorted order."""
    digest = hashlib.sha256()
    for path in sorted(Path(root).rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def kernel_cache_dir(package: Path = PACKAGE) -> Path | None:
    """The cache folder for the kernels of ``package``'s current sources (module docstring),
    created; None when neither candidate is writable."""
    name = f"numba-{kernel_sources_hash(Path(package) / 'sim')}"
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "soft_envs"
    for folder in (Path(package) / "__pycache__" / name, user / name):
        if _writable(folder):
            return folder
    return None


def use_source_keyed_cache() -> Path | None:
    """Point numba's cache at :func:`kernel_cache_dir` unless ``NUMBA_CACHE_DIR`` is set (then
    None): through ``NUMBA_CACHE_DIR`` when numba is not imported yet (child processes inherit
    it), through ``numba.config.CACHE_DIR`` when it is (read when a kernel is decorated). A
    ``NUMBA_CACHE_DIR`` this function set in a parent process (:data:`MARKER`) is replaced."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given and given != os.environ.get(MARKER):         # the user's own, not one inherited from us
        return None
    folder = kernel_cache_dir()
    if folder is None:
        return None
    os.environ["NUMBA_CACHE_DIR"] = os.environ[MARKER] = str(folder)
    if "numba" in sys.modules:
        from numba.core import config
        config.CACHE_DIR = str(folder)
    prune_stale_caches(folder)
    return folder


def prune_stale_caches(folder: Path, max_age_days: float = STALE_DAYS) -> list[Path]:
    """Touch ``folder`` (in use now) and remove the other ``numba-*`` folders beside it whose
    last modification is more than ``max_age_days`` old; returns those removed. A folder that
    cannot be removed (another process removing it too, permissions) is left, silently."""
    folder = Path(folder)
    try:
        os.utime(folder)
    except OSError:
        return []
    removed = []
    cutoff = time.time() - 86400.0 * max_age_days
    for other in folder.parent.glob("numba-*"):
        try:
            if other == folder or not other.is_dir() or other.stat().st_mtime > cutoff:
                continue
            shutil.rmtree(other)
            removed.append(other)
        except OSError:
            continue
    return removed
