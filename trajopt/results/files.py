"""Writing output files safely: atomically, with the user's umask, never leaving temporaries.

Every file a ``trajopt`` command writes goes through :func:`atomic_output` (or
:func:`atomic_write_bytes`): the data goes to a temporary file beside the target, named
``.NAME.PID.RANDOM.tmp[.EXT]``, created with mode ``0o666`` minus the umask (as ``open`` would;
``tempfile.mkstemp`` gives 0600), flushed to disk, then renamed over the target (``os.replace``,
atomic on POSIX and Windows) and the directory entry is flushed too. An exception removes the
temporary; a process killed outright (``kill -9``, power loss) cannot, so every later write of the
same target first removes the temporaries it recognises as stale (:func:`clean_stale_temporaries`):
those of a process that no longer runs (on Windows, where that cannot be asked safely, and for a
reused process id: those older than a day), and those of the older ``mkstemp`` naming
(``.NAME.XXXXXXXX.tmp``) after :data:`LEGACY_STALE_SECONDS`.

This module needs only the standard library (``trajopt.hardware`` reads results through it).
"""
from __future__ import annotations

import os
import re
import secrets
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

try:
    import fcntl                                    # POSIX: locks shared by processes (FileLock)
except ImportError:                                 # pragma: no cover - Windows
    fcntl = None

#: whether :class:`FileLock` excludes other processes here (POSIX ``flock``)
HAVE_FILE_LOCKS = fcntl is not None

__all__ = ["RESULTS_DIR", "atomic_output", "atomic_write_bytes", "clean_stale_temporaries", "temporary_name",
           "check_output_dir", "refuse_existing", "FileLock", "HAVE_FILE_LOCKS", "LEGACY_STALE_SECONDS"]

#: Where the ``trajopt`` commands write by default: results (.npz/.json), GIFs, ``plots/``,
#: ``paraview/``, ``runs/`` (RL), relative to the working directory.
RESULTS_DIR = Path("results")
#: Age [s] after which a temporary of the old ``mkstemp`` naming (no process id) counts as stale.
LEGACY_STALE_SECONDS = 3600.0
_TEMP = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.[0-9a-f]{8}\.tmp(?:\.[A-Za-z0-9]+)?$")
_LEGACY = re.compile(r"^\.(?P<name>.+)\.[A-Za-z0-9_]{8}\.(?:tmp|vtu)$")


def temporary_name(path: Path) -> Path:
    """A fresh temporary path beside ``path`` that :func:`clean_stale_temporaries` recognises;
    it keeps ``path``'s extension (writers such as Pillow choose the format by it)."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp{path.suffix}")


def _process_alive(pid: int) -> bool:
    if pid == os.getpid() or os.name == "nt":     # on Windows os.kill(pid, 0) would end the process
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):   # another user's process, or no way to tell: keep it
        return True
    return True


def clean_stale_temporaries(path: Path) -> list[Path]:
    """Remove the temporaries of ``path`` left by writers that were killed; returns them."""
    path = Path(path)
    removed = []
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return removed
    now = time.time()
    for entry in entries:
        m = _TEMP.match(entry.name)
        if m and m["name"] == path.name:
            stale = not _process_alive(int(m["pid"])) or _age(entry, now) > LEGACY_STALE_SECONDS * 24
        else:
            m = _LEGACY.match(entry.name)
            stale = bool(m and m["name"] in (path.name, path.stem)) and _age(entry, now) > LEGACY_STALE_SECONDS
        if stale:
            try:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
            except OSError:
                pass
    return removed


def _age(entry: os.DirEntry, now: float) -> float:
    try:
        return now - entry.stat(follow_symlinks=False).st_mtime
    except OSError:
        return 0.0


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:                         # e.g. Windows: directories cannot be opened
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_output(path: str | os.PathLike, *, sync: bool = True) -> Iterator[Path]:
    """``with atomic_output(p) as tmp: write(tmp)``: the file appears at ``p`` complete or not
    at all. ``tmp`` exists (empty, mode 0o666 minus the umask) when the block starts; on leaving
    it normally it is flushed to disk (``sync=False``: left to the system; still atomic for
    other processes, not across a power loss) and renamed to ``p``, on an exception (Ctrl-C
    included) removed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_temporaries(path)
    tmp = temporary_name(path)
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        yield tmp
        if sync:
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    if sync:
        _fsync_dir(path.parent)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_output`)."""
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)


def atomic_write_png(fig, path: str | os.PathLike, *, dpi: int) -> Path:
    """A matplotlib figure written as PNG to ``path`` atomically (see :func:`atomic_output`),
    then closed (also when writing fails)."""
    import io

    import matplotlib.pyplot as plt
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        atomic_write_bytes(path, buf.getvalue())
    finally:
        plt.close(fig)
    return Path(path)


def check_output_dir(path: str | os.PathLike, what: str) -> Path:
    """``path`` as a directory outputs can be written to (existing and writable, or creatable
    under a writable parent); otherwise a ValueError naming ``what`` (e.g. ``--out``) and the
    path. Creates nothing."""
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise ValueError(f"{what} {path}: exists and is not a directory")
        if not os.access(path, os.W_OK | os.X_OK):
            raise ValueError(f"{what} {path}: directory is not writable")
        return path
    parent = path.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{what} {path}: cannot be created ({parent} is not a directory)")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{what} {path}: cannot be created ({parent} is not writable)")
    return path


def refuse_existing(paths: list[Path], overwrite: bool, what: str = "output") -> None:
    """A ValueError naming the first of ``paths`` that exists, unless ``overwrite``."""
    if overwrite:
        return
    existing = [p for p in paths if Path(p).exists()]
    if existing:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise ValueError(f"{existing[0]}: {what} exists already{more}; pass --overwrite to replace it")


def decode_utf8(data: bytes, src: str | os.PathLike, *, hint: str = "save it as UTF-8") -> str:
    """``data`` (the bytes of file ``src``) as text, a leading UTF-8 byte-order mark dropped; text
    that is not UTF-8 is a ValueError naming the file, the offending byte, its offset and line:
    ``"t.csv: not UTF-8 text: byte 0xe9 at offset 33 (line 3); save it as UTF-8"``."""
    bom = 3 if data.startswith(b"\xef\xbb\xbf") else 0
    try:
        return data[bom:].decode("utf-8")
    except UnicodeDecodeError as exc:
        at = bom + exc.start
        line = data.count(b"\n", 0, at) + 1
        raise ValueError(f"{src}: not UTF-8 text: byte {data[at]:#04x} at offset {at} (line {line}); {hint}") from None


class FileLock:
    """An exclusive lock on the file ``path`` (made if missing) shared by processes, held from
    :meth:`acquire` (or ``with``) to :meth:`release`: POSIX ``flock``, which the system releases
    when the process ends however it ends. Where there is none (:data:`HAVE_FILE_LOCKS` false) it
    excludes nothing, and a caller with several processes must refuse to start."""

    def __init__(self, path: str | os.PathLike) -> None:
        self._file = open(path, "a+")           # noqa: SIM115 - held for the lock's life
        self._held = False

    def acquire(self) -> None:
        if fcntl is not None:
            fcntl.flock(self._file, fcntl.LOCK_EX)
        self._held = True

    def release(self) -> None:
        if self._held:
            if fcntl is not None:
                fcntl.flock(self._file, fcntl.LOCK_UN)
            self._held = False

    def close(self) -> None:
        self.release()
        self._file.close()

    def __enter__(self) -> "FileLock":
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()
