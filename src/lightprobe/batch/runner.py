"""The batch driver: inputs → workers (a local process pool, or Dask distributed) → committed Parquet parts.

Exactly-once: a result counts only once its part file is renamed into ``parts/`` (see :mod:`.table`); the driver
commits every ``chunk_rows`` results or ``chunk_seconds``, whichever comes first. Killed at any moment, a rerun with
``--resume`` reads the committed parts, skips every path (and every content hash) they hold, and redoes the rest —
an input whose result was in flight or not yet committed is redone, never counted twice; artifacts are written
atomically by the workers, so a redone one replaces an identical file. The same task function
(:func:`lightprobe.batch.task.process`) runs under both executors. A worker that dies mid-task (killed, crashed)
costs the pool, not the batch: the local pool is restarted and its unfinished inputs resubmitted, and an input that
was in flight at :data:`MAX_ATTEMPTS` deaths is recorded as an error (``WorkerDied``) rather than retried forever.
"""

from __future__ import annotations

import atexit
import os
import re
import signal
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from ..util.errors import UsageError
from .table import Parts, consolidate, done_keys, manifest, read_manifest, write_manifest
from .task import JobOptions, process

MAX_ATTEMPTS = 3
WORKER_ENVIRONMENT = {"OPENBLAS_NUM_THREADS": "1", "LIGHTPROBE_THREADS": "1", "LIGHTPROBE_PROGRESS": "0"}
CHUNK_ROWS, CHUNK_SECONDS = 64, 5.0
DASK_TIMEOUT = 10.0


@dataclass
class Summary:
    """What a batch run did: counts, time and memory, updated after every result and passed to ``progress``.

    Parameters
    ----------
    total : int
        Inputs given.
    already : int
        Inputs already in the table from an earlier run (``--resume``).
    done : int
        Rows added by this run.
    skipped : int
        Inputs whose content is already in the table (another path with the same bytes): not processed again, their
        row is a copy of that content's row with their own path.
    failed : int
        Errors recorded by this run.
    seconds : float
        Seconds since this run started processing.
    peak_rss : int
        The largest peak resident memory any worker reported, bytes.
    rows : int
        Rows in ``results.parquet`` after consolidation.
    errors : int
        Rows in ``errors.parquet`` after consolidation.
    workers : int
        The executor's worker count.
    executor : str
        The executor's name.
    """
    total: int = 0          # inputs given
    already: int = 0        # already in the table from an earlier run (--resume)
    done: int = 0           # rows added by this run
    skipped: int = 0        # content already in the table (another path with the same bytes)
    failed: int = 0         # errors recorded by this run
    seconds: float = 0.0
    peak_rss: int = 0       # the largest peak resident memory any worker reported (bytes)
    rows: int = 0           # rows in results.parquet after consolidation
    errors: int = 0
    workers: int = 0
    executor: str = ""

    @property
    def throughput(self) -> float:
        """Inputs finished by this run (rows and errors) per second; 0 before any time has passed."""
        return (self.done + self.failed) / self.seconds if self.seconds > 0 else 0.0


# ---- executors ----------------------------------------------------------------------------------------------------
_SKIP: frozenset = frozenset()


def _die_with_the_driver(parent: int) -> None:
    """A worker outlives nothing: on Linux the kernel kills it when its parent, the driver ``parent``, dies
    (PR_SET_PDEATHSIG); elsewhere a thread watches for the parent to change."""
    import threading

    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:  # the parent died before the call above took effect
        os._exit(1)

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


def _init_worker(skip: frozenset, driver: int) -> None:
    global _SKIP
    _die_with_the_driver(driver)
    _SKIP = skip
    # A worker exits only when the pool shuts down, every result already sent (its result queue writes the pipe
    # synchronously) and every artifact renamed into place. Python's finalisation after numba has run costs
    # ~0.3 s, which the driver waits out at the end of every batch: skipped. Registered now, this handler runs
    # before those registered earlier (multiprocessing's, with nothing to flush here) and after any registered
    # later (numba's, on its first kernel).
    atexit.register(os._exit, 0)


