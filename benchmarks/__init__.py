"""Benchmarks: ``make bench`` runs every ``bench_*.py`` module here (see __main__).

Every benchmark process runs numpy's BLAS on one thread, as the campaign's worker
processes do (:data:`cosim.verify.pool.ONE_THREAD`), set here before numpy is first
imported. The matrices of a run are small: a second BLAS thread does not speed a run
up, it spins beside it. Measured on the 2-core machine (40-run campaign row): with the
default threads the in-process 1-worker campaign took 21.4 s and obtained 1.21 cores,
and the 2-worker one, beside the parent's spinning threads, 11.6 s; with one thread
19.4 s (1.00 core) and 10.0 s. Both campaigns of a row then run the same code the same
way, which the row's bound assumes.
"""

import os

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
