"""numba's cache of the kernels is keyed on the sources of soft_envs.sim (soft_envs/kernel_cache.py):
a kernel compiled with a function of another module must not survive a change of that function."""
from __future__ import annotations

import os
import time
import subprocess
import sys
from pathlib import Path

from soft_envs import kernel_cache
from soft_envs.kernel_cache import MARKER, kernel_cache_dir, kernel_sources_hash, use_source_keyed_cache

ROOT = Path(__file__).resolve().parents[1]


def test_the_hash_follows_every_source_file(tmp_path):
    sim = tmp_path / "sim"
    (sim / "contact").mkdir(parents=True)
    (sim / "coulomb.py").write_text("from .penalty import Q\n")
    (sim / "contact" / "penalty.py").write_text("def Q(s): return s\n")
    before = kernel_sources_hash(sim)
    assert kernel_sources_hash(sim) == before and len(before) == 16
    (sim / "contact" / "penalty.py").write_text("def Q(s): return 2 * s\n")         # the callee only
    assert kernel_sources_hash(sim) != before
    folder = kernel_cache_dir(tmp_path)
    assert folder == tmp_path / "__pycache__" / f"numba-{kernel_sources_hash(sim)}" and folder.is_dir()


def test_an_unwritable_package_caches_in_the_users_folder(tmp_path, monkeypatch):
    (tmp_path / "pkg" / "sim").mkdir(parents=True)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setattr(kernel_cache, "_writable", lambda folder: "xdg" in str(folder))
    folder = kernel_cache_dir(tmp_path / "pkg")
    assert folder.parent == tmp_path / "xdg" / "soft_envs" and folder.name.startswith("numba-")


def test_a_users_numba_cache_dir_stands_and_an_inherited_one_is_replaced(monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere/of/mine")
    monkeypatch.delenv(MARKER, raising=False)
    assert use_source_keyed_cache() is None and os.environ["NUMBA_CACHE_DIR"] == "/somewhere/of/mine"
    monkeypatch.setenv(MARKER, "/somewhere/of/mine")              # set by a parent soft_envs
    folder = use_source_keyed_cache()
    assert folder == kernel_cache_dir() and os.environ["NUMBA_CACHE_DIR"] == str(folder)


def test_importing_soft_envs_points_numba_at_the_folder_of_these_sources():
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", MARKER)}
    env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{env.get('PYTHONPATH', '')}"
    out = subprocess.run([sys.executable, "-c", "import soft_envs.sim.materials, numba; print(numba.config.CACHE_DIR)"],
                         env=env, capture_output=True, text=True, check=True).stdout.strip()
    assert Path(out).name == f"numba-{kernel_sources_hash(ROOT / 'soft_envs' / 'sim')}"


def test_folders_of_other_sources_unused_for_two_weeks_are_removed(tmp_path):
    from soft_envs.kernel_cache import STALE_DAYS, prune_stale_caches
    now = time.time()
    made = {}
    for name, age_days in (("numba-current", 60), ("numba-old", STALE_DAYS + 1), ("numba-recent", STALE_DAYS - 1),
                           ("other-old", 60)):
        folder = tmp_path / name
        (folder / "sim").mkdir(parents=True)
        (folder / "sim" / "kernel.nbi").write_bytes(b"x")
        os.utime(folder, (now - 86400 * age_days,) * 2)
        made[name] = folder
    removed = prune_stale_caches(made["numba-current"])
    assert removed == [made["numba-old"]]
    assert not made["numba-old"].exists()
    assert all(made[n].exists() for n in ("numba-current", "numba-recent", "other-old"))
    assert made["numba-current"].stat().st_mtime > now - 60          # touched: in use now
