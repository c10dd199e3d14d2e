"""Mutation check: does the default test suite notice a wrong result?

    python benchmarks/mutation_check.py                 # every fault, its relevant test files
    python benchmarks/mutation_check.py --only bl_per_min_30 friction_halved
    python benchmarks/mutation_check.py --all-tests     # the whole default suite per fault (slow)
    python benchmarks/mutation_check.py --list

Each fault is a one-place change of behaviour written as ``(file, exact old text, new text)``.
The checkout (tracked and untracked, non-ignored files, with numba's caches) is copied to a
temporary directory once; the working tree is never touched. The relevant test files are run
there unmutated first (they must pass), then once per fault with that fault applied, with
pytest's default options (so ``-m 'not slow'``: a fault must be caught by the default suite).
A table fault / caught by (the first failing test) / time is printed; the exit code is 0 when
every fault was caught, 1 when one was not, 2 when a fault's old text is no longer found
exactly once (a refactor moved the code: re-target that fault, do not delete it).
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Fault:
    name: str
    file: str
    old: str
    new: str
    tests: tuple[str, ...]
    why: str


OPT = ("tests/test_optimizer_outcomes.py", "tests/test_trajopt.py")
METRICS = ("tests/test_metrics.py", "tests/test_trajopt.py")
ENVS = ("tests/test_env_rewards.py", "tests/test_envs.py")
PHYSICS = ("tests/test_physics_magnitudes.py", "tests/test_reference_rollouts.py", "tests/test_dynamics.py",
           "tests/test_static.py")
HARDWARE = ("tests/test_cli_paths.py", "tests/test_hardware_config.py", "tests/test_hardware_playback.py")
TURN = ("tests/test_turn.py",)
ROBUSTNESS = tuple(f"tests/test_robustness.py::{t}" for t in (
    "test_perturbations_are_seeded_per_sample_and_within_their_ranges",
    "test_applied_controls_model_lag_speed_limit_and_jitter", "test_perturbed_slope_composes_tilts",
    "test_samples_are_independent_picklable_calls"))
# issue #30's tests, by class: the files that test the module first, the class's own file last (with -x the
# first failing test then says whether the older tests see the fault too)
PINNED = ("tests/test_dynamics.py", "tests/test_trajopt.py", *ROBUSTNESS,
          "tests/test_pinned_magnitudes.py")
CALIB = ("tests/test_calibrate.py", "tests/test_pinned_magnitudes.py")
TABLES = (*ROBUSTNESS, "tests/test_env_rewards.py", "tests/test_hardware_config.py",
          "tests/test_pinned_tables.py")
REACH = (*ROBUSTNESS, "tests/test_env_rewards.py", "tests/test_envs_coulomb.py",
         "tests/test_perturbations_reach_physics.py")
RULES = ("tests/test_env_rewards.py", "tests/test_envs.py", "tests/test_metrics.py::test_a_sinking_com_is_not_upright",
         "tests/test_turn.py", "tests/test_envs_coulomb.py", "tests/test_hardware_config.py", "tests/test_each_rule.py")
INTEGRITY = ("tests/test_result_files.py::test_the_json_repeats_the_npz_hash_and_a_mismatch_is_reported",
             "tests/test_result_files.py::test_a_damaged_npz_is_refused",
             "tests/test_robot_match.py::test_the_fingerprint_ignores_layout_and_file_format_but_not_content",
             "tests/test_robot_match.py::test_moved_mesh_nodes_with_the_same_connectivity_change_the_fingerprint",
             "tests/test_integrity_fields.py")
STOP = ("tests/test_hardware_playback.py", "tests/test_stop_confirmation.py")
COULOMB = ("tests/test_physics_magnitudes.py", "tests/test_coulomb_anchors.py", "tests/test_coulomb.py",
           "tests/test_energy_derivatives.py", "tests/test_sensitivity.py")

FAULTS = [
    # ------------------------------------------------------------------ trajopt: optimiser
    Fault("gn_uphill", "trajopt/optim/gauss_newton.py",
          "dz[free] = np.linalg.solve(A, -g[free])", "dz[free] = np.linalg.solve(A, g[free])", OPT,
          "Gauss-Newton steps uphill (every step rejected)"),
    Fault("active_set_sign", "trajopt/optim/gauss_newton.py",
          "at_lo = (z <= lower) & (g > 0)\n    at_hi = (z >= upper) & (g < 0)",
          "at_lo = (z <= lower) & (g < 0)\n    at_hi = (z >= upper) & (g > 0)", OPT,
          "active-set sign flipped in the bound projection"),
    Fault("armijo_off", "trajopt/optim/gauss_newton.py",
          "if f_try <= f + opt.armijo * min(float(g @ (z_try - z)), 0.0):", "if True:", OPT,
          "line search accepts any step"),
    # ------------------------------------------------------------------ trajopt: metrics, targets
    Fault("bl_per_min_30", "trajopt/evaluation.py",
          "return float(v) * 60.0 / float(body_length)", "return float(v) * 30.0 / float(body_length)", METRICS,
          "BL/min computed with 30 instead of 60"),
    Fault("heading_sign", "soft_envs/sim/kinematics.py",
          "return np.array([math.cos(h), 0.0, math.sin(h)])", "return np.array([math.cos(h), 0.0, -math.sin(h)])",
          METRICS, "speed measured along the mirrored heading (heading_vector, shared by metrics and envs)"),
    Fault("slack_max", "trajopt/evaluation.py",
          "s[:, m] = slack[:, cols].min(axis=1)", "s[:, m] = slack[:, cols].max(axis=1)", METRICS,
          "zero-slack post-processing reels in the larger slack of a tendon pair"),
    Fault("target_speed_unit", "trajopt/tasks/targets.py",
          "return float(speed_bl_per_min) * float(body_length) / 60.0",
          "return float(speed_bl_per_min) * float(body_length) / 30.0",
          ("tests/test_cli_paths.py", "tests/test_trajopt.py"), "target speed BL/min -> m/s off by 2"),
    # ------------------------------------------------------------------ envs
    Fault("forward_reward_doubled", "soft_envs/envs/task.py",
          "forward = float(self.forward_reward_weight) * progress",
          "forward = 2.0 * float(self.forward_reward_weight) * progress", ENVS, "forward reward doubled"),
    Fault("ctrl_cost_of_action", "soft_envs/envs/task.py",
          "np.sum(np.square(0.5 * (action + 1.0)))", "np.sum(np.square(action))", ENVS,
          "control cost of the raw action instead of the contraction fraction"),
    Fault("obs_velocity_env_dt", "soft_envs/envs/base.py",
          "obs[3:6] = (self._com - self._frame.com(self._x_prev)) / self.timestep",
          "obs[3:6] = (self._com - self._frame.com(self._x_prev)) / self.dt", ENVS,
          "COM velocity observation over the env step instead of the simulation step"),
    Fault("density_not_randomised", "soft_envs/sim/parameters.py",
          'if name is None or float(factor) == 1.0 or',
          'if name in (None, "density") or float(factor) == 1.0 or', ENVS,
          "domain randomisation (scale_parameters) ignores the density factor"),
    # ------------------------------------------------------------------ sim
    Fault("friction_halved", "soft_envs/sim/contact/paper.py",
          "self.mu_f = robot.contact.friction", "self.mu_f = 0.5 * robot.contact.friction", PHYSICS,
          "friction weight halved consistently everywhere"),
    Fault("friction_removed", "soft_envs/sim/contact/paper.py",
          "self.mu_f = robot.contact.friction", "self.mu_f = 0.0 * robot.contact.friction", PHYSICS,
          "no friction at all"),
    Fault("contact_stiffer", "soft_envs/sim/contact/law.py",
          "self.k_n, self.eps_n = c.stiffness, c.blend", "self.k_n, self.eps_n = 1.5 * c.stiffness, c.blend",
          PHYSICS, "ground penalty 1.5x stiffer consistently everywhere (every contact law)"),
    Fault("lame_mu", "soft_envs/sim/materials.py",
          "return E / (2.0 * (1.0 + nu)), E * nu", "return E / (2.0 * (1.0 - nu)), E * nu",
          ("tests/test_physics_magnitudes.py", "tests/test_reference_rollouts.py"),
          "shear modulus with (1 - nu)"),
    Fault("lumped_mass_third", "soft_envs/sim/mesh.py",
          "np.repeat(density * self.volumes / 4.0, 4)", "np.repeat(density * self.volumes / 3.0, 4)", PHYSICS,
          "each tet gives a third of its mass to each node"),
    Fault("payload_not_spread", "soft_envs/sim/robot.py",
          "m[self.payload_nodes] += self.payload_mass / len(self.payload_nodes)",
          "m[self.payload_nodes] += self.payload_mass", PHYSICS, "the whole payload on every payload node"),
    Fault("rest_state_full_gravity", "soft_envs/sim/rest.py",
          "relax_g = g if (anchored or sim.robot.fixed_nodes.size) else np.array([0.0, g[1], 0.0])",
          "relax_g = g", PHYSICS, "rest state on a slope under full (not normal) gravity with the paper's law"),
    # ------------------------------------------------------------------ sim: Coulomb law, terms, solver state
    Fault("coulomb_bound_doubled", "soft_envs/sim/contact/coulomb.py",
          "self.mu, self.rs = c.friction_coefficient, c.slip_distance",
          "self.mu, self.rs = 2.0 * c.friction_coefficient, c.slip_distance", COULOMB,
          "Coulomb friction bounded by 2 mu N instead of mu N, consistently everywhere"),
    Fault("coulomb_slip_distance_doubled", "soft_envs/sim/contact/coulomb.py",
          "self.mu, self.rs = c.friction_coefficient, c.slip_distance",
          "self.mu, self.rs = c.friction_coefficient, 2.0 * c.slip_distance", COULOMB,
          "the bristles reach mu N at twice the slip distance, consistently everywhere"),
    Fault("anchor_drags_sticking_nodes", "soft_envs/sim/contact/coulomb.py",
          "if r <= rs:\n            out[c, 0], out[c, 1] = anchors[c, 0], anchors[c, 1]",
          "if r <= rs:\n            out[c, 0], out[c, 1] = tx, tz", COULOMB,
          "a sticking node's anchor follows it (no stick: creeps like the paper's law)"),
    Fault("anchor_not_dragged_when_sliding", "soft_envs/sim/contact/coulomb.py",
          "out[c, 0], out[c, 1] = tx - rs * dx / r, tz - rs * dz / r",
          "out[c, 0], out[c, 1] = anchors[c, 0], anchors[c, 1]", COULOMB,
          "a sliding node leaves its anchor behind (pulled back after it stops)"),
    Fault("history_not_carried", "soft_envs/sim/state.py",
          "history = system.next_history(x, state.x, state.history) if system.has_history else state.history",
          "history = state.history", COULOMB,
          "a rollout keeps its starting anchors instead of updating them after each step"),
    Fault("rest_anchors_dropped", "soft_envs/sim/simulator.py",
          "            if x_prev0 is None and history0 is None:\n                return rest\n",
          "            if x_prev0 is None and history0 is None:\n                return self.state_at_rest(rest.x)\n",
          (*COULOMB, "tests/test_state.py"),
          "a rollout from the rest state re-anchors the nodes where they stand (its loaded bristles forgotten)"),
    Fault("rest_state_unloaded_anchors", "soft_envs/sim/rest.py",
          "    rest = State.at_rest(x, history)\n", "    rest = State.at_rest(x, system.initial_history(x))\n",
          ("tests/test_state.py", "tests/test_coulomb_anchors.py"),
          "the rest State carries anchors where the nodes stand, not the relaxation's loaded ones (issue #27's trap)"),
    Fault("adjoint_start_at_rest", "soft_envs/sim/simulator.py",
          'start = traj.info.get("start") if x0 is None and history0 is None else None',
          "start = None", ("tests/test_state.py", "tests/test_sensitivity.py"),
          "the adjoint of a rollout re-walks it from rest at x_0 with fresh anchors, not from the State it started from"),
    Fault("factor_cache_no_generation", "soft_envs/sim/linsolve.py",
          "return self.generation == solver.generation", "return self.generation >= 0",
          ("tests/test_dynamics.py",), "a FactorCache trusts whatever the solver holds (generation check removed)"),
    Fault("term_dropped_cables", "soft_envs/sim/system.py",
          "[self.elastic, self.cables, self.contact,", "[self.elastic, self.contact,", PHYSICS,
          "the cable term left out of EnergySystem.terms"),
    Fault("term_dropped_contact", "soft_envs/sim/system.py",
          "[self.elastic, self.cables, self.contact,", "[self.elastic, self.cables,", PHYSICS,
          "the contact term left out of EnergySystem.terms"),
    # ------------------------------------------------------------------ trajopt / envs after the refactors
    Fault("measure_gait_window", "trajopt/evaluation.py",
          "marks = n_prep + n_cycle * np.arange(n_cycles + 1)", "marks = n_cycle * np.arange(n_cycles + 1)",
          METRICS, "measure_gait's cycles start at step 0 instead of after the prep phase"),
    Fault("forward_reward_timestep", "soft_envs/envs/base.py",
          "forward_velocity = float((self._com - com_before) @ self._heading) / self.dt / self._body_length",
          "forward_velocity = float((self._com - com_before) @ self._heading) / self.timestep / self._body_length",
          ENVS, "forward velocity over the simulation step instead of the env step (env.dt) with frame_skip"),
    # ------------------------------------------------------------------ hardware
    Fault("counts_without_2pi", "trajopt/hardware/config.py",
          "/ self.spool_radius / (2 * math.pi) * self.counts_per_rev",
          "/ self.spool_radius / math.pi * self.counts_per_rev", HARDWARE,
          "cable length -> encoder counts without the 2 pi"),
    # ------------------------------------------------------------------ the turn, slack eating, robustness
    Fault("heading_jacobian_sign", "trajopt/optim/objectives.py",
          "return s * (yaw[1:] - heading.yaw[1:]), s * dyaw[1:]",
          "return s * (yaw[1:] - heading.yaw[1:]), -s * dyaw[1:]", TURN,
          "the heading term's Jacobian with the wrong sign (the turn's Gauss-Newton would step away)"),
    Fault("slack_eating_inactive", "trajopt/optim/objectives.py",
          "active = gamma < eps", "active = gamma < -eps", OPT,
          "slack eating (eq. 13) only on cables more than eps slack instead of less than eps taut"),
    Fault("robustness_contact_law", "trajopt/robustness/study.py",
          "robot = with_contact_law(load_robot(job.robot), job.contact)", "robot = load_robot(job.robot)",
          ("tests/test_robustness.py",),
          "robustness replays a gait under the robot file's law, not its own (a paper-law gait under Coulomb)"),
    # ================================================================== issue #30: the six classes
    # (1) magnitudes asserted as thresholds
    Fault("cable_tension_is_stiffness", "soft_envs/sim/cables.py",
          "return one_sided_quadratic(self.deformation(x, u), self.stiffness, self.blend)[1]",
          "return one_sided_quadratic(self.deformation(x, u), self.stiffness, self.blend)[2]", PINNED,
          "cable tension read-out returns the stiffness Q'' instead of the force Q'"),
    Fault("gravity_per_node_g_halved", "soft_envs/sim/gravity.py",
          "self.force = (np.asarray(node_masses)[:, None] * self.g[None, :]).ravel()",
          "self.force = (np.asarray(node_masses)[:, None] * 0.5 * self.g[None, :]).ravel()", PINNED,
          "gravity's force is m g / 2 per node"),
    Fault("objective_com_not_over_K", "trajopt/optim/objectives.py",
          "s_com = np.sqrt(weights.com / K) / body_length", "s_com = np.sqrt(weights.com) / body_length", PINNED,
          "COM tracking term not averaged over the K states"),
    Fault("magnitude_from_upper_bound", "trajopt/optim/objectives.py",
          "r_mag = s_mag * (z - lo) / rng_z", "r_mag = s_mag * (z - hi) / rng_z", PINNED,
          "magnitude regulariser measured from u_max (its Jacobian unchanged)"),
    Fault("motor_rpm_over_30", "soft_envs/sim/robot.py",
          "return self.max_speed_rpm * 2.0 * np.pi / 60.0", "return self.max_speed_rpm * 2.0 * np.pi / 30.0",
          ("tests/test_motor_limit.py::test_a_motors_contraction_speed_is_its_rpm_on_its_spool",),
          "a motor's speed limit rpm -> m/s off by 2"),
    Fault("cycle_path_speed_per_cycle", "trajopt/evaluation.py",
          '"cycle_path_speed_bl_per_min": mps_to_bl_per_min(chords / (n_cycles * n_cycle * dt), bl)',
          '"cycle_path_speed_bl_per_min": mps_to_bl_per_min(chords / (n_cycle * dt), bl)', PINNED,
          "cycle path speed over one cycle's time instead of all cycles'"),
    Fault("calibrate_std_in_log_units", "trajopt/calibration/calibrate.py",
          "* np.where(prob.log, theta, 1.0)", "* np.where(prob.log, 1.0, 1.0)", CALIB,
          "calibration standard errors of log-fitted parameters left in log units"),
    Fault("calibrate_rms_without_3", "trajopt/calibration/calibrate.py",
          "float(np.sqrt(3.0 * np.mean(rr ** 2)))", "float(np.sqrt(np.mean(rr ** 2)))", CALIB,
          "calibration RMS marker distance off by sqrt(3) (per coordinate instead of per marker)"),
    # (2) tables tested against themselves
    Fault("robustness_lag_in_ms", "trajopt/robustness/study.py",
          '"motor_lag_s": ("value", 0.0, 0.1)', '"motor_lag_s": ("value", 0.0, 100.0)', TABLES,
          "robustness motor lag range in ms where the table says s"),
    Fault("robustness_youngs_range_narrow", "trajopt/robustness/study.py",
          '"youngs_modulus": ("factor", 0.7, 1.3)', '"youngs_modulus": ("factor", 0.9, 1.1)', TABLES,
          "robustness Young's modulus range not the documented x 0.7 - 1.3"),
    Fault("dr_default_friction_range", "soft_envs/envs/domain.py",
          'MappingProxyType({\n    "friction": (0.7, 1.3),', 'MappingProxyType({\n    "friction": (0.97, 1.03),',
          TABLES, "domain_randomization=True friction range not the documented (0.7, 1.3)"),
    Fault("crc_init_ffff", "trajopt/hardware/protocol.py",
          "return binascii.crc_hqx(bytes(data), 0)", "return binascii.crc_hqx(bytes(data), 0xFFFF)",
          ("tests/test_hardware_protocol.py", *TABLES), "RoboClaw CRC-16 with init 0xFFFF (CCITT-FALSE, not XMODEM)"),
    Fault("counts_per_rev_motor_side", "trajopt/hardware/config.py",
          "DEFAULT_COUNTS_PER_REV = 12 * 297.92", "DEFAULT_COUNTS_PER_REV = 12 * 29.792", TABLES,
          "default encoder counts per output revolution with a 10x wrong gear ratio"),
    # (3) a perturbation never shown to reach the physics
    Fault("robustness_cable_stiffness_not_applied", "trajopt/robustness/study.py",
          '"payload_mass", "cable_stiffness")', '"payload_mass")', REACH,
          "robustness draws and reports cable stiffness but never applies it"),
    Fault("robustness_payload_not_applied", "trajopt/robustness/study.py",
          '"friction", "payload_mass",', '"friction",', REACH,
          "robustness draws and reports payload mass but never applies it"),
    Fault("robustness_coulomb_friction_not_applied", "soft_envs/sim/parameters.py",
          "name = robot.contact.law.friction_parameter", 'name = "friction"', REACH,
          "robustness (scale_parameters) perturbs the paper weight of a Coulomb gait (not its mu)"),
    Fault("robustness_slope_not_applied", "trajopt/robustness/study.py",
          'incline, uphill = perturbed_slope(job.incline_deg, job.heading_deg, p["slope_deg"], p["slope_direction_deg"])',
          "incline, uphill = job.incline_deg, job.heading_deg", REACH,
          "robustness reports an extra slope but replays on the nominal one"),
    Fault("robustness_lag_not_applied", "trajopt/robustness/study.py",
          'alpha = 1.0 - math.exp(-dt / p["motor_lag_s"]) if p["motor_lag_s"] > 0 else 1.0', "alpha = 1.0", REACH,
          "robustness reports a motor lag but the motors follow at once"),
    Fault("dr_contact_stiffness_ignored", "soft_envs/sim/parameters.py",
          'if name is None or float(factor) == 1.0 or',
          'if name in (None, "contact_stiffness") or float(factor) == 1.0 or', REACH,
          "domain randomisation (scale_parameters) reports a contact stiffness factor but never applies it"),
    # (4) one of several rules exercised
    Fault("healthy_ignores_height", "soft_envs/envs/task.py",
          "and com[1] >= self.healthy_height_fraction * rest_com_height",
          "and com[1] >= 0.0 * rest_com_height", RULES, "termination only by tilt (the COM-height rule lost)"),
    Fault("upright_ignores_height", "trajopt/evaluation.py",
          "com_h.min() >= 0.5 * com_h[0]", "com_h.min() >= 0.0 * com_h[0]", RULES,
          "measure_gait's upright only by tilt (the COM-height rule lost)"),
    Fault("dr_coulomb_friction_paper_weight", "soft_envs/sim/parameters.py",
          "name = robot.contact.law.friction_parameter", 'name = "friction"', RULES,
          "domain randomisation (scale_parameters) of friction under the Coulomb law scales the (unused) paper weight"),
    Fault("turn_left_rewarded_as_right", "soft_envs/envs/task.py",
          'sign = 1.0 if self.turn_direction == "right" else -1.0', "sign = 1.0", RULES,
          "turn reward: a left turn rewarded for turning right"),
    Fault("turn_radius_ignored", "soft_envs/envs/task.py",
          "radius = body_length if self.turn_radius is None else self.turn_radius", "radius = body_length", RULES,
          "turn reward ignores turn_radius"),
    Fault("readback_ignores_direction", "trajopt/hardware/config.py",
          "return self.direction * turns * (2 * math.pi) * self.spool_radius",
          "return turns * (2 * math.pi) * self.spool_radius", RULES,
          "encoder counts -> cable length ignores the motor's direction -1"),
    # (5) integrity checks with one edited field
    Fault("mesh_hash_ignores_nodes", "soft_envs/sim/fingerprint.py",
          "    h.update(np.round(mesh.points / size * 1e9).astype(np.int64).tobytes())\n", "", INTEGRITY,
          "robot fingerprint's mesh hash ignores node positions (moved nodes, same tets, pass)"),
    Fault("content_hash_ignores_meta", "trajopt/results/result.py",
          "h = hashlib.sha256(meta_text.encode())", "h = hashlib.sha256()", INTEGRITY,
          "a result's content hash ignores its metadata (an edited setting passes)"),
    # (6) hardware confirmation tried one way
    Fault("stop_unreadable_encoder_confirmed", "trajopt/hardware/stop.py",
          "            outcome[ch] = (False, unreadable + why)\n        else:",
          "            outcome[ch] = (True, unreadable + why)\n        else:", STOP,
          "a stop whose first encoder read-back goes unanswered is confirmed"),
    Fault("stop_moving_motor_confirmed", "trajopt/hardware/stop.py",
          'outcome[ch] = (False, f"duty 0 acknowledged but the motor still moves',
          'outcome[ch] = (True, f"duty 0 acknowledged but the motor still moves', STOP,
          "a stop whose motor keeps moving is confirmed"),
    # sweep
    Fault("sweep_quick_ignored", "trajopt/sweep/spec.py",
          "if quick:\n            params.update(overrides)", "if False:\n            params.update(overrides)",
          ("tests/test_sweep.py::test_quick_arguments_keep_the_run_names", "tests/test_each_rule.py"), "a sweep's [runs.quick] overrides ignored under --quick"),
    Fault("sweep_option_unchecked", "trajopt/sweep/kinds.py",
          "        return self.parse(str(raw))", "        return raw",
          ("tests/test_sweep.py",), "a sweep file's option values reach the run unchecked (speed = \"fast\")"),
    # tasks
    Fault("turn_on_the_paper_law", "trajopt/tasks/registry.py",
          '    contact: str | None = "coulomb"', "    contact: str | None = None",
          ("tests/test_tasks.py", "tests/test_turn.py"), "the turn runs on the robot file's contact law"),
    Fault("turn_heading_untracked", "trajopt/tasks/registry.py",
          "        return quarter_circle_heading(n_steps, dt, speed, 0.0, turn)", "        return None",
          ("tests/test_tasks.py", "tests/test_turn.py"), "the turn's heading term has no target (COM tracking only)"),
]


def copy_checkout(dest: Path) -> None:
    """Tracked and untracked non-ignored files, plus __pycache__ (numba's caches), mtimes kept."""
    out = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, check=True,
                         capture_output=True).stdout.decode()
    for rel in filter(None, out.split("\0")):
        src = ROOT / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    for cache in ROOT.rglob("__pycache__"):
        rel = cache.relative_to(ROOT)
        if ".git" in rel.parts or rel.parts[0].startswith("."):
            continue
        if (dest / rel.parent).is_dir():
            shutil.copytree(cache, dest / rel, dirs_exist_ok=True, copy_function=shutil.copy2)


