"""Run the independent cases of a sweep as tasks on Dask (or serially), results in case order.

Sweeps (``paramotion fast sweep``, ``paramotion workspace arrangements``, ``paramotion coverage
sweep``) evaluate many independent cases, each CPU-bound Python and often a whole ROS graph.
:func:`run_tasks` spreads them over processes: by default a ``LocalCluster`` on this machine
with one single-threaded worker process per core (the GIL makes threads useless here, and a
process per worker keeps each case's rclpy context apart), or an existing cluster given by its
scheduler address. Each case runs with ``ROS_DOMAIN_ID`` unset (:func:`private_call`), so every
:class:`paramotion.graph.Graph` it builds picks a private random DDS domain with discovery off,
and cases running side by side never hear each other.

Results come back in case order whatever the completion order, so a Dask run writes exactly
what the serial run (``--serial``) writes. See docs/sweeps.md for a multi-machine cluster.
"""
import argparse
import os
from collections.abc import Callable, Iterable, Sequence
from typing import Any, TypeVar

from paramotion.backend import usable_cores
from paramotion.errors import UserError

_Case = TypeVar('_Case')
_Result = TypeVar('_Result')


def default_workers() -> int:
    """Cores this process may use (the affinity mask, not the machine's count)."""
    return usable_cores()


def add_dask_args(parser: argparse.ArgumentParser) -> None:
    """Add ``--scheduler``, ``--workers`` and ``--serial`` to a sweep's argument parser."""
    parser.add_argument('--scheduler', default=None, metavar='tcp://HOST:8786',
                        help='run the cases on this existing Dask scheduler (default: a local '
                        'cluster of one-thread worker processes)')
    parser.add_argument('--workers', type=int, default=None,
                        help='worker processes of the local cluster (default: all cores)')
    parser.add_argument('--serial', action='store_true',
                        help='run the cases one after the other in this process (no Dask)')


def run_args(args: argparse.Namespace) -> dict[str, Any]:
    """The :func:`run_tasks` keyword arguments from parsed :func:`add_dask_args` options."""
    return {'scheduler': getattr(args, 'scheduler', None),
            'workers': getattr(args, 'workers', None),
            'serial': getattr(args, 'serial', False)}


def private_call(fn: Callable[[_Case], _Result], case: _Case) -> _Result:
    """``fn(case)`` with ``ROS_DOMAIN_ID`` unset, so every Graph the case builds takes a private
    random domain with discovery off. A ``ROS_DOMAIN_ID`` set to watch one run live would
    otherwise put all the cases running side by side in one shared domain where they hear each
    other's topics (seen: different results than the serial run). Workers run one thread each,
    so changing the environment for the call is safe there."""
    old = os.environ.pop('ROS_DOMAIN_ID', None)
    try:
        return fn(case)
    finally:
        if old is not None:
            os.environ['ROS_DOMAIN_ID'] = old


def private_call_chunk(fn: Callable[[_Case], _Result], chunk: Iterable[_Case]
                       ) -> list[_Result]:
    """:func:`private_call` over a chunk of cases, results in chunk order. One task per chunk
    instead of one per case: the scheduler's overhead per task (milliseconds) would otherwise
    exceed a small case's work, and arrays shared by the cases of a chunk (grids, rotation
    sets) are pickled once per chunk, not once per case (the Table II search has 8594
    candidates sharing a 3.6 MB grid: one task per case ran the client out of memory)."""
    return [private_call(fn, case) for case in chunk]


def chunked(cases: Sequence[_Case], workers: int, per_worker: int = 4
            ) -> list[Sequence[_Case]]:
    """``cases`` cut into consecutive chunks, about ``per_worker`` chunks per worker so that
    the load still balances when cases differ in cost."""
    n = max(1, min(len(cases), int(workers) * per_worker))
    size = -(-len(cases) // n)
    return [cases[k:k + size] for k in range(0, len(cases), size)]


def _progress_bar(total, desc, enabled):
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit='case', disable=not enabled, leave=True)


def run_tasks(fn: Callable[[_Case], _Result], cases: Iterable[_Case], scheduler: str | None = None,
              workers: int | None = None, progress: bool = True, serial: bool = False,
              desc: str = 'cases') -> list[_Result]:
    """``[fn(case) for case in cases]``, the calls spread over a Dask cluster.

    ``fn`` must be a module-level (picklable) function and each case picklable. With
    ``serial`` the calls run here, in order. Otherwise, with ``scheduler`` (``tcp://HOST:PORT``)
    the cases go to that cluster; without, to a ``LocalCluster`` of ``workers`` (default: all
    cores, never more than there are cases) one-thread worker processes, closed on return. A
    tqdm bar counts finished cases when ``progress``. The cases travel in consecutive chunks,
    about four per worker thread (:func:`chunked`). The first failing case's exception is
    raised (the other tasks are cancelled).
    """
    cases = list(cases)
    if workers is not None and int(workers) < 1:
        raise UserError(f'--workers {workers}: must be at least 1')
    if scheduler is not None and not str(scheduler).strip():
        raise UserError('--scheduler: empty address (expected tcp://HOST:8786)')
    if serial or not cases:
        results = []
        with _progress_bar(len(cases), desc, progress) as bar:
            for case in cases:
                results.append(private_call(fn, case))
                bar.update(1)
        return results
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise UserError("Dask is not installed: pip install 'paramotion[sweeps]' (or "
                        'requirements.txt), or run the sweep with --serial') from None

    cluster = None
    if scheduler is None:
        n = min(int(workers or default_workers()), len(cases))
        # Processes, one thread each: every case is CPU-bound Python holding the GIL. No
        # dashboard (its port could clash with another sweep's on a shared machine).
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None)
    try:
        try:
            client = Client(cluster if cluster is not None else scheduler, timeout='20s')
        except OSError as exc:
            raise UserError(f'--scheduler {scheduler}: cannot connect ({exc})') from None
        with client:
            if cluster is None:
                try:
                    client.wait_for_workers(1, timeout=60)
                except TimeoutError:
                    raise UserError(f'--scheduler {scheduler}: no worker joined within 60 s '
                                    '(start some with: dask worker ' f'{scheduler})') from None
            threads = sum(client.nthreads().values()) or 1
            chunks = chunked(cases, threads)
            futures = [client.submit(private_call_chunk, fn, chunk, pure=False)
                       for chunk in chunks]
            index = {f.key: k for k, f in enumerate(futures)}
            results = [None] * len(chunks)
            with _progress_bar(len(cases), desc, progress) as bar:
                try:
                    for future in as_completed(futures):
                        k = index[future.key]
                        results[k] = future.result()
                        bar.update(len(chunks[k]))
                except BaseException:
                    client.cancel(futures)
                    raise
            return [r for chunk_results in results for r in chunk_results]
    finally:
        if cluster is not None:
            cluster.close()
