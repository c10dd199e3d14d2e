"""Reserving an output name for the length of a run, so that no two runs write the same result.

``with reserve(lock_file):`` creates ``lock_file`` exclusively (``os.open`` with
``O_CREAT | O_EXCL``, atomic on a local filesystem) holding JSON ``{pid, host, started,
command, token}``, and removes it when the block ends in any way (return, exception, Ctrl-C).
A second writer of the same name is refused at once (:class:`ReservationRefused`, a
``ValueError``: the command line exits 2 with one line naming the lock file and its owner).
A reservation left by a process that no longer runs (same host, dead pid: ``kill -9``, a
power loss) is taken over with a :class:`StaleReservationWarning`, and so is one whose pid
now belongs to a process that started after the lock was written (the pid was reused; the
start time is read from /proc on Linux). On another host, or on
Windows, whether the owner lives cannot be asked: the lock is refused and the message says
to remove it by hand once no run uses it.

The lock protects a run while it lives; a finished result stays protected by the commands'
no-overwrite rule (``--overwrite``). Where the locks are: ``OUT/NAME.lock`` beside
``trajopt optimize``'s ``OUT/NAME.npz`` and beside ``trajopt rl train``'s run directory
``OUT/NAME/``; ``DIR/sweep.lock`` and ``DIR/robustness.lock`` inside a sweep's and a
robustness study's folder.

This module needs only the standard library.
"""
from __future__ import annotations

import json
import os
import platform
import secrets
import sys
import time
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

from .files import _process_alive

__all__ = ["reserve", "lock_path", "read_owner", "process_start_time", "ReservationRefused", "StaleReservationWarning"]

#: the locks this process holds (a lock naming our own pid that is not here is stale: pid reuse)
_HELD: set[str] = set()


class ReservationRefused(ValueError):
    """Another live run holds the name (or its lock file cannot be read)."""


class StaleReservationWarning(UserWarning):
    """A reservation of a process that no longer runs was taken over."""


def lock_path(result: str | os.PathLike) -> Path:
    """The lock file reserving ``result``: ``NAME.lock`` beside ``NAME.npz`` (or beside a run
    directory ``NAME/``)."""
    result = Path(result)
    name = result.name[:-len(".npz")] if result.name.endswith(".npz") else result.name
    return result.with_name(name + ".lock")


def read_owner(lock_file: str | os.PathLike) -> dict[str, Any] | None:
    """The owner recorded in ``lock_file``, or None when it is gone; ``{}`` when unreadable."""
    try:
        owner = json.loads(Path(lock_file).read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        return {}
    return owner if isinstance(owner, dict) else {}


#: a process cannot have written a lock before it started; this much slack [s] covers the
#: coarse clocks the start time is read from (the boot time has whole seconds)
START_TIME_SLACK_S = 2.0


def process_start_time(pid: int) -> float | None:
    """When process ``pid`` started [s since the epoch], from /proc (Linux); None where that
    cannot be read (another system, the process gone)."""
    try:
        stat = Path(f"/proc/{int(pid)}/stat").read_text()
        ticks = int(stat[stat.rindex(")") + 2:].split()[19])         # field 22: starttime
        boot = next(float(line.split()[1]) for line in Path("/proc/stat").read_text().splitlines()
                    if line.startswith("btime "))
        return boot + ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def _is_stale(owner: dict[str, Any], key: str) -> bool:
    pid, host = owner.get("pid"), owner.get("host")
    if not isinstance(pid, int) or isinstance(pid, bool) or host != platform.node():
        return False
    if pid == os.getpid():
        return key not in _HELD                   # our pid, not our lock: an older process's
    if not _process_alive(pid):
        return True
    started, began = owner.get("started"), process_start_time(pid)
    if isinstance(started, (int, float)) and not isinstance(started, bool) and began is not None:
        return began > float(started) + START_TIME_SLACK_S      # the pid was reused by a later process
    return False


def _describe(owner: dict[str, Any]) -> str:
    if not owner:
        return "an owner that cannot be read"
    started = owner.get("started")
    when = time.strftime(" since %Y-%m-%d %H:%M:%S", time.localtime(started)) if isinstance(started, (int, float)) else ""
    return f"pid {owner.get('pid')} on host {owner.get('host')}{when} ({owner.get('command', '?')})"


def _create(lock_file: Path, record: dict[str, Any]) -> bool:
    try:
        fd = os.open(lock_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    except FileExistsError:
        return False
    try:
        os.write(fd, json.dumps(record).encode())
        os.fsync(fd)
    finally:
        os.close(fd)
    return True


def _take_over(lock_file: Path, stale: dict[str, Any]) -> None:
    """Move the stale lock aside and delete it, unless another process replaced it meanwhile
    (then put theirs back, so that the next attempt sees it)."""
    aside = lock_file.with_name(f".{lock_file.name}.{os.getpid()}.{secrets.token_hex(4)}.stale")
    try:
        os.rename(lock_file, aside)
    except FileNotFoundError:
        return
    if read_owner(aside) != stale:
        try:
            os.link(aside, lock_file)
        except OSError:
            pass
    else:
        warnings.warn(f"{lock_file}: taking over the reservation of {_describe(stale)}, which no "
                      "longer runs", StaleReservationWarning, stacklevel=4)
    aside.unlink(missing_ok=True)


@contextmanager
def reserve(lock_file: str | os.PathLike, what: str = "this output",
            command: str | None = None) -> Iterator[Path]:
    """Hold ``lock_file`` for the block (see the module docstring); ``what`` names the
    reserved output in the refusal. Creates the lock's folder if needed (and removes it again
    if the run left it empty)."""
    lock_file = Path(lock_file).absolute()
    created = [d for d in (lock_file.parent, *lock_file.parent.parents) if not d.exists()]
    lock_file.parent.mkdir(parents=True, exist_ok=True)
    key = str(lock_file)
    record = {"pid": os.getpid(), "host": platform.node(), "started": time.time(),
              "command": (command or " ".join(["trajopt", *sys.argv[1:]]))[:300], "token": secrets.token_hex(8)}
    for _ in range(5):
        if _create(lock_file, record):
            break
        owner = read_owner(lock_file)
        if owner is None and lock_file.is_symlink() and not lock_file.exists():
            raise ReservationRefused(f"{lock_file}: is a symbolic link to {os.readlink(lock_file)}, which does not "
                                     "exist: not a lock a run wrote; remove it if no run uses this output")
        if owner is None:                     # released meanwhile
            continue
        if not _is_stale(owner, key):
            advice = ("remove it by hand if no run uses it any more" if owner.get("host") != platform.node()
                      or os.name == "nt" or not owner else "wait for it to end, or choose another name")
            raise ReservationRefused(f"{lock_file}: {what} is reserved by {_describe(owner)}; {advice}")
        _take_over(lock_file, owner)
    else:
        raise ReservationRefused(f"{lock_file}: could not reserve {what} (the lock file keeps changing)")
    _HELD.add(key)
    try:
        yield lock_file
    finally:
        _HELD.discard(key)
        if (read_owner(lock_file) or {}).get("token") == record["token"]:
            lock_file.unlink(missing_ok=True)
        for d in created:                     # folders made for the lock and left empty
            try:
                d.rmdir()
            except OSError:
                break
