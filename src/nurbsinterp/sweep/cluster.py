"""The cases on Dask (the only module of nurbsinterp that imports ``distributed``).

By default a ``distributed.LocalCluster`` of one single-threaded worker process per core (a case is numba
kernels and Python glue: one core each); with a scheduler address, the cluster already running there.  The
cases are submitted a bounded window at a time and their rows come back as they finish
(``distributed.as_completed``), so neither the client nor the scheduler holds more than the window: the
client's memory does not grow with the sweep.  Each task carries its case's bytes (the program, the servo
model), never a path, so workers on other machines need no shared filesystem.  A worker that dies takes only
its running cases with it: the scheduler runs them again elsewhere, and a case that keeps killing workers
(``distributed.scheduler.allowed-failures``) comes back as a ``lost`` row naming why.
"""
from __future__ import annotations

import logging
import os
import uuid

from ..errors import silence_asyncio
from .case import run_case

SATURATION = 1.0  # distributed.scheduler.worker-saturation of the local cluster (Cluster.__init__)
WINDOW_PER_WORKER = 2  # cases in flight per worker thread beyond the one it runs: no worker waits for the client


def _distributed():
    import distributed  # the CLI has said in one line how to install it where it is missing

    return distributed


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _worker_version() -> str:
    from .._version import __version__

    return __version__


def _kernels_warm() -> tuple:
    """On a worker: its host, and whether its install has compiled the kernels of this version."""
    import socket

    from .._cache import kernels_warm

    return socket.gethostname(), kernels_warm()


def _prime() -> int:
    """Run every stage of the pipeline once on the bundled circle (warmup.warm_up), so that the kernels' cache
    loads -- about 3 s of a fresh worker's first case -- are paid before any case and never counted in a row's
    plan_s or simulate_s; where the install has never compiled them, this compiles them.  Returns the kernels
    compiled."""
    from . import case  # noqa: F401  -- the whole pipeline's modules
    from .._cache import mark_warm
    from ..warmup import warm_up

    compiled = warm_up()["compiled"]
    mark_warm()
    return compiled


def _task(case):
    """One case on a worker: its row, the worker's address added."""
    row = run_case(case)
    try:
        from distributed import get_worker

        row["worker"] = get_worker().address
    except Exception:  # noqa: BLE001 -- run outside a worker (a test): no address
        pass
    return row


