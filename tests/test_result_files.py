"""Result files are one unit and never lost (issue #16 items 5 and 9): the .npz carries a content
hash that the .json repeats, a mismatch is reported, kill -9 at any point of a save leaves a
readable result and no temporary after the next save, files follow the umask, NaN controls are
never written."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from trajopt.results.result import Result

ROOT = Path(__file__).resolve().parents[1]


def make_result(version: int = 0, steps: int = 40) -> Result:
    u = np.full((steps, 2), 1e-4 * (version % 50))
    return Result(robot="tripod", task="walk", motor_names=["front", "back"], dt=0.033, z=np.zeros(3), u=u,
                  u_post=u.copy(), target=np.zeros((steps + 1, 2)), com=np.zeros((steps + 1, 3)),
                  status=f"v{version}", settings={"n_prep": 0, "n_cycle": steps})


def leftovers(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.name.startswith(".") or ".tmp" in p.name)


def test_the_json_repeats_the_npz_hash_and_a_mismatch_is_reported(tmp_path):
    path = make_result(1).save(tmp_path / "r")
    sidecar = json.loads(path.with_suffix(".json").read_text())
    with np.load(path) as data:
        assert str(data["content_sha256"]) == sidecar["content_sha256"] and len(sidecar["content_sha256"]) == 64
    old_json = path.with_suffix(".json").read_bytes()
    make_result(2).save(path)
    path.with_suffix(".json").write_bytes(old_json)          # as a save killed between the two files
    with pytest.warns(UserWarning, match=r"r\.json does not match .*r\.npz .*authoritative"):
        back = Result.load(path)
    assert back.status == "v2"


def test_a_damaged_npz_is_refused(tmp_path):
    path = make_result(1).save(tmp_path / "r")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["u"] = arrays["u"] + 1e-3                          # edited behind Result.save's back
    np.savez(path, **arrays)
    with pytest.raises(ValueError, match=r"r\.npz: its content does not match its content_sha256"):
        Result.load(path)


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_result_files_follow_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        path = make_result().save(tmp_path / "r")
    finally:
        os.umask(old)
    for p in (path, path.with_suffix(".json")):
        assert p.stat().st_mode & 0o777 == 0o666 & ~umask, p


@pytest.mark.parametrize("field", ["u", "u_post"])
def test_nan_controls_are_never_written(tmp_path, field):
    res = make_result()
    getattr(res, field)[3, 1] = np.nan
    with pytest.raises(ValueError, match=rf"r\.npz: field '{field}' contains NaN or inf \(steps \[3\]\)"):
        res.save(tmp_path / "r")
    assert list(tmp_path.iterdir()) == []


def test_save_refuses_to_replace_when_asked(tmp_path):
    path = make_result(1).save(tmp_path / "r")
    with pytest.raises(ValueError, match=r"r\.npz: exists already"):
        make_result(2).save(path, overwrite=False)
    assert Result.load(path).status == "v1"


def test_stale_temporaries_of_killed_writers_are_removed(tmp_path):
    target = tmp_path / "r.npz"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f".r.npz.{int(dead.stdout)}.0123abcd.tmp"            # a writer that no longer runs
    alive = tmp_path / f".r.npz.{os.getppid()}.0123abcd.tmp"                # one that still runs: kept
    legacy = tmp_path / ".r.npz.k3j_x9q2.tmp"                               # tempfile.mkstemp's, old
    other = tmp_path / ".notes.txt"
    for p in (stale, alive, legacy, other):
        p.write_bytes(b"x")
    os.utime(legacy, (time.time() - 7200, time.time() - 7200))
    make_result().save(target)
    assert leftovers(tmp_path) == sorted([alive.name, other.name])


WRITER = """
import sys
import numpy as np
from trajopt.results import Result
path = sys.argv[1]


def make_result(version, steps):
    u = np.full((steps, 2), 1e-4 * (version % 50))
    return Result(robot="tripod", task="walk", motor_names=["front", "back"], dt=0.033, z=np.zeros(3), u=u,
                  u_post=u.copy(), target=np.zeros((steps + 1, 2)), com=np.zeros((steps + 1, 3)),
                  status=f"v{version}", settings={"n_prep": 0, "n_cycle": steps})


results = [make_result(v, 4000 + 1000 * (v % 3)) for v in range(30)]   # 130-200 kB each
results[0].save(path)             # one whole unit exists before the test may kill this writer
print("ready", flush=True)
v = 1
while True:
    results[v % 30].save(path)
    v += 1
"""


def test_kill_9_at_random_points_of_saves_never_breaks_the_unit(tmp_path):
    """A writer saving results in a loop is killed with SIGKILL at seeded random moments; after
    each kill the .npz is one whole result, the .json matches it or the mismatch is reported,
    and the next save leaves no temporary behind. The writer says "ready" only after its first
    whole save (the kill may then land anywhere in the later ones, whatever the machine's load;
    before, a kill during the first save left an .npz without its .json)."""
    rng = np.random.default_rng(16)
    path = tmp_path / "r.npz"
    code = WRITER
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    mismatches = temporaries = 0
    for _ in range(10):
        proc = subprocess.Popen([sys.executable, "-c", code, str(path)], stdout=subprocess.PIPE, env=env, text=True)
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(rng.uniform(0.02, 0.25))
        proc.kill()
        proc.wait(timeout=30)
        proc.stdout.close()
        temporaries += len(leftovers(tmp_path))
        meta = json.loads(path.with_suffix(".json").read_text())                    # both files exist
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")
            res = Result.load(path)
        version = int(res.status[1:])
        assert np.array_equal(res.u, make_result(version, steps=len(res.u)).u)     # one whole result
        if meta["status"] != res.status:
            mismatches += 1
            assert any("does not match" in str(w.message) for w in record)          # detected and reported
            assert json.loads(path.with_suffix(".json").read_text())["status"] == res.status   # and repaired
        else:
            assert not [w for w in record if "does not match" in str(w.message)]
    res.save(path)                                                                  # the next save cleans up
    assert leftovers(tmp_path) == []
    print(f"kills left {temporaries} temporaries and {mismatches} .json files behind their .npz")


def test_a_file_lock_excludes_another_process_until_released(tmp_path):
    """trajopt.results.files.FileLock (a tuning study's and the suite ledger's): while one process
    holds it, another cannot take it; released, it can."""
    from trajopt.results.files import HAVE_FILE_LOCKS, FileLock
    if not HAVE_FILE_LOCKS:
        pytest.skip("no POSIX file locks here")
    path = tmp_path / "x.lock"
    probe = ("import fcntl, sys\nf = open(sys.argv[1], 'a+')\n"
             "try:\n    fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)\nexcept BlockingIOError:\n    sys.exit(3)\n")
    lock = FileLock(path)
    with lock:
        assert subprocess.run([sys.executable, "-c", probe, str(path)]).returncode == 3
    assert subprocess.run([sys.executable, "-c", probe, str(path)]).returncode == 0
    lock.close()
