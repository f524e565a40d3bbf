"""Where a campaign's jobs run: in this process, on a local worker pool, or on Dask.

:func:`run_jobs` picks the place and hands every finished :class:`RunRecord` back;
what one run does is :func:`cosim.verify.workers.run_one`, the same in every place. Kept
apart from :mod:`cosim.verify.workers` so that the pool (:mod:`cosim.verify.pool`),
which runs the workers' code, and the workers do not import each other.
"""

from __future__ import annotations

import contextlib
import uuid
from collections.abc import Callable, Sequence
from typing import Any

from cosim.verify.pool import WorkerPool
from cosim.verify.records import RunRecord
from cosim.verify.workers import (
    CampaignError,
    Job,
    WorkerSpec,
    crashed_record,
    run_here,
    run_one,
)


def run_jobs(
    spec: WorkerSpec,
    jobs: Sequence[Job],
    done: Callable[[RunRecord], None],
    *,
    workers: int = 1,
    cluster: str | None = None,
    pool: Any = None,
) -> None:
    """Run jobs and hand each finished record to ``done`` (in completion order).

    Parameters
    ----------
    spec : WorkerSpec
        The campaign.
    jobs : sequence of Job
        The runs.
    done : callable
        Called in this process with each :class:`RunRecord` as it finishes.
    workers : int
        Local processes (1: this process), for a pool that lives for this call.
    cluster : str, optional
        Address of a Dask scheduler; replaces local workers.
    pool : cosim.verify.pool.WorkerPool, optional
        Run on this pool (its size replaces ``workers``); its processes and built blocks
        stay for its next call.

    Raises
    ------
    CampaignError
        The Dask scheduler cannot be reached, or local workers cannot start.
    """
    jobs = list(jobs)
    if not jobs:
        return
    if cluster:
        run_dask(spec, jobs, done, cluster)
    elif pool is not None:
        pool.run(spec, jobs, done)
    elif (workers > 1 and len(jobs) > 1) or spec.isolate:
        with WorkerPool(workers) as once:
            once.run(spec, jobs, done)
    else:
        run_here(spec, jobs, done)


def run_dask(
    spec: WorkerSpec, jobs: list[Job], done: Callable[[RunRecord], None], address: str
) -> None:
    """Run jobs on a Dask cluster, each record to ``done`` as it finishes.

    Parameters
    ----------
    spec : WorkerSpec
        The campaign.
    jobs : list of Job
        The runs.
    done : callable
        Called in this process with each :class:`RunRecord`; a run whose Dask workers
        died again and again is recorded as crashed.
    address : str
        The scheduler's address (``tcp://host:8786``).

    Raises
    ------
    CampaignError
        The scheduler cannot be reached.
    """
    from distributed import Client, KilledWorker, as_completed

    try:
        client = Client(address, timeout="30s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise CampaignError(f"cannot connect to the Dask scheduler at {address}: {exc}") from exc
    token = uuid.uuid4().hex[:12]
    futures = []
    try:
        futures = [
            client.submit(run_one, spec, job, key=f"ins-cosim-run-{token}-{n:05d}")
            for n, job in enumerate(jobs)
        ]
        job_of = {fut.key: job for fut, job in zip(futures, jobs, strict=True)}
        for fut in as_completed(futures):
            try:
                record = fut.result()
            except KilledWorker as exc:  # its workers died, again and again
                text = f"the Dask workers running it died ({exc}); recorded as crashed"
                record = crashed_record(spec, job_of[fut.key], text)
            done(record)
    except BaseException:
        with contextlib.suppress(Exception):
            client.cancel(futures)
        raise
    finally:
        client.close()
