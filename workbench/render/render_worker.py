"""City renders in a separate, long-lived process, so nothing Mitsuba does (loading a scene, the
label kernel, a render; several of them hold the GIL) can stall the process that asks for them.

    worker = RenderWorker(threads=1)
    render = run_job(worker.job(inputs, seeds))      # a long job, like city_scene_job
    worker.close()

The worker process keeps one render.city_frame.CitySceneSession, so a frame that only moves the
camera reuses the loaded scene. Requests are served one at a time; `job` yields the worker's
progress (without preview images: they would cost a copy each) and returns its CityRender.
Cancelling (the job's cancel token) asks the worker to stop at its next chunk; if it does not
answer within CANCEL_TIMEOUT_S the process is ended and the next job starts a new one. A worker
that dies (a crash, a kill) fails its job with a StageError naming the exit code.

A render's arrays (a 640×480 frame: 19 MB of radiance and 5 MB of labels) come back through a
shared-memory segment that the worker keeps (and grows when a frame needs more), not through the
pipe: the pipe moved 19 MB in 60–140 ms here, in 64 kB steps that each wake both processes, and a
new segment per frame 40–65 ms (its pages fault in on both sides), while copying 19 MB between
mapped pages takes ~3 ms. Only the pickled remainder goes through the pipe (pickle protocol 5 with
out-of-band buffers); what is unpickled is the worker's own result, as through the pipe before.
"""
from __future__ import annotations

import multiprocessing
import pickle
import threading
import time
from multiprocessing import shared_memory

from workbench.errors import StageError
from workbench.jobs import JobCancelled, Progress

CANCEL_TIMEOUT_S = 10.0
POLL_S = 0.05
SHARED_MIN_BYTES = 1 << 20
"""Results whose arrays hold at least this many bytes come back through shared memory."""
SEGMENT_HEADROOM = 1.25
"""A new segment is this much larger than the result that needs it (room for a larger frame)."""


class _Outbox:
    """The worker's side of results in shared memory: one segment, kept between results, which
    the asking side has read before it asks again (one request at a time)."""

    def __init__(self, min_bytes: int):
        self.min_bytes = min_bytes
        self.segment = None

    def message(self, result) -> tuple:
        """The message that answers a request with `result`."""
        buffers = []
        payload = pickle.dumps(result, protocol=5, buffer_callback=buffers.append)
        views = [buffer.raw() for buffer in buffers]
        total = sum(view.nbytes for view in views)
        if not views or total < self.min_bytes:
            return ("result", result)
        if self.segment is None or self.segment.size < total:
            self.close()
            self.segment = shared_memory.SharedMemory(create=True, size=max(1, int(total * SEGMENT_HEADROOM)))
        spans, offset = [], 0
        for view in views:
            self.segment.buf[offset:offset + view.nbytes] = view
            spans.append((offset, view.nbytes))
            offset += view.nbytes
        return ("shared_result", payload, self.segment.name, spans)

    def close(self) -> None:
        if self.segment is not None:
            self.segment.close()
            self.segment.unlink()
            self.segment = None


class _Inbox:
    """The asking side: maps the worker's segment (again when it is replaced) and copies each
    result out of it."""

    def __init__(self):
        self.segment = None

    def result(self, msg: tuple):
        _, payload, name, spans = msg
        if self.segment is None or self.segment.name != name:
            self.close()
            self.segment = shared_memory.SharedMemory(name=name)
        return pickle.loads(payload, buffers=[bytearray(self.segment.buf[offset:offset + size])
                                              for offset, size in spans])

    def close(self, unlink: bool = False) -> None:
        """Unmap the segment; with unlink (the worker was ended before it could) also remove it."""
        if self.segment is None:
            return
        self.segment.close()
        if unlink:
            try:
                self.segment.unlink()
            except FileNotFoundError:
                pass                       # the worker removed it
        self.segment = None


class _PipeCancel:
    """The worker side of cancelling: is_set() looks for a message without waiting. A cancel or
    stop cancels; a new request also cancels the one in progress and is kept (`pending`)."""

    def __init__(self, conn):
        self.conn = conn
        self.cancelled = False
        self.pending = None

    def is_set(self) -> bool:
        while not self.cancelled and self.conn.poll():
            msg = self.conn.recv()
            if msg[0] == "render":
                self.pending = msg
            self.cancelled = True
        return self.cancelled


def serve(conn, threads: int | None, nice: int = 0, shared_min_bytes: int = SHARED_MIN_BYTES) -> None:
    """The worker process: answer ('render', inputs, seeds, quick_look, film_edges_nm) requests until
    ('stop',) or EOF.
    With `nice`, the process (and the render threads it starts later) yields the cores to others.
    Results with at least shared_min_bytes of arrays come back through shared memory."""
    if nice:
        import os
        os.nice(nice)
    from workbench.render.city_frame import CitySceneSession
    from workbench.render.variants import import_mitsuba
    import_mitsuba()                     # load Mitsuba (and its LLVM) before the first request
    if threads:
        import drjit
        drjit.set_thread_count(int(threads))
    session = CitySceneSession()
    outbox = _Outbox(shared_min_bytes)
    try:
        _serve_requests(conn, session, outbox)
    finally:
        outbox.close()