def _local_task(path: str, options: JobOptions, out: str) -> dict:
    return process(path, options, out, _SKIP)


def _died(path: str) -> dict:
    return {"kind": "error", "path": path, "sha256": None, "size": None, "error_class": "WorkerDied",
            "message": f"the worker processing {path} died {MAX_ATTEMPTS} times (killed or crashed)", "worker": None}


class LocalPool:
    """``workers`` processes of this machine (spawned: fresh interpreters, nothing inherited).

    Parameters
    ----------
    workers : int
        Worker processes; at most 2 × ``workers`` inputs are in flight.
    """

    name = "local process pool"

    def __init__(self, workers: int):
        self.workers = workers

    def results(self, paths: list[str], options: JobOptions, out: Path, skip: frozenset):
        """Run :func:`lightprobe.batch.task.process` on every path in worker processes, yielding each result.

        Results come in the order they finish, not the order given. The workers run with one BLAS and one kernel thread
        each (:data:`WORKER_ENVIRONMENT`, set in this process while the generator runs and restored after). When a
        worker dies the pool is restarted and the inputs it held go back to the front of the queue; an input in flight
        at :data:`MAX_ATTEMPTS` deaths yields a ``WorkerDied`` error instead.

        Parameters
        ----------
        paths : list of str
            The inputs, read by the workers themselves.
        options : JobOptions
            The job options for every input.
        out : Path
            The batch folder; artifacts are written under its ``maps/``.
        skip : frozenset
            SHA-256 (hex) of contents already in the table: those inputs yield a skip.

        Yields
        ------
        dict
            One result per path (:func:`lightprobe.batch.task.process`): ``kind`` "row", "error" or "skipped".
        """
        import multiprocessing

        pending, attempts = deque(paths), {}
        context = multiprocessing.get_context("spawn")
        # Set before the workers start (they start as tasks are submitted, and again after a pool dies), not in
        # their initializer: numpy loads OpenBLAS, sizing its thread pool, as a worker unpickles its task. One BLAS
        # and one kernel thread each, as the CLI runs, keeps results identical. The driver's own environment is
        # given back when the batch ends.
        saved = {k: os.environ.get(k) for k in WORKER_ENVIRONMENT}
        os.environ.update(WORKER_ENVIRONMENT)
        try:
            yield from self._results(pending, attempts, context, options, out, skip)
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v

    def _results(self, pending, attempts, context, options, out, skip):
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool

        while pending:
            pool = ProcessPoolExecutor(self.workers, mp_context=context, initializer=_init_worker,
                                       initargs=(skip, os.getpid()))
            in_flight: dict = {}
            broken = False
            try:
                while (pending or in_flight) and not broken:
                    while pending and len(in_flight) < 2 * self.workers:
                        path = pending.popleft()
                        in_flight[pool.submit(_local_task, path, options, str(out))] = path
                    finished, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                    for future in finished:
                        try:
                            result = future.result()
                        except BrokenProcessPool:
                            broken = True
                            continue
                        del in_flight[future]
                        yield result
            finally:
                pool.shutdown(wait=not broken, cancel_futures=True)
            for path in in_flight.values():  # the pool died: what was in it goes back (the culprit among them)
                attempts[path] = attempts.get(path, 0) + 1
                if attempts[path] >= MAX_ATTEMPTS:
                    yield _died(path)
                else:
                    pending.appendleft(path)

    def close(self) -> None:
        """Nothing to release: each :meth:`LocalPool.results` shuts its own pools down."""
        pass


