"""Calibration: fitting a robot's physical parameters to tracked markers (``trajopt calibrate``).

* :mod:`.calibrate`: the fit (Gauss-Newton on the parameter sensitivities);
* :mod:`.checks`: what a fit must pass before it is believed;
* :mod:`.tracks`: the marker tracks (CSV); :mod:`.files`: the calibrated robot.toml, the plot.

The package imports nothing at import time; import the modules. docs/calibration.md.
"""
