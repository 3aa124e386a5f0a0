"""Co-simulation: SUMO traffic, the frame loop, the command line, sweeps."""

import os

# One BLAS thread (set before numpy loads, unless the user chose): the loop's matrix products
# are (N, 3) x (3, 3), where OpenBLAS's threads gain nothing and, spinning, slow down Open3D's
# casts, SUMO and the writer process that share the cores.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