class DaskPool:
    """Dask distributed: an existing scheduler, or a ``LocalCluster`` of ``local`` single-threaded worker processes.

    Whoever can submit to a scheduler runs code as its workers, so the local cluster is not open to the machine: it
    listens on loopback with mutual TLS, its credentials made for this run and held in memory only
    (:meth:`distributed.security.Security.temporary`); a client without them — another local user — cannot connect.
    An existing scheduler is reached with the TLS settings of Dask's own configuration (``distributed.comm.tls``),
    if any. Workers read their inputs themselves; only paths go out and rows come back.

    Parameters
    ----------
    scheduler : str or None
        Address of a running scheduler (e.g. ``tcp://host:8786``, ``tls://host:8786``), used when ``local`` is not
        given.
    local : int or None
        Start a local cluster of this many worker processes on 127.0.0.1 (one thread each, with
        :data:`WORKER_ENVIRONMENT`) and use it.
    timeout : float
        Seconds to wait for the scheduler. Default :data:`DASK_TIMEOUT` (10).
    dashboard : bool
        Give the local cluster Dask's dashboard on 127.0.0.1 (a free port, in ``dashboard``). Default False: none.

    Attributes
    ----------
    dashboard : str or None
        The dashboard's URL, or None.

    Raises
    ------
    UsageError
        dask.distributed (or, for ``local``, cryptography; for ``dashboard``, bokeh) is not installed, or the
        scheduler cannot be reached within ``timeout``.
    """

    name = "Dask distributed"

    def __init__(self, scheduler: str | None = None, local: int | None = None, timeout: float = DASK_TIMEOUT,
                 dashboard: bool = False):
        try:
            from dask.distributed import Client, LocalCluster
            from distributed.security import Security
        except ImportError:
            raise UsageError("--scheduler and --dask-local need the optional 'distributed' package: "
                             "pip install 'lightprobe[batch]'") from None
        import logging

        import dask

        self.cluster, self.dashboard = None, None
        if local:
            security = _temporary_security()
            if dashboard:
                _need_bokeh()
            # Dask's scheduler and workers always listen for HTTP too (status pages, metrics: plain HTTP, no
            # credentials); with no routes they serve nothing until their listeners are closed below.
            routes = {"distributed.worker.http.routes": []} | ({} if dashboard else
                                                               {"distributed.scheduler.http.routes": []})
            with dask.config.set(routes):
                self.cluster = LocalCluster(n_workers=local, threads_per_worker=1, processes=True,
                                            host="127.0.0.1", dashboard_address=None, security=security,
                                            scheduler_kwargs={"dashboard": dashboard, "dashboard_address":
                                                              "127.0.0.1:0"},  # a free port, never 8787
                                            silence_logs=logging.ERROR, env=WORKER_ENVIRONMENT)
            scheduler = self.cluster.scheduler_address
            self.dashboard = self.cluster.dashboard_link if dashboard else None
        else:
            security = Security()  # what Dask's configuration says: TLS files, require-encryption
        try:
            if not local:  # Dask's client waits on a silent peer for ever; first a handshake within the timeout
                _handshake(scheduler, timeout, security.get_connection_args("client"))
            self.client = Client(scheduler, timeout=f"{timeout}s", security=security)
        except (OSError, TimeoutError, ValueError) as e:
            self.close()
            raise UsageError(f"cannot reach the Dask scheduler at {scheduler} within {timeout:g} s: "
                             f"{' '.join(str(e).split())[:200] or type(e).__name__}") from None
        if local:
            self.client.run(_close_http)
            if not dashboard:
                self.client.run_on_scheduler(_close_http)
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))

    def results(self, paths: list[str], options: JobOptions, out: Path, skip: frozenset):
        """Submit :func:`lightprobe.batch.task.process` for each path, yielding each result as it completes.

        At most 4 × ``workers`` tasks are in flight. ``skip`` is scattered to every worker once. A task that fails
        inside Dask (KilledWorker after Dask's own retries, a lost worker) yields a ``WorkerDied`` error for its path.

        Parameters
        ----------
        paths : list of str
            The inputs, opened by the workers at these paths.
        options : JobOptions
            The job options for every input.
        out : Path
            The batch folder, which the workers write artifacts into at this path.
        skip : frozenset
            SHA-256 (hex) of contents already in the table: those inputs yield a skip.

        Yields
        ------
        dict
            One result per path, in the order they complete.
        """
        from dask.distributed import as_completed

        skip_future = self.client.scatter([skip], broadcast=True)[0]  # one object, not one per hash
        todo = deque(paths)
        window = 4 * self.workers

        def submit():
            path = todo.popleft()
            return self.client.submit(process, path, options, str(out), skip_future, pure=False), path

        futures = dict(submit() for _ in range(min(window, len(todo))))
        queue = as_completed(list(futures))
        for future in queue:
            path = futures.pop(future)
            try:
                result = future.result()
            except Exception:  # noqa: BLE001 - KilledWorker after Dask's own retries, or a lost worker
                result = _died(path)
            yield result
            if todo:
                new, p = submit()
                futures[new] = p
                queue.add(new)

    def close(self) -> None:
        """Close the client and the local cluster, if any; closing is best effort (its errors are ignored)."""
        for obj in (getattr(self, "client", None), self.cluster):
            if obj is not None:
                try:
                    obj.close()
                except Exception:  # noqa: BLE001 - closing is best effort
                    pass


