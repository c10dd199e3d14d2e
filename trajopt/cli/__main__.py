"""``python -m trajopt.cli ...``: the ``trajopt`` command."""
import sys

import numpy as np

from . import main

if __name__ == "__main__":  # pragma: no cover
    np.seterr(all="ignore")
    sys.exit(main())