def _serve_requests(conn, session, outbox: _Outbox) -> None:
    pending = None
    while True:
        try:
            msg, pending = (pending, None) if pending is not None else (conn.recv(), None)
        except EOFError:
            return
        if msg[0] == "stop":
            return
        if msg[0] != "render":
            continue                     # a late cancel of a finished request
        _, inputs, seeds, quick_look, film_edges_nm = msg
        cancel = _PipeCancel(conn)
        try:
            job = session.job(inputs, seeds, cancel, quick_look, film_edges_nm)
            while True:
                try:
                    step = next(job)
                except StopIteration as stop:
                    result = stop.value
                    break
                conn.send(("progress", step.done, step.total, step.message))
            conn.send(outbox.message(result))
        except JobCancelled:
            conn.send(("cancelled",))
        except Exception as exc:  # noqa: BLE001 — sent back to the asking process, which raises it
            conn.send(("error", exc))
        pending = cancel.pending


class RenderWorker:
    """The asking side: one worker process (started on first use), one request at a time."""

    def __init__(self, threads: int | None = 1, nice: int = 0, shared_min_bytes: int = SHARED_MIN_BYTES):
        self.threads = threads
        self.nice = nice
        self.shared_min_bytes = shared_min_bytes
        self._inbox = _Inbox()
        self._proc = None
        self._conn = None
        self._lock = threading.Lock()
        self._in_flight = False

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None and self._proc.is_alive() else None

    def _ensure(self) -> None:
        if self._proc is not None and self._proc.is_alive():
            return
        ctx = multiprocessing.get_context("spawn")      # never fork a process that runs Qt or threads
        here, there = ctx.Pipe()
        self._proc = ctx.Process(target=serve, args=(there, self.threads, self.nice, self.shared_min_bytes), name="workbench-render", daemon=True)
        self._proc.start()
        there.close()
        self._conn = here

    def start(self) -> None:
        """Start the process now (its imports take a second or two) instead of at the first job."""
        with self._lock:
            self._ensure()

    def job(self, inputs, seeds, cancel=None, quick_look: bool = False,
            film_edges_nm: tuple[float, ...] | None = None):
        """Render one city frame in the worker (a long job: yields Progress, returns CityRender;
        quick_look, film_edges_nm: see CitySceneSession.job). Closing the job before its end (the
        caller stopped iterating) cancels the worker's render and waits for it to stop, so the
        worker is free for the next job."""
        with self._lock:
            self._ensure()
            conn, proc = self._conn, self._proc
            conn.send(("render", inputs, seeds, bool(quick_look), film_edges_nm))
            self._in_flight = True
            try:
                return (yield from self._answers(conn, proc, seeds, cancel))
            finally:
                if self._in_flight:          # left before the worker answered
                    self._abandon(conn)

    def _abandon(self, conn) -> None:
        """The request in flight is no longer wanted: cancel it and read until the worker has
        answered it (or end the process if it does not within CANCEL_TIMEOUT_S)."""
        self._in_flight = False
        if self._conn is not conn:
            return                                   # the process is gone already
        try:
            conn.send(("cancel",))
            deadline = time.monotonic() + CANCEL_TIMEOUT_S
            while time.monotonic() < deadline:
                if conn.poll(POLL_S) and conn.recv()[0] in ("result", "shared_result", "cancelled", "error"):
                    return
        except (EOFError, OSError):
            pass
        self._end()

    def _answers(self, conn, proc, seeds, cancel):
        """Read the worker's answers to the request in flight: yields Progress, returns the render."""
        asked_at = None
        while True:
            if cancel is not None and cancel.is_set() and asked_at is None:
                conn.send(("cancel",))
                asked_at = time.monotonic()
            if asked_at is not None and time.monotonic() - asked_at > CANCEL_TIMEOUT_S:
                self._in_flight = False
                self._end()
                raise JobCancelled(f"frame {seeds.index}: cancelled (the render worker was ended)")
            try:
                ready = conn.poll(POLL_S)
            except (EOFError, OSError):
                ready = True
            if not ready:
                if not proc.is_alive():
                    self._died(proc)
                continue
            try:
                msg = conn.recv()
            except (EOFError, OSError):
                self._died(proc)
            self._in_flight = msg[0] == "progress"
            if msg[0] == "progress":
                if asked_at is None:
                    yield Progress(msg[1], msg[2], msg[3])
            elif msg[0] in ("result", "shared_result"):
                if asked_at is not None:
                    raise JobCancelled(f"frame {seeds.index}: cancelled")
                return msg[1] if msg[0] == "result" else self._inbox.result(msg)
            elif msg[0] == "cancelled":
                raise JobCancelled(f"frame {seeds.index}: cancelled")
            elif msg[0] == "error":
                raise msg[1]

    def _died(self, proc) -> None:
        self._in_flight = False
        proc.join(1.0)
        code = proc.exitcode
        self._proc, self._conn = None, None
        self._inbox.close(unlink=True)
        raise StageError("scene", f"the render worker process ended (exit code {code}); the next render "
                                  "starts a new one")

    def _end(self) -> None:
        proc = self._proc              # close() runs on another thread than _died(), which clears it
        if proc is not None:
            proc.terminate()
            proc.join(2.0)
            if proc.is_alive():
                proc.kill()
                proc.join(2.0)
        self._proc, self._conn = None, None
        self._inbox.close(unlink=True)

    def close(self) -> None:
        """Stop the worker process at once (a render in flight is abandoned; its job fails)."""
        self._end()
