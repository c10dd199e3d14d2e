"""Fit the foam's Young's modulus, Poisson ratio and the ground friction to tracked markers.

Run:  python examples/calibrate_from_markers.py                (about a minute)
      SOFT_ENVS_QUICK=1 python examples/calibrate_from_markers.py   (tiny settings, as CI runs it)

The paper fits E and nu "through trial and error" (II-A). Here a Tripod under the paper's contact
law (``--contact paper``: its ``friction`` weight is fitted) with hidden parameters
(E 25 % stiffer, nu 0.36 instead of 0.3, friction 30 % lower) plays a gait while a tracker
records 8 markers at 30 Hz with 0.5 mm noise; ``trajopt calibrate`` then recovers the
parameters from the tracks (Gauss-Newton with exact sensitivities of the whole rollout), with
standard errors, a plot of the tracks before and after, and a new robot.toml (all under
results/calibration/; a quick run under results/calibration_quick/). The same from the shell, on
the same data as shipped in examples/data/ (``examples/data/make_tripod_tracks.py`` makes both):

    trajopt calibrate tripod --markers examples/data/tripod_tracks.csv \\
        --controls examples/data/tripod_gait.npz --marker-points examples/data/tripod_markers.csv \\
        --fit youngs_modulus,poisson_ratio,friction --contact paper --out results/calibration/fit
"""
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "data"))
from make_tripod_tracks import HIDDEN, write_tripod_tracks  # noqa: E402  (examples/data/, not a package)

from trajopt.cli import main  # noqa: E402

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
OUT = Path("results") / ("calibration_quick" if QUICK else "calibration")   # a quick run never replaces a full one

# the tracks of a Tripod with hidden parameters playing a gait (120 steps; 30 quick), 8 markers
fit = ["youngs_modulus"] if QUICK else ["youngs_modulus", "poisson_ratio", "friction"]
hidden = write_tripod_tracks(OUT / "markers.csv", OUT / "gait.npz", OUT / "tracks.csv", steps=30 if QUICK else 120,
                             hidden={k: HIDDEN[k] for k in fit})
gait = OUT / "gait.npz"
print("hidden:", ", ".join(f"{k} = {v:g}" for k, v in hidden.items()))

code = main(["calibrate", "tripod", "--markers", str(OUT / "tracks.csv"), "--controls", str(gait),
             "--marker-points", str(OUT / "markers.csv"), "--fit", ",".join(fit), "--contact", "paper",
             "--out", str(OUT / "fit")])
print(f"the plot of the tracks before and after the fit: {OUT / 'fit' / 'tracks.png'}")
raise SystemExit(code)