def check_targets(faults: list[Fault], root: Path) -> list[str]:
    problems = []
    for f in faults:
        path = root / f.file
        n = path.read_text().count(f.old) if path.is_file() else -1
        if n != 1:
            where = "file missing" if n < 0 else f"old text found {n} times"
            problems.append(f"{f.name}: {f.file}: {where}: {f.old!r}")
    return problems


def run_tests(root: Path, tests: tuple[str, ...], timeout: float) -> tuple[int, str, float]:
    env = {**os.environ, "PYTHONPATH": str(root), "MPLBACKEND": "Agg"}
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests],
                              cwd=root, env=env, capture_output=True, text=True, timeout=timeout)
        code, out = proc.returncode, proc.stdout + proc.stderr
    except subprocess.TimeoutExpired as exc:
        code, out = -1, f"timeout after {timeout:.0f} s\n{exc.stdout or ''}"
    return code, out, time.perf_counter() - t0


def first_failure(output: str) -> str:
    m = re.search(r"^(?:FAILED|ERROR) (\S+)", output, re.MULTILINE)
    return m.group(1) if m else "?"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", nargs="+", metavar="FAULT", help="run these faults only")
    p.add_argument("--all-tests", action="store_true", help="run the whole default suite for every fault")
    p.add_argument("--list", action="store_true", help="list the faults and exit")
    p.add_argument("--timeout", type=float, default=1800.0, help="per test run [s]")
    p.add_argument("--keep", action="store_true", help="keep the temporary copy")
    a = p.parse_args(argv)
    faults = [f for f in FAULTS if not a.only or f.name in a.only]
    if a.only and len(faults) != len(a.only):
        print(f"unknown faults: {sorted(set(a.only) - {f.name for f in FAULTS})}", file=sys.stderr)
        return 2
    if a.list:
        for f in faults:
            print(f"{f.name:26s} {f.file:30s} {f.why}")
        return 0
    stale = check_targets(faults, ROOT)
    if stale:
        print("STALE FAULTS (the code they target changed; re-target them):\n  " + "\n  ".join(stale),
              file=sys.stderr)
        return 2
    tmp = Path(tempfile.mkdtemp(prefix="soft_envs_mutation_"))
    try:
        copy_checkout(tmp)
        suites = {("tests",)} if a.all_tests else {f.tests for f in faults}
        print(f"copy: {tmp}; baseline: {len(suites)} test set(s) without faults", file=sys.stderr)
        for tests in sorted(suites):
            code, out, dt = run_tests(tmp, tests, a.timeout)
            if code != 0:
                print(f"BASELINE FAILS ({' '.join(tests)}, exit {code}, {dt:.0f} s): fix the suite first",
                      out[-3000:], sep="\n", file=sys.stderr)
                return 2
            print(f"  baseline {' '.join(tests)}: passed in {dt:.0f} s", file=sys.stderr)
        rows = []
        for f in faults:
            path = tmp / f.file
            original, stat = path.read_text(), path.stat()
            pyc = Path(importlib.util.cache_from_source(str(path)))
            pyc.unlink(missing_ok=True)              # never a stale bytecode of another fault
            path.write_text(original.replace(f.old, f.new))
            try:
                code, out, dt = run_tests(tmp, ("tests",) if a.all_tests else f.tests, a.timeout)
            finally:
                path.write_text(original)
                os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))    # numba's cache stays valid
                pyc.unlink(missing_ok=True)
            if code == 1:
                verdict = first_failure(out)
            elif code == 0:
                verdict = "NOT CAUGHT"
            else:
                verdict = f"ERROR (pytest exit {code}: {first_failure(out)})"
            rows.append((f.name, f.why, verdict, dt))
            print(f"  {f.name}: {verdict} ({dt:.0f} s)", file=sys.stderr)
    finally:
        if not a.keep:
            shutil.rmtree(tmp, ignore_errors=True)
    print("\n| fault | what | caught by (first failing test) | time |\n|---|---|---|---|")
    for name, why, verdict, dt in rows:
        print(f"| {name} | {why} | {verdict} | {dt:.0f} s |")
    missed = [r[0] for r in rows if r[2] == "NOT CAUGHT" or r[2].startswith("ERROR")]
    print(f"\n{len(rows) - len(missed)}/{len(rows)} faults caught" + (f"; NOT caught: {missed}" if missed else ""))
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
