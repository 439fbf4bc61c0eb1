"""The control side's watch on the dead-man: when is quiet silence? (receive_or_silence, with a
scripted queue and clock: the races it guards against cannot be timed in a test)."""

from __future__ import annotations

import pytest

from lanewarden.actuation.deadman_link import receive_or_silence

REPORT = b"WIRE 3 0.0 0.0"


class Socket:
    """A scripted non-blocking queue and clock; `arrive` messages come in when the clock is read
    (as if they arrived while the caller was descheduled or frozen just before)."""

    def __init__(self, times: list[float], queued: list[bytes] | None = None,
                 arrive: dict[int, bytes] | None = None) -> None:
        self.times = times
        self.queue = list(queued or [])
        self.arrive = arrive or {}
        self.clock_reads = 0
        self.waits: list[float | None] = []

    def recv(self) -> bytes:
        if not self.queue:
            raise BlockingIOError
        return self.queue.pop(0)

    def clock(self) -> float:
        if self.clock_reads in self.arrive:
            self.queue.append(self.arrive[self.clock_reads])
        now = self.times[min(self.clock_reads, len(self.times) - 1)]
        self.clock_reads += 1
        return now

    def wait(self, timeout_s: float | None) -> None:
        self.waits.append(timeout_s)

    def receive(self, deadline_s: float | None) -> bytes | None:
        return receive_or_silence(self.recv, deadline_s, self.clock, self.wait)


def test_a_queued_report_is_returned_even_long_after_the_deadline() -> None:
    # the caller itself was frozen: its backlog is not silence
    sock = Socket(times=[99.0], queued=[REPORT])
    assert sock.receive(10.2) == REPORT
    assert sock.clock_reads == 0


def test_a_report_that_arrived_while_the_caller_was_frozen_before_its_clock_reading() -> None:
    # looked (empty), frozen past the deadline while the dead-man kept reporting, read the clock
    sock = Socket(times=[10.5], arrive={0: REPORT})
    assert sock.receive(10.2) == REPORT


def test_an_empty_queue_seen_after_the_deadline_is_silence() -> None:
    sock = Socket(times=[10.05, 10.21])
    assert sock.receive(10.2) is None
    assert sock.waits == [pytest.approx(0.15)]  # it waited for the rest of the time once


def test_without_a_deadline_it_waits_as_long_as_it_takes() -> None:
    sock = Socket(times=[0.0])

    def wait(timeout_s: float | None) -> None:
        sock.waits.append(timeout_s)
        if len(sock.waits) == 3:
            sock.queue.append(REPORT)

    assert receive_or_silence(sock.recv, None, sock.clock, wait) == REPORT
    assert sock.waits == [None, None, None]


def test_end_of_stream_is_an_empty_message() -> None:
    def reset() -> bytes:
        raise ConnectionResetError

    assert receive_or_silence(reset, 10.2, lambda: 0.0, lambda t: None) == b""