def _close_http(dask_worker=None, dask_scheduler=None) -> None:
    """Close the HTTP listener of a local cluster's worker or scheduler (run there by Dask, on its event loop)."""
    (dask_worker or dask_scheduler).http_server.stop()


def _temporary_security():
    """Mutual-TLS credentials for one local cluster, in memory only (:meth:`distributed.security.Security.temporary`).
    """
    from distributed.security import Security

    try:
        return Security.temporary()
    except ImportError:
        raise UsageError("--dask-local needs the optional 'cryptography' package (the cluster's TLS credentials): "
                         "pip install 'lightprobe[batch]'") from None


def _need_bokeh() -> None:
    """Dask's dashboard needs bokeh, which no extra installs (only ``--dashboard`` uses it); without it Dask only logs
    a warning and serves nothing."""
    from importlib.util import find_spec

    if find_spec("bokeh") is None:
        raise UsageError("--dashboard needs the 'bokeh' package (Dask's dashboard): pip install 'bokeh>=3.1'")


def _handshake(address: str, timeout: float, connection_args: dict | None = None) -> None:
    """Open a Dask connection to ``address`` and exchange the handshake, all within ``timeout`` seconds, then close it.

    ``connection_args`` are the client's TLS settings (:meth:`distributed.security.Security.get_connection_args`).
    Anything else at that address — a server that accepts and says nothing, one that answers HTTP, a closed port —
    is an :class:`OSError` (a :class:`TimeoutError` past the deadline), never a wait without end or a traceback."""
    import asyncio

    from distributed.comm import connect

    async def exchange():
        comm = await connect(address, timeout=timeout, **(connection_args or {}))
        await comm.close()

    try:
        asyncio.run(asyncio.wait_for(exchange(), timeout))
    except asyncio.TimeoutError as e:  # the builtin TimeoutError since Python 3.11
        raise TimeoutError(str(e) or "no Dask handshake: nothing answered, or not Dask") from None
    except (OSError, ValueError):
        raise
    except Exception as e:  # noqa: BLE001 - a peer that is not Dask makes its protocol fail in many ways
        raise OSError(f"not a Dask scheduler ({type(e).__name__})") from None


