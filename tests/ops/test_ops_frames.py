"""The answer pipe's framing: what a worker writes with
:func:`planner_api.pool.process.send_frame` comes out of
:meth:`planner_api.pool.handle.Worker.take` message by message, whatever the chunks the
event loop happens to read (a large answer arrives over many reads of at most a pipe's
64 KiB; several small ones can arrive in one)."""

from __future__ import annotations

import mmap
import os
import pickle
import select
import threading
from multiprocessing.connection import Connection

import numpy as np

from planner_api.pool.handle import Worker
from planner_api.pool.process import resident_bytes, send_frame


def _worker() -> Worker:
    return Worker(process=None, jobs=None, answers=None)  # type: ignore[arg-type]


def test_frames_are_cut_out_of_any_chunking():
    rng = np.random.default_rng(3)
    small = [("ok", b"x" * int(n)) for n in rng.integers(0, 300, 40)]
    large = [*small, ("ok", bytes(range(256)) * 1200), ("rss", 123), ("error", KeyError("e"))]
    for messages, most in ((small, 9), (large, 70_000)):  # bytes per read: 1.., 1..
        stream = b"".join(
            len(d).to_bytes(8, "big") + d for d in (pickle.dumps(m) for m in messages)
        )  # the frame format, written out independently of send_frame
        for _ in range(10):
            worker, got, i = _worker(), [], 0
            while i < len(stream):
                n = int(rng.integers(1, most))
                got += worker.take(stream[i : i + n])
                i += n
            assert [pickle.loads(m)[:2] for m in got[: len(small)]] == small
            assert [pickle.loads(m)[0] for m in got] == [m[0] for m in messages]
            assert not worker.inbox
    assert pickle.loads(got[-3]) == large[-3]


def test_send_frame_writes_what_take_reads_through_a_real_pipe():
    """A 5 MB answer and small ones through an OS pipe, read as the event loop reads it
    (non-blocking, what is there): the same messages, in order."""
    read_fd, write_fd = os.pipe()
    answers = [("ok", os.urandom(5 * 2**20)), ("ok", b"small"), ("rss", 7)]

    def write() -> None:
        for m in answers:
            send_frame(write_fd, pickle.dumps(m))
        os.close(write_fd)

    writer = threading.Thread(target=write)
    writer.start()
    worker, got = _worker(), []
    reader = Connection(read_fd, writable=False)
    while chunk := os.read(reader.fileno(), 1 << 20):
        got += worker.take(chunk)
    writer.join()
    reader.close()
    assert [pickle.loads(m) for m in got] == answers


def test_resident_bytes_reads_fresh_memory_each_time():
    """The worker's memory after a job (kept open ``/proc/self/statm``, read again at offset
    0 each time): it follows memory taken and given back, and agrees with ``VmRSS`` of
    ``/proc/self/status``, the kernel's other account of the same number."""

    def vm_rss() -> int:
        with open("/proc/self/status") as f:
            line = next(x for x in f if x.startswith("VmRSS:"))
        return int(line.split()[1]) * 1024

    before = resident_bytes()
    assert before is not None and abs(before - vm_rss()) < 4 * 2**20
    # 64 MiB of new pages, mapped and touched here, not from malloc: a long-lived process's
    # allocator may hand out free memory that is resident already (seen once, pinned to a core)
    block = mmap.mmap(-1, 64 * 2**20)
    for page in range(0, len(block), mmap.PAGESIZE):
        block[page] = 1
    grown = resident_bytes()
    assert grown is not None and grown - before > 48 * 2**20
    assert abs(grown - vm_rss()) < 4 * 2**20
    block.close()  # unmapped: given back at once
    assert resident_bytes() < grown - 48 * 2**20  # type: ignore[operator]


def test_resident_bytes_survives_a_fork_and_a_closed_descriptor():
    """A forked child reads its own memory, not its parent's (the descriptor it inherited
    names the parent's file), and a descriptor closed under the reader is opened again."""
    from planner_api.pool import process

    assert resident_bytes() is not None
    inherited = process._STATM[1]  # type: ignore[index]
    read_r, read_w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: syscalls only, then out
        try:
            resident_bytes()
            fd = process._STATM[1]  # type: ignore[index]
            own = os.readlink(f"/proc/self/fd/{fd}") == f"/proc/{os.getpid()}/statm"
            try:  # the parent's descriptor is closed (or its number reused by the new one)
                closed = fd == inherited or not os.fstat(inherited)
            except OSError:
                closed = True
            os.write(read_w, b"1" if own and closed else b"0")
        finally:
            os._exit(0)
    os.close(read_w)
    ready, _, _ = select.select([read_r], [], [], 60.0)
    answer = os.read(read_r, 1) if ready else b"timeout"
    os.waitpid(pid, 0)
    os.close(read_r)
    assert answer == b"1"
    os.close(process._STATM[1])  # type: ignore[index]
    assert resident_bytes() is not None
