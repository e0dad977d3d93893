"""The robustness matrix's cells on a running Dask distributed cluster (``robustness_matrix.py
--cluster ADDRESS``; ``pip install "dask[distributed]"``).

Dask's scheduler unpickles each task, its function and its cell, and the workers run it, so both
must import this folder's modules: start them from the clone with ``bench/`` on their path
(``PYTHONPATH=bench dask scheduler``, ``PYTHONPATH=bench dask worker ADDRESS``), the workers with
radarodom installed and the matrix's ``--data`` folder at the same path.  A cluster that cannot is
refused before any cell is sent, saying so, rather than each cell failing with Dask's "Error
during deserialization of the task graph".
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator

HERE = os.path.dirname(os.path.abspath(__file__))
#: What a task needs to import where it is unpickled and run.
MODULES = ("matrix_cells", "robustness_matrix", "sequences")


def check_imports(client, address: str) -> None:
    """Refuse (SystemExit, saying how to start them) a scheduler or workers that cannot import
    :data:`MODULES`."""
    # Sent by value (a closure), so that it runs where bench/ is absent.
    modules = MODULES

    def missing() -> list[str]:
        import importlib.util
        return [m for m in modules if importlib.util.find_spec(m) is None]

    where = {"scheduler": client.run_on_scheduler(missing)}
    where.update((f"worker {w}", m) for w, m in client.run(missing).items())
    lacking = {k: v for k, v in where.items() if v}
    if lacking:
        names = sorted(set(sum(lacking.values(), [])))
        raise SystemExit(f"--cluster {address}: the {', '.join(sorted(lacking))} cannot import bench/'s modules "
                         f"({', '.join(names)}): start the scheduler and the workers with this clone's bench/ on "
                         f"their path, e.g. PYTHONPATH={HERE} dask scheduler; PYTHONPATH={HERE} dask worker ADDRESS")


def run_on_cluster(address: str, function: Callable, calls: list[tuple]) -> Iterator[tuple[int, object]]:
    """``(i, function(*calls[i]))`` for every call, as the cluster at *address* finishes them."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise SystemExit("--cluster needs Dask distributed: pip install \"dask[distributed]\"") from None
    with Client(address) as client:
        check_imports(client, address)
        futures = {client.submit(function, *args, pure=False): i for i, args in enumerate(calls)}
        for fut in as_completed(futures):
            yield futures[fut], fut.result()
