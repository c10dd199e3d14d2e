"""Robustness of a gait: replays under perturbed physics (``trajopt robustness``).

* :mod:`.study`: the perturbations, the samples and their summary (re-exported here);
* :mod:`.report`: the study of a result file with its report and picture.
"""
from .study import (PERTURBATIONS, DERIVED_NAMES, SampleJob, draw_perturbation, applied_controls, perturbed_slope,
    run_sample, map_samples, summarize)

__all__ = ["PERTURBATIONS", "DERIVED_NAMES", "SampleJob", "draw_perturbation", "applied_controls",
           "perturbed_slope", "run_sample", "map_samples", "summarize"]
