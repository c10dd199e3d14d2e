"""Result files and their checks.

* :mod:`.result`: :class:`~.result.Result`, the ``.npz`` + ``.json`` pair of an optimised gait
  (re-exported here: ``from trajopt.results import Result``);
* :mod:`.checks`: what a result's controls must obey; :mod:`.robot_match`: the robot
  fingerprint that ties a result to its robot;
* :mod:`.files`: atomic writes; :mod:`.reservation`: output names reserved by a run;
  :mod:`.export`: ParaView export.
"""
from .result import FORMAT_VERSION, Result, ResultFileWarning, atomic_write_bytes, partial_path, result_path

__all__ = ["Result", "ResultFileWarning", "atomic_write_bytes", "result_path", "partial_path", "FORMAT_VERSION"]