class Cluster:
    """A Dask client on a local cluster (*workers* processes) or on the scheduler at *scheduler*; a context manager
    that closes what it opened (a remote scheduler and its workers are left running)."""

    def __init__(self, scheduler: str | None = None, workers: int | None = None, wait_timeout: float = 600.0):
        distributed = _distributed()
        self.scheduler = scheduler
        self.cluster = None
        if scheduler is None:
            import dask

            # A worker process logs through its own `distributed` loggers, set up from dask's config as it imports
            # distributed -- before the nanny hands it `silence_logs`, which reaches only the nanny's logger.  Its
            # INFO lines ("Received 'close-stream' ... closing.") would then follow the sweep's last line when an
            # interrupt closes the cluster under it.  The environment is what a spawned worker reads at import
            # (a worker the nanny restarts too); a user's own setting is kept.
            os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "critical")
            n = workers or usable_cores()
            # one case a worker thread at a time: with Dask's default saturation (1.1, rounded up) each worker holds
            # a second case in its own queue, and a short case can wait there behind a long one while another
            # worker idles.  A case is long enough (tens of ms and more) for the scheduler's round trip not to count.
            # and no statistical profiler: it takes each worker's GIL every 10 ms to read its stack, for a dashboard
            # no local sweep opens, and on a machine whose cores are all workers that is the cases' time.
            with dask.config.set({"distributed.scheduler.worker-saturation": SATURATION,
                                  "distributed.worker.profile.enabled": False}):
                # the scheduler still serves HTTP (health, metrics) with no dashboard; on its default port 8787 a
                # second cluster on the machine draws "Port 8787 is already in use" on stderr -- a free port on
                # loopback instead.  The workers' own log records are silenced to CRITICAL: a case's failure comes
                # back through its future and is reported in the sweep's words, and when the client goes first (an
                # interrupt) each worker would otherwise log its lost heartbeat with a traceback.
                self.cluster = distributed.LocalCluster(
                    n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                    scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
                    silence_logs=logging.CRITICAL)
            self.client = distributed.Client(self.cluster)
        else:
            self.client = distributed.Client(scheduler, timeout="30s")
            self.client.wait_for_workers(1, timeout=wait_timeout)
        self.primed = False

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None and not issubclass(exc_type, Exception):
            silence_asyncio()  # an interrupt or a termination cut the client short mid-gather
        self.close()
        return False

    def close(self):
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()

    @property
    def threads(self) -> int:
        return max(1, sum(self.client.nthreads().values()))

    def check_versions(self) -> None:
        """Every worker runs this nurbsinterp: a task travels by reference, and another version runs other code."""
        from .._version import __version__
        from ..errors import UsageError

        for address, version in self.client.run(_worker_version).items():
            if version != __version__:
                raise UsageError(f"the worker at {address} runs nurbsinterp {version}, this sweep {__version__}: "
                                 "install the same version on every worker")

    def prime(self, notice=None) -> None:
        """Prime every worker (_prime).  Where a host's install has not compiled the kernels, one of its workers
        compiles them first (its siblings then load that cache rather than each compiling), *notice*(text) told
        before: minutes, not the seconds of a warm worker.  Once a cluster: a benchmark primes it off the clock."""
        if self.primed:
            return
        cold = {}  # host -> the one worker that compiles there
        found = self.client.run(_kernels_warm)
        for address, (host, warm) in found.items():
            if not warm:
                cold.setdefault(host, address)
        if cold:
            if notice is not None:
                for host, address in sorted(cold.items()):
                    notice(f"worker {address} on {host}: compiling the numeric kernels once for that install "
                           "(about 4 minutes on one core; `nurbsinterp warmup` there beforehand saves it)")
            self._on_each(_prime, list(cold.values()))
        self._on_each(_prime, list(found))
        self.primed = True

    def _on_each(self, function, addresses) -> list:
        """*function*() as a task on each worker of *addresses*, waited for.  A task, not client.run: run calls it
        in the worker's event loop, and minutes of compiling there would stop its heartbeats until the scheduler
        dropped the worker (distributed.scheduler.worker-ttl, 5 minutes).  Another worker runs it where the
        worker named has gone (priming one twice is harmless)."""
        token = uuid.uuid4().hex[:8]
        futures = [self.client.submit(function, key=f"nurbsinterp-{function.__name__.strip('_')}-{i}-{token}",
                                      workers=[address], allow_other_workers=True, pure=False)
                   for i, address in enumerate(addresses)]
        try:
            return self.client.gather(futures)
        finally:
            for future in futures:
                future.release()

    def run(self, cases, on_row):
        """Run every case of the iterable *cases*, calling *on_row*(row) as each finishes (in any order)."""
        distributed = _distributed()
        window = max(4, (WINDOW_PER_WORKER + 1) * self.threads)
        # keys of this run alone: a key an earlier run on the same cluster released may not be forgotten yet
        token = uuid.uuid4().hex[:8]
        pending = {}  # future key -> case: only the window's
        # this client's loop: as_completed takes the *default* client's otherwise, the newest one of the process,
        # and a second client open beside this one (a benchmark's other cluster, a user's own) would never see
        # these futures finish
        done = distributed.as_completed(with_results=True, raise_errors=False, loop=self.client.loop)
        todo = iter(cases)

        def top_up():
            while done.count() < window:
                case = next(todo, None)
                if case is None:
                    return
                key = f"nurbsinterp-case-{case.index}-{token}"
                pending[key] = case
                done.add(self.client.submit(_task, case, key=key, pure=False, retries=0))

        top_up()
        for future, result in done:
            case = pending.pop(future.key)
            row = result if future.status == "finished" else lost_row(case, result)
            future.release()
            on_row(row)
            top_up()


def lost_row(case, error) -> dict:
    """The row of a case Dask could not run (a worker it killed, ...): its labels and the reason."""
    from .case import labels

    row = labels(case)
    row.update(status="lost", error=" ".join(f"dask: {type(error).__name__}: {error}".split()))
    return row