# ---- the driver -----------------------------------------------------------------------------------------------------
def check_out(out: Path, options: JobOptions, resume: bool, force: bool) -> None:
    """Refuse an unusable ``--out`` before any work.

    Not a folder, not writable, a batch there without ``--resume``, or ``--resume`` on a batch of another lightprobe
    version (unless ``force``) or other options. A folder is a batch folder only by its manifest (``batch.json`` of
    format ``lightprobe.batch``): one without it must be empty, whatever it holds (``parts/`` or ``maps/`` included).

    Parameters
    ----------
    out : Path
        The batch folder, existing or to be made.
    options : JobOptions
        The options of this run, compared with those of a batch already there.
    resume : bool
        Continue the batch already in ``out``.
    force : bool
        Resume even a batch written by another lightprobe version, batch format or schema version.

    Raises
    ------
    UsageError
        ``out`` cannot be used, with what to do instead.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file, not a folder")
    existing = read_manifest(out) if out.is_dir() else None
    wanted = manifest(options.as_dict())
    if existing is not None and not resume:
        raise UsageError(f"{out} holds a batch already: --resume to continue it, or give another --out")
    if existing is None and out.is_dir() and any(out.iterdir()):
        raise UsageError(f"{out} is not empty and holds no batch: give a new or empty folder")
    if existing is not None:
        for key in ("version", "schema_version", "lightprobe"):
            if existing.get(key) != wanted[key] and not force:
                raise UsageError(f"{out} was written by lightprobe {existing.get('lightprobe')} (batch format "
                                 f"{existing.get('version')}, schema {existing.get('schema_version')}); this is "
                                 f"lightprobe {wanted['lightprobe']}: --force to resume it anyway")
        if existing.get("options") != wanted["options"]:
            raise UsageError(f"{out} was made with other options ({existing.get('options')}): resume it with those")
    nearest = out
    while not nearest.exists() and nearest != nearest.parent:
        nearest = nearest.parent
    if not nearest.is_dir() or not os.access(nearest, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write into --out {out}: {nearest} is not a writable folder")


def _sweep(out: Path) -> None:
    """Remove what a killed driver left half-written: consolidated tables being written (``.NAME.tmp-PID`` of a
    process no longer alive). Parts and artifacts sweep their own folders."""
    from ..util.files import process_alive

    for stale in out.glob(".*.parquet.tmp-*"):
        pid = stale.name.rsplit("-", 1)[-1]
        if not pid.isdigit() or not process_alive(int(pid)):
            stale.unlink(missing_ok=True)


# What a worker writes in an artifact folder maps/<sha256[:2]>/<sha256>/ and may leave when killed: a radiance-map
# folder being written or set aside (write_radiance_set), and the temporary files of atomic writes.
_ARTIFACT_FOLDER = re.compile(r"[0-9a-f]{64}")
_STALE_RADIANCE = re.compile(r"\.radiance\.(?:tmp|old)-(\d+)")


def _sweep_artifacts(out: Path) -> None:
    """Remove the temporary files of workers killed mid-write (their artifact was redone and renamed into place
    by another worker, or will be by the next run). Only the batch's own: in artifact folders
    ``maps/<sha256[:2]>/<sha256>/``, names the batch's writers give, of processes no longer alive; anything else
    under ``maps/`` is left alone."""
    import shutil

    from ..util.files import process_alive, sweep_stale_temporaries

    for folder in _artifact_folders(out / "maps"):
        for entry in folder.iterdir():
            match = _STALE_RADIANCE.fullmatch(entry.name)
            if match and entry.is_dir() and not entry.is_symlink() and not process_alive(int(match.group(1))):
                shutil.rmtree(entry, ignore_errors=True)
        sweep_stale_temporaries(folder)


def _artifact_folders(maps: Path) -> list[Path]:
    """The folders ``maps``/<xx>/<sha256> the batch makes (xx the hash's first two hex digits), none through a
    symlink."""
    found = []
    if not maps.is_dir() or maps.is_symlink():
        return found
    for prefix in maps.iterdir():
        if re.fullmatch(r"[0-9a-f]{2}", prefix.name) and prefix.is_dir() and not prefix.is_symlink():
            found += [f for f in prefix.iterdir() if _ARTIFACT_FOLDER.fullmatch(f.name) and
                      f.name.startswith(prefix.name) and f.is_dir() and not f.is_symlink()]
    return found


class _CommittedRows:
    """The rows committed before this run, by content: a copy for another path with the same bytes (every input path
    has its row). Read from the parts on first use."""

    def __init__(self, parts: Parts):
        self.parts, self.table, self.index = parts, None, {}

    def row_for(self, result: dict) -> dict:
        if self.table is None:
            self.table = self.parts.read("rows")
            for i, digest in enumerate(self.table.column("sha256").to_pylist()):
                self.index.setdefault(digest, i)
        row = self.table.slice(self.index[result["sha256"]], 1).to_pylist()[0]
        return {**row, "path": result["path"], "size": result["size"], "worker": result["worker"], "seconds": 0.0}


def run_batch(inputs: list[str], out: Path, options: JobOptions, executor, resume: bool = False,
              force: bool = False, chunk_rows: int = CHUNK_ROWS, chunk_seconds: float = CHUNK_SECONDS,
              progress=None) -> Summary:
    """Process ``inputs`` into ``out`` with ``executor``; returns the summary.

    The executor is a :class:`LocalPool` or :class:`DaskPool`. ``progress(summary)`` is called after every result.
    Results are committed as parts every ``chunk_rows`` results or ``chunk_seconds``, whichever comes first, and once
    more at the end; then ``results.parquet`` and ``errors.parquet`` are consolidated from every part.

    Parameters
    ----------
    inputs : list of str
        The input paths (:func:`lightprobe.batch.inputs.expand_inputs`); those already recorded in ``out`` are not
        sent again.
    out : Path
        The batch folder, made if needed; its manifest is written with this run's versions.
    options : JobOptions
        The job options for every input.
    executor : LocalPool or DaskPool
        Runs the tasks; not closed here.
    resume : bool
        Continue the batch already in ``out``. Default False.
    force : bool
        With ``resume``, accept a batch of another lightprobe version. Default False.
    chunk_rows : int
        Commit once this many rows and errors wait. Default :data:`CHUNK_ROWS` (64).
    chunk_seconds : float
        Commit, as a result arrives, once this many seconds have passed since the last commit. Default
        :data:`CHUNK_SECONDS` (5).
    progress : callable or None
        Called with the :class:`Summary` after every result. Default None.

    Returns
    -------
    Summary
        The run's counts, seconds and peak memory, with the rows and errors of the consolidated tables.

    Raises
    ------
    UsageError
        ``out`` cannot be used (:func:`check_out`) or made, or a part in it is damaged.
    """
    out = Path(out)
    check_out(out, options, resume, force)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"cannot write into --out {out}: {e.strerror or e}") from None
    _sweep(out)
    write_manifest(out, manifest(options.as_dict()))  # the options are the folder's (check_out); versions now ours
    parts = Parts(out, options.order if "sh" in options.jobs else None)
    done_paths, done_hashes = done_keys(parts)
    committed = _CommittedRows(parts)
    todo = [p for p in inputs if p not in done_paths]
    summary = Summary(total=len(inputs), already=len(inputs) - len(todo), workers=executor.workers,
                      executor=executor.name)
    t0 = time.perf_counter()
    rows, errors, last_commit = [], [], time.perf_counter()

    def commit():
        nonlocal rows, errors, last_commit
        parts.commit("rows", rows)
        parts.commit("errors", errors)
        rows, errors, last_commit = [], [], time.perf_counter()

    for result in executor.results(todo, options, out, frozenset(done_hashes)):
        kind = result.pop("kind")
        if kind == "row":
            rows.append(result)
            summary.done += 1
            summary.peak_rss = max(summary.peak_rss, result.get("peak_rss") or 0)
        elif kind == "error":
            from .. import __version__

            errors.append({**result, "lightprobe_version": __version__})
            summary.failed += 1
        else:  # the same bytes as a committed row: that row, for this path
            rows.append(committed.row_for(result))
            summary.skipped += 1
        summary.seconds = time.perf_counter() - t0
        if len(rows) + len(errors) >= chunk_rows or time.perf_counter() - last_commit >= chunk_seconds:
            commit()
        if progress is not None:
            progress(summary)
    commit()
    _sweep_artifacts(out)
    summary.seconds = time.perf_counter() - t0
    summary.rows, summary.errors = consolidate(out, parts)
    return summary
