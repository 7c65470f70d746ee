"""FAP Studio: MPEG-4 facial animation of a single photo."""

import os

# The numerical work here is small (least squares of a few hundred rows when a photo is opened,
# 2x2 products per frame): OpenBLAS's worker threads only add synchronisation, and on a loaded
# machine they made opening a photo several times slower in wall time (issue 21). One thread
# unless the user asks otherwise; effective when ``editor`` is imported before numpy (the CLI,
# the GUI, the bench).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
