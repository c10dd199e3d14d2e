"""What ``trajopt evaluate`` scores is what ``trajopt play`` streams (issue #26 item 5, issue #30
"integrity checks tried with one edited field"): a result file edited with its hash recomputed
(u x3, arrays cut, motor order swapped, u_post changed) is refused naming the array; removing
``content_sha256`` or ``robot_fingerprint`` is refused unless the file predates them; metadata
edited behind the hash is refused; a stale, missing or edited .json is rewritten from the .npz."""
from __future__ import annotations

import io
import json
import shutil

import numpy as np
import pytest

from soft_envs.envs import load_robot, make_gradient_env, robot_fingerprint
from soft_envs.sim.robot_file import asset_path
from trajopt import GaitParameterization, GaitSpec
from trajopt.cli import main
from trajopt.evaluation import zero_slack_controls
from trajopt.results.result import Result, ResultFileWarning, _sidecar_text, content_hash

GAIT = GaitSpec(n_prep=4, n_cycle=12, n_cycles=1, n_keyframes=2, symmetry=False)


@pytest.fixture
def gait(tmp_path):
    """A consistent result (keyframes, u, zero-slack u_post of its rollout, fingerprint) for a copy
    of the Tripod, saved as tmp_path/gait.npz."""
    for p in asset_path("tripod").parent.glob("*"):
        if p.name in ("robot.toml", "tripod.vtu"):
            shutil.copy(p, tmp_path / p.name)
    toml = tmp_path / "robot.toml"
    robot = load_robot(toml)
    param = GaitParameterization.for_robot(robot, GAIT)
    z = param.initial_z(0.5, np.random.default_rng(3), noise=0.4)
    u = param.controls(z)
    env = make_gradient_env(toml)
    traj = env.rollout(u)
    u_post = zero_slack_controls(u, traj.cable_deformation, robot.tendon_motor, robot.u_bounds)
    K = len(u)
    res = Result(robot=str(toml), task="walk", motor_names=robot.motor_names, dt=0.033, z=z, u=u, u_post=u_post,
                 target=np.zeros((K + 1, 2)), com=traj.com, status="converged",
                 settings={**GAIT.to_settings(), "keyframes": param.keyframes(z).tolist(), "heading_deg": 0.0,
                           "eval_cycles": 1, "contact": robot.contact.model,    # as results record it
                           "substeps": env.substeps},
                 evaluation={"upright": True, "speed_bl_per_min": 1.0}, robot_fingerprint=robot_fingerprint(toml))
    return res.save(tmp_path / "gait.npz")


def read(path):
    with np.load(path) as data:
        arrays = {k: np.array(data[k]) for k in data.files}
    return json.loads(str(arrays.pop("meta"))), arrays


def forge(path, meta, arrays, *, rehash=True):
    """Write ``path`` (and its .json) as an editing script would: the hash recomputed to match."""
    text = json.dumps(meta)
    arrays = dict(arrays)
    if rehash:
        arrays["content_sha256"] = np.array(content_hash(text, arrays))
    buf = io.BytesIO()
    np.savez(buf, meta=np.array(text), **arrays)
    path.write_bytes(buf.getvalue())
    if "content_sha256" in arrays:
        path.with_suffix(".json").write_text(_sidecar_text(text, str(arrays["content_sha256"])))
    else:
        path.with_suffix(".json").write_text(json.dumps(meta))


