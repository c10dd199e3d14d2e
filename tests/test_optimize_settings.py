"""optimize_gait's settings as one object (OptimizeSettings): the object and the keywords give
the same result; a field the object lacks, or another type, is refused by name."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from trajopt import GaitSpec, GaussNewtonOptions, OptimizeSettings, optimize_gait
from trajopt.optim.optimize_settings import settings_with

GAIT = GaitSpec(n_prep=4, n_cycle=8, n_keyframes=2)


def test_the_object_and_the_keywords_give_the_same_result():
    settings = OptimizeSettings(gait=GAIT, speed_bl_per_min=12.0, options=GaussNewtonOptions(max_iter=1), n_seeds=1,
                                eval_cycles=1)
    by_object = optimize_gait("tripod", "walk", settings)
    by_keywords = optimize_gait("tripod", "walk", gait=GAIT, speed_bl_per_min=12.0,
                                options=GaussNewtonOptions(max_iter=1), n_seeds=1, eval_cycles=1)
    mixed = optimize_gait("tripod", "walk", dataclasses.replace(settings, speed_bl_per_min=5.0), speed_bl_per_min=12.0)
    for res in (by_keywords, mixed):
        assert np.array_equal(res.z, by_object.z) and np.array_equal(res.u, by_object.u)
        assert res.settings == by_object.settings
    assert by_object.settings["speed_bl_per_min"] == 12.0 and by_object.settings["n_cycle"] == 8


def test_fields_replace_the_settings_and_unknown_names_are_refused():
    base = OptimizeSettings(n_seeds=3)
    assert settings_with(base, {"eval_cycles": 2}) == OptimizeSettings(n_seeds=3, eval_cycles=2)
    assert settings_with(None, {}) == OptimizeSettings() and settings_with(base, {}) is base
    with pytest.raises(TypeError, match="'n_seed'.*the settings are"):
        optimize_gait("tripod", "walk", n_seed=1)
    with pytest.raises(TypeError, match="settings must be an OptimizeSettings, got dict"):
        optimize_gait("tripod", "walk", {"n_seeds": 1})
