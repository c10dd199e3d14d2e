"""The optimisation core (paper III): forward shooting with exact sensitivities and Gauss-Newton.

* :mod:`.optimize`: :func:`~.optimize.optimize_gait` (the problem, the start, the solve, the
  result);
* :mod:`.gauss_newton` with :mod:`.qp`: the constrained Gauss-Newton step;
* :mod:`.objectives`: the residuals (paper eqs. 5, 13) and :mod:`.heading` (the body's heading);
* :mod:`.parameterization` and :mod:`.gait`: keyframes -> controls (eq. 12);
* :mod:`.motor_limit`: the motors' limits as constraints on the keyframes.

The package imports nothing at import time; import the modules.
"""
