"""Where ``build-dataset`` prepares its recordings: on this machine, or as tasks on a Dask cluster.

An executor maps a function over tasks and returns the results in task order, whatever finishes
first, so a build gives the same bytes on any executor; it calls ``progress(done, total)`` as
results arrive. The registry :data:`EXECUTORS` names them:

- ``local``: in this process (``jobs`` 1) or in a pool of ``jobs`` worker processes;
- ``dask``: one task per recording on a running Dask cluster, reached at its scheduler's address
  (``tcp://HOST:8786``); needs ``dask[distributed]`` (``pip install 'kinectdata[dask]'``).

The Dask workers read the recordings and write their work files themselves, at the paths this
machine gives them: the recordings and the dataset folder must be on a filesystem every worker
sees at the same paths (a shared filesystem, or a cluster on this machine), and each worker needs
the same kinectdata installed.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

from kinectdata.core.errors import KinectDataError

Progress = Callable[[int, int], None] | None


PARENT_POLL_S = 0.5


def exit_with_parent(parent: int) -> None:
    """In a worker process: exit as soon as ``parent`` is gone (this process is re-parented),
    whatever the worker is doing, even blocked on the pipe to the parent that no longer reads it.
    The parent's own work files are atomic, so what the worker was writing is a ``.partial`` the
    rerun removes."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


@dataclass(frozen=True)
class LocalExecutor:
    """This machine: in this process (``jobs`` 1) or in ``jobs`` worker processes."""

    jobs: int = 1

    @classmethod
    def from_options(cls, *, jobs: int = 1, scheduler: str | None = None) -> LocalExecutor:
        if scheduler is not None:
            raise KinectDataError(f"--scheduler {scheduler} is for --executor dask, not local")
        return cls(jobs)

    def map(self, function: Callable, tasks: Sequence, names: Sequence[str], progress: Progress = None) -> list[Any]:
        """``function(task)`` for each task, in task order. A worker's error is raised as is
        (``names`` are not needed: the worker's own error travels back); a worker that dies is a
        KinectDataError."""
        results = []
        if self.jobs > 1 and len(tasks) > 1:
            # spawned, not forked: a fork copies whatever lock another thread of this process held
            # (a test suite's, a notebook's), and a worker then hung in its first large allocation
            pool = ProcessPoolExecutor(
                max_workers=self.jobs,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=exit_with_parent,
                initargs=(os.getpid(),),
            )
            with pool:
                try:
                    for i, result in enumerate(pool.map(function, tasks)):
                        results.append(result)
                        if progress:
                            progress(i + 1, len(tasks))
                except BrokenProcessPool:
                    raise KinectDataError(
                        f"a worker process died before its task was done ({len(results)} of {len(tasks)} done): "
                        "killed or out of memory, or a script that starts this work outside "
                        '`if __name__ == "__main__":` (the workers are spawned and import it again); '
                        "--jobs 1 runs it in this process"
                    ) from None
        else:
            for i, task in enumerate(tasks):
                results.append(function(task))
                if progress:
                    progress(i + 1, len(tasks))
        return results


@dataclass(frozen=True)
class DaskExecutor:
    """A running Dask cluster: one task per item, submitted through its scheduler.

    Attributes:
        scheduler: the scheduler's address, e.g. ``tcp://10.0.0.5:8786``.
        timeout: seconds to wait for the scheduler (None: Dask's ``distributed.comm.timeouts.connect``,
            30 s unless configured).
    """

    scheduler: str
    timeout: float | None = None

    @classmethod
    def from_options(cls, *, jobs: int = 1, scheduler: str | None = None) -> DaskExecutor:
        if scheduler is None:
            raise KinectDataError("--executor dask needs --scheduler ADDRESS (a running Dask scheduler's)")
        if jobs != 1:
            raise KinectDataError(
                f"--jobs {jobs} is for --executor local; on a Dask cluster its workers set the parallelism"
            )
        return cls(scheduler)

    def _client(self):
        try:
            from distributed import Client
        except ImportError:
            raise KinectDataError("--executor dask needs Dask: pip install 'kinectdata[dask]'") from None
        timeout = {} if self.timeout is None else {"timeout": self.timeout}
        try:
            return Client(self.scheduler, set_as_default=False, **timeout)
        except ValueError as exc:
            raise KinectDataError(f"{self.scheduler!r} is not a Dask scheduler address ({exc})") from None
        except OSError as exc:  # distributed's connection timeout is an OSError
            raise KinectDataError(
                f"cannot reach a Dask scheduler at {self.scheduler} ({exc}): is it running (dask scheduler) and "
                "is the address right?"
            ) from None

    def map(self, function: Callable, tasks: Sequence, names: Sequence[str], progress: Progress = None) -> list[Any]:
        """``function(task)`` for each task on the cluster, results in task order. The function's
        KinectDataError comes back as raised; any other failure (a worker lost, a task that could
        not be sent or run) becomes a KinectDataError naming the task by ``names[i]``. The first
        failure is raised once every other task has ended, so that the work they finish is kept
        for a rerun (closing the client at once would cancel tasks under way, at random)."""
        from distributed import as_completed

        results: list[Any] = [None] * len(tasks)
        failure: KinectDataError | None = None
        with self._client() as client:
            futures = client.map(function, list(tasks), pure=False)
            index = {future.key: i for i, future in enumerate(futures)}
            for done, future in enumerate(as_completed(futures, loop=client.loop), 1):
                i = index[future.key]
                try:
                    results[i] = future.result()
                except KinectDataError as exc:
                    failure = failure or exc
                except Exception as exc:
                    if failure is None:
                        failure = KinectDataError(
                            f"{names[i]}: failed on the Dask cluster at {self.scheduler}: {type(exc).__name__}: {exc}"
                        )
                        failure.__cause__ = exc
                if progress:
                    progress(done, len(tasks))
        if failure is not None:
            raise failure
        return results


Executor = LocalExecutor | DaskExecutor

EXECUTORS: dict[str, type[LocalExecutor] | type[DaskExecutor]] = {"local": LocalExecutor, "dask": DaskExecutor}


def make_executor(name: str, *, jobs: int = 1, scheduler: str | None = None) -> Executor:
    """The executor registered as ``name`` with the command line's ``--jobs`` and ``--scheduler``;
    KinectDataError for an unknown name or an option the executor does not take."""
    try:
        kind = EXECUTORS[name]
    except KeyError:
        raise KinectDataError(f"unknown executor {name!r}; known: {', '.join(EXECUTORS)}") from None
    return kind.from_options(jobs=jobs, scheduler=scheduler)
