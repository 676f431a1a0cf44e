"""Worker processes that grade one item at a time: a worker that dies costs only its item.

:class:`concurrent.futures.ProcessPoolExecutor` turns the death of one worker into a
broken pool (every pending item lost) and leaves Ctrl-C to its own threads. Here each
worker is a forked process joined to the parent by a pipe: the parent hands it the index
of one item at a time (the items themselves were inherited at the fork), a worker that
dies is noticed by its sentinel and replaced, and on Ctrl-C every worker is told to stop
(SIGTERM: it ends its kernels and exits) and killed if it has not within a second.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from collections import deque
from multiprocessing.connection import wait

#: Seconds a worker gets to end its kernels after SIGTERM before it is killed.
STOP_GRACE = 1.0


def _serve(conn, items, work, start, stop) -> None:
    """A worker's life: set up, then grade the items the parent names until told to stop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle

    def terminate(signum, frame):
        stop()
        os._exit(1)

    signal.signal(signal.SIGTERM, terminate)
    start()
    try:
        while True:
            index = conn.recv()
            if index is None:
                break
            conn.send((index, work(items[index])))
    finally:
        stop()


class _Worker:
    def __init__(self, context, items, work, start, stop):
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, items, work, start, stop), daemon=True)
        self.process.start()
        child.close()
        self.index = None  # the item it is grading


class WorkerPool:
    """``size`` forked workers running ``work(item)``.

    Parameters
    ----------
    size : int
        Workers at once.
    work : callable
        ``work(item)`` in a worker; its result must pickle.
    start, stop : callable
        Run in each worker when it starts and when it stops (also on SIGTERM).
    """

    def __init__(self, size: int, work, start, stop):
        self.size, self.work, self.start, self.stop = size, work, start, stop
        self._context = multiprocessing.get_context("fork")  # the sealed process's modules, inherited
        self._workers: list[_Worker] = []

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if kind is None:
            self.close()
            return False
        # a second Ctrl-C must not cut the ending of the kernels short
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            self.close(now=True)
        finally:
            signal.signal(signal.SIGINT, previous)
        return False

    def map(self, items: list, died):
        """Yield ``(index, result)`` as each item is done, in the order they finish.

        ``died(item, why)`` gives the result of an item whose worker died grading it.
        """
        pending = deque(range(len(items)))
        left = len(items)
        while left:
            while pending and len([w for w in self._workers if w.index is not None]) < self.size:
                worker = next((w for w in self._workers if w.index is None), None)
                if worker is None:
                    worker = _Worker(self._context, items, self.work, self.start, self.stop)
                    self._workers.append(worker)
                worker.index = pending.popleft()
                worker.conn.send(worker.index)
            busy = [w for w in self._workers if w.index is not None]
            ready = set(wait([w.conn for w in busy] + [w.process.sentinel for w in busy]))
            for worker in busy:
                if worker.conn in ready or worker.process.sentinel in ready:
                    index, result = self._collect(worker, items, died)
                    left -= 1
                    yield index, result

    def _collect(self, worker: _Worker, items, died):
        index = worker.index
        worker.index = None
        try:
            if worker.conn.poll():
                got, result = worker.conn.recv()
                if got == index:
                    return index, result
        except (EOFError, OSError):
            pass
        worker.process.join(STOP_GRACE)
        code = worker.process.exitcode
        why = f"killed by signal {-code}" if code is not None and code < 0 else f"exit status {code}"
        self._workers.remove(worker)
        worker.conn.close()
        return index, died(items[index], why)

    def close(self, now: bool = False) -> None:
        """Stop every worker: after its item (``now`` False) or at once (SIGTERM, then SIGKILL)."""
        for worker in self._workers:
            try:
                if now:
                    worker.process.terminate()
                else:
                    worker.conn.send(None)
            except (OSError, ValueError):  # already gone
                pass
        deadline = time.monotonic() + STOP_GRACE
        for worker in self._workers:
            worker.process.join(max(deadline - time.monotonic(), 0) if now else None)
            if worker.process.is_alive():
                worker.process.kill()
                worker.process.join()
            worker.conn.close()
        self._workers = []
