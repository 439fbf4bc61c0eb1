"""A frame goes to the video encoder whole: a stop signal that lands while it is being written
takes effect after the write (scenarios/encoder_pipe.py). Without that, a Ctrl-C left ffmpeg a
truncated frame, which it reported on the terminal in six lines beside the command's one."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Generator

import pytest

from lanewarden.scenarios.encoder_pipe import send_whole


@pytest.fixture(autouse=True)
def ctrl_c_raises() -> Generator[None, None, None]:
    """Ctrl-C raises KeyboardInterrupt during each test, as in a command started from a
    terminal, however pytest was started: one started in the background (`cmd &` in a script,
    as a CI runner may) inherits SIGINT ignored and Python keeps it ignored (tests/processes.py),
    and then the deferred Ctrl-C, sent again after the frame, was ignored too: the tests failed
    3 of 3 so started, and passed from a terminal."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


def encoder(written: list[str]) -> Generator[None, str, None]:
    """A stand-in for imageio-ffmpeg's writer whose frame write is interrupted half way."""
    while True:
        frame = yield
        written.append(f"{frame}: first half")
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C in the middle of the pipe write
        written.append(f"{frame}: second half")


def interrupted_frame() -> list[str]:
    """What the stand-in wrote of one frame sent through `send_whole` with a Ctrl-C half way
    (the KeyboardInterrupt must come, and after the send)."""
    written: list[str] = []
    writer = encoder(written)
    writer.send(None)
    with pytest.raises(KeyboardInterrupt):
        send_whole(writer, "frame 1")
    return written


def test_a_ctrl_c_during_a_frame_takes_effect_after_it() -> None:
    assert interrupted_frame() == ["frame 1: first half", "frame 1: second half"]


def test_the_handlers_are_restored_after_the_frame() -> None:
    deferred = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    before = [signal.getsignal(s) for s in deferred]
    interrupted_frame()
    assert [signal.getsignal(s) for s in deferred] == before


def test_a_ctrl_c_during_a_frame_takes_effect_after_it_with_another_thread_running() -> None:
    """A process-directed signal goes to any thread that does not block it (a progress bar's
    monitor thread, pytest-xdist's own): the frame is still written whole."""
    stop = threading.Event()
    other = threading.Thread(target=stop.wait, daemon=True)
    other.start()
    try:
        assert interrupted_frame() == ["frame 1: first half", "frame 1: second half"]
    finally:
        stop.set()
        other.join()