def cli(argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def test_the_consistent_gait_loads_and_evaluates(gait, capsys):
    res = Result.load(gait)
    assert res.robot_fingerprint and np.any(res.u_post > res.u + 1e-5)     # it has slack to reel in
    code, err = cli(["evaluate", gait], capsys)
    assert code == 0, err


def test_u_times_three_is_refused_naming_u(gait, capsys):
    meta, arrays = read(gait)
    arrays["u"] = 3 * arrays["u"]
    arrays["u_post"] = 3 * arrays["u_post"]
    forge(gait, meta, arrays)
    with pytest.raises(ValueError, match=r"gait\.npz: field 'u' is not what its keyframes make \(step \d+, motor"):
        Result.load(gait)
    from trajopt.hardware import EXAMPLE_TRIPOD
    for argv in (["evaluate", gait], ["play", gait, "--dry-run", "--hardware", EXAMPLE_TRIPOD]):
        code, err = cli(argv, capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert "gait.npz: field 'u' is not what its keyframes make" in err


def test_arrays_cut_are_refused(gait):
    meta, arrays = read(gait)
    for key, n in (("u", 10), ("u_post", 10), ("target", 11), ("com", 11)):
        arrays[key] = arrays[key][:n]
    forge(gait, meta, arrays)
    with pytest.raises(ValueError, match=r"gait\.npz: field 'u' has 10 steps, its gait has 16"):
        Result.load(gait)


def test_swapped_motor_columns_are_refused_naming_u(gait):
    meta, arrays = read(gait)
    for key in ("u", "u_post"):
        arrays[key] = arrays[key][:, ::-1]
    forge(gait, meta, arrays)
    with pytest.raises(ValueError, match=r"gait\.npz: field 'u' is not what its keyframes make"):
        Result.load(gait)


def test_swapped_motor_order_everywhere_is_refused_naming_motor_names(gait):
    """Columns, keyframes, z and names all swapped: consistent with itself, not with its robot."""
    meta, arrays = read(gait)
    for key in ("u", "u_post"):
        arrays[key] = arrays[key][:, ::-1]
    meta["motor_names"] = meta["motor_names"][::-1]
    meta["settings"]["keyframes"] = meta["settings"]["keyframes"][::-1]
    arrays["z"] = np.asarray(meta["settings"]["keyframes"]).ravel()
    forge(gait, meta, arrays)
    with pytest.raises(ValueError, match=r"gait\.npz: field 'motor_names' \['back', 'front'\] is not the motors"):
        Result.load(gait)


def test_an_edited_u_post_is_refused_by_evaluate(gait, capsys):
    """Within the motor range and above u, so only a new rollout can tell: evaluate refuses it."""
    meta, arrays = read(gait)
    arrays["u_post"] = np.minimum(arrays["u_post"] + 5e-4, 0.02)
    forge(gait, meta, arrays)
    Result.load(gait)
    code, err = cli(["evaluate", gait], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "gait.npz: field 'u_post' is not the zero-slack controls of its u" in err


def test_u_post_below_u_is_refused(gait):
    meta, arrays = read(gait)
    arrays["u_post"] = arrays["u"] - 1e-4
    forge(gait, meta, arrays)
    with pytest.raises(ValueError, match=r"gait\.npz: field 'u_post' is below u"):
        Result.load(gait)


@pytest.mark.parametrize("field", ["content_sha256", "robot_fingerprint"])
def test_removing_the_hash_or_the_fingerprint_is_refused(gait, field):
    meta, arrays = read(gait)
    if field == "content_sha256":
        del arrays["content_sha256"]
        forge(gait, meta, arrays, rehash=False)
    else:
        del meta["robot_fingerprint"]
        forge(gait, meta, arrays)
    with pytest.raises(ValueError, match=rf"gait\.npz: field '{field}' is missing"):
        Result.load(gait)


@pytest.mark.parametrize("drop", ["content_sha256", "robot_fingerprint"])
def test_a_version_1_file_predates_them_only_without_every_newer_field(gait, drop):
    """format_version 1 was written both before and after hashing: it passes as old only when
    it has neither the hash nor the fingerprint (nor a hash in its .json)."""
    meta, arrays = read(gait)
    meta["format_version"] = 1
    del arrays["content_sha256"]
    old = {k: v for k, v in meta.items() if k != "robot_fingerprint"}
    forge(gait, old, arrays, rehash=False)
    assert Result.load(gait).robot_fingerprint == {}                 # a genuine old file
    kept = meta if drop == "content_sha256" else old                 # one newer field left
    forge(gait, kept, arrays, rehash=False)
    if drop == "robot_fingerprint":                                   # the .json still carries a hash
        gait.with_suffix(".json").write_text(json.dumps({"content_sha256": "0" * 64, **old}))
    with pytest.raises(ValueError, match=r"gait\.npz: field 'content_sha256' is missing, but the file has"):
        Result.load(gait)


@pytest.mark.parametrize("edit", ["evaluation.upright", "settings.heading_deg", "robot_fingerprint.mesh_sha256",
                                  "dt"])
def test_metadata_edited_behind_the_hash_is_refused(gait, edit):
    meta, arrays = read(gait)
    where = meta
    *parents, key = edit.split(".")
    for p in parents:
        where = where[p]
    where[key] = {"upright": False, "heading_deg": 90.0, "mesh_sha256": "0" * 64, "dt": 0.02}[key]
    forge(gait, meta, arrays, rehash=False)
    with pytest.raises(ValueError, match=r"gait\.npz: its content does not match its content_sha256"):
        Result.load(gait)


def sidecar_of(path):
    return json.loads(path.with_suffix(".json").read_text())


@pytest.mark.parametrize("case", ["stale", "missing", "edited"])
def test_a_stale_missing_or_edited_json_is_rewritten_from_the_npz(gait, case):
    side = gait.with_suffix(".json")
    res = Result.load(gait)
    if case == "stale":                          # a save killed between the .npz's and the .json's renames
        old = side.read_bytes()
        res.status = "second save"
        res.save(gait)
        side.write_bytes(old)
    elif case == "missing":
        side.unlink()
    else:                                        # a field of the .json edited, its hash left as is
        doc = sidecar_of(gait)
        doc["evaluation"]["upright"] = False
        side.write_text(json.dumps(doc))
    with pytest.warns(ResultFileWarning, match=r"gait\.json (does not match|is missing) .*gait\.npz .*authoritative "
                                               r"and was read; it was rewritten from the \.npz"):
        back = Result.load(gait)
    doc = sidecar_of(gait)
    assert doc["status"] == back.status and doc["evaluation"]["upright"] is True
    assert doc["content_sha256"] == str(np.load(gait)["content_sha256"])
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Result.load(gait)                        # repaired: no warning the second time
