"""One BLAS thread per process.

Every matrix beambench multiplies or factors is small (a Newton matrix of at most a few
hundred rows, 3x3 homographies, modal bases), and the work that runs in parallel is
beambench's own (``process`` measures frames while its model thread simulates; tests and
benchmarks share a 2-core machine with other jobs). OpenBLAS's worker threads busy-wait
for each other, so as soon as another process or thread holds a core, a 144 x 144 LU or a
96 x 96 product takes 10-30 ms instead of 0.2 ms (measured 2026-11-23 on the 2-core
machine with one core busy: the 6-element radau5 run went from 0.21 to 6 s per simulated
second). One thread per BLAS library removes that and costs nothing at these sizes.

``threadpoolctl`` is the maintained, standard way to set native thread pools at run
time (the environment variables only act before the libraries load).
"""

from __future__ import annotations

from threadpoolctl import threadpool_limits


def limit_blas_threads(n_threads: int = 1) -> None:
    """Limit every loaded BLAS library (numpy's and scipy's OpenBLAS) to ``n_threads``
    for the rest of the process."""
    import numpy  # noqa: F401  (load the libraries whose pools are limited)
    import scipy.linalg  # noqa: F401

    threadpool_limits(limits=n_threads, user_api="blas")
