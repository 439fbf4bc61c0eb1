"""The dead-man survives the terminal and is itself watched.

Its own session (terminal signals never reach it), its raised priority, a stop held while the
control process suspends itself, the control side writing the stop itself when the dead-man
freezes or dies, and `base drive` under Ctrl-Z, Ctrl-\\ and a base that goes silent. Real
processes over the pty stand-in; no sleeps: every wait is on a condition with a generous deadline.
Latencies are measured in benchmarks/deadman_latency.py, not asserted here.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.errors import ActuationError, DeadmanTrippedError, KobukiLinkError
from lanewarden.actuation.kobuki_base import KobukiBase
from lanewarden.actuation.realtime import OOM_NEVER, raise_priority, spare_from_oom
from lanewarden.cli import main
from tests.actuation.kobuki_standin import STOP_PACKET, KobukiStandIn
from tests.actuation.processes import (
    DEADLINE_S,
    assert_stop_held_since,
    deadman_of,
    is_motion,
    motion_after_the_stop,
    process_state,
    start_lanewarden,
    stderr_lines,
    wait_for_more_packets,
    wait_for_stop_after,
)

MOVE = VelocityCommand(0.2, 0.0)


@pytest.fixture
def kobuki(standin: KobukiStandIn) -> Iterator[KobukiBase]:
    with KobukiBase.open(standin.port) as base:
        yield base


def _drive_until(base: KobukiBase, done: Callable[[KobukiBase], bool]) -> bool:
    """A control loop's heartbeat: send MOVE at every feedback packet until `done` holds."""
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline:
        if done(base):
            return True
        try:
            base.send(MOVE, time.monotonic())
        except ActuationError:
            pass
        seen = base.packets_received
        base.wait_for(lambda b, seen=seen: b.packets_received > seen or done(b), 0.05)
    return done(base)


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


# ---- the dead-man's own session and priority ----------------------------------------------------
def test_the_deadman_runs_in_a_session_of_its_own(kobuki: KobukiBase) -> None:
    pid = kobuki.deadman_pid
    assert os.getsid(pid) == pid, "the dead-man must lead its own session"
    assert os.getpgid(pid) != os.getpgrp(), "terminal job-control signals would reach it"


def test_the_deadman_raises_its_priority_or_says_it_could_not(kobuki: KobukiBase) -> None:
    health = kobuki.link_health(time.monotonic())
    pid = kobuki.deadman_pid
    if health.deadman_priority_raised:
        raised = (os.sched_getscheduler(pid) == os.SCHED_FIFO
                  or os.getpriority(os.PRIO_PROCESS, pid) < 0)
        assert raised, health.deadman_priority
    else:
        assert "could not raise it" in health.deadman_priority


def test_the_deadman_asks_the_oom_killer_to_spare_it_where_permitted(
        kobuki: KobukiBase, tmp_path: Path) -> None:
    """An attacker's review: killing the control process and the dead-man at once leaves the base
    driving its last command. Running out of memory should take the control process (whose
    death the dead-man answers with a stop), never the dead-man: it asks for oom_score_adj -1000,
    which root may set; elsewhere the value stays and the kernel picks by size."""
    def oom_score_adj(pid: str) -> int:
        with open(f"/proc/{pid}/oom_score_adj", encoding="ascii") as adjust:
            return int(adjust.read())

    # (root without CAP_SYS_RESOURCE, as in some containers, may not lower it either)
    permitted = subprocess.run(
        [sys.executable, "-c", "from lanewarden.actuation.realtime import spare_from_oom; "
         "print(spare_from_oom()[0])"], capture_output=True, text=True, check=True).stdout
    inherited = oom_score_adj("self")
    assert oom_score_adj(str(kobuki.deadman_pid)) == (
        OOM_NEVER if permitted.strip() == "True" else inherited)
    assert spare_from_oom(str(tmp_path / "absent" / "oom_score_adj")) == (
        False, "oom_score_adj unchanged (No such file or directory)")
    spared, said = spare_from_oom(str(tmp_path / "oom_score_adj"))  # (a file that takes it)
    assert spared and said == "oom_score_adj -1000"
    assert (tmp_path / "oom_score_adj").read_text(encoding="ascii") == "-1000"


# ---- the control process suspends itself on purpose --------------------------------------------
def test_hold_stopped_puts_a_stop_on_the_wire_and_holds_it_without_heartbeats(
        standin: KobukiStandIn, kobuki: KobukiBase) -> None:
    kobuki.send(MOVE, time.monotonic())
    assert standin.wait_for(lambda pkts: any(map(is_motion, pkts)), DEADLINE_S)
    held_at = time.monotonic()
    assert kobuki.hold_stopped(time.monotonic()) is True  # the dead-man confirmed the stop
    assert standin.wait_for(lambda pkts: any(
        p.arrival_s >= held_at and p.packet == STOP_PACKET for p in pkts), DEADLINE_S)
    wait_for_more_packets(standin, 20)  # 0.4 s of silence from us: longer than the timeout
    assert kobuki.deadman_mode is DeadmanMode.DISARMED  # held, not tripped
    with pytest.raises(DeadmanTrippedError, match="held stopped"):
        kobuki.send(MOVE, time.monotonic())
    wait_for_more_packets(standin, 5)
    assert motion_after_the_stop(standin, held_at) == []
    kobuki.rearm(time.monotonic())
    assert kobuki.wait_for(lambda b: b.deadman_mode is DeadmanMode.ARMED, DEADLINE_S)
    mark = len(standin.snapshot())
    kobuki.send(MOVE, time.monotonic())
    assert standin.wait_for(lambda pkts: any(map(is_motion, pkts[mark:])), DEADLINE_S)
    kobuki.send(STOP, time.monotonic())


# ---- the dead-man freezes or dies: the control side stops the base itself -----------------------
@pytest.mark.parametrize(("how", "said"), [
    (signal.SIGSTOP, "the dead-man process stopped answering (no report for 0.2 s): killed it"),
    (signal.SIGKILL, "the dead-man process was killed (SIGKILL)"),
])
def test_a_frozen_or_killed_deadman_is_noticed_and_the_stop_written_directly(
        standin: KobukiStandIn, kobuki: KobukiBase, how: signal.Signals, said: str) -> None:
    kobuki.send(MOVE, time.monotonic())
    assert standin.wait_for(lambda pkts: any(map(is_motion, pkts)), DEADLINE_S)
    signalled_at = time.monotonic()
    os.kill(kobuki.deadman_pid, how)
    assert _drive_until(kobuki, lambda b: b.link_lost is not None)
    lost = kobuki.link_lost or ""
    assert said in lost and standin.port in lost
    assert "a stop was written to the port directly" in lost
    assert_stop_held_since(standin, signalled_at)
    assert _gone(kobuki.deadman_pid)  # killed and reaped
    with pytest.raises(KobukiLinkError, match="dead-man process"):
        kobuki.send(MOVE, time.monotonic())


def test_sigtstp_sent_to_the_deadman_itself_is_ignored(standin: KobukiStandIn,
                                                       kobuki: KobukiBase) -> None:
    os.kill(kobuki.deadman_pid, signal.SIGTSTP)
    mark = len(standin.snapshot())
    assert _drive_until(kobuki, lambda b: len(standin.snapshot()) >= mark + 25)
    assert kobuki.link_lost is None and process_state(kobuki.deadman_pid) != "T"
    assert any(map(is_motion, standin.snapshot()[mark:]))
    kobuki.send(STOP, time.monotonic())


# ---- `base drive` under terminal signals and stale feedback -------------------------------------
@pytest.fixture
def driving(standin: KobukiStandIn) -> Iterator[tuple[subprocess.Popen[str], int]]:
    """`lanewarden base drive` in its own process group, moving; (process, its dead-man's pid)."""
    drive = start_lanewarden("base", "drive", "--port", standin.port, "--linear", "0.1",
                             "--duration", "30")
    try:
        deadman = deadman_of(drive.pid, standin)
        assert standin.wait_for(lambda pkts: any(map(is_motion, pkts)), 3 * DEADLINE_S)
        yield drive, deadman
    finally:
        drive.kill()
        drive.wait()


def test_ctrl_z_to_base_drive_stops_first_and_nothing_moves_after_sigcont(
        standin: KobukiStandIn, driving: tuple[subprocess.Popen[str], int]) -> None:
    drive, _ = driving
    signalled_at = time.monotonic()
    os.killpg(drive.pid, signal.SIGTSTP)  # Ctrl-Z: the whole foreground job
    wait_for_stop_after(standin, signalled_at)
    # re-checked at every packet: the dead-man keeps writing stop while drive is stopped
    assert standin.wait_for(lambda _: process_state(drive.pid) == "T", DEADLINE_S)
    wait_for_more_packets(standin, 20)
    os.killpg(drive.pid, signal.SIGCONT)
    _, err = drive.communicate(timeout=3 * DEADLINE_S)
    assert drive.returncode == 130
    assert stderr_lines(err) == ["lanewarden: error: interrupted (SIGTSTP): the base was "
                                 "stopped before suspending; the drive does not resume"]
    assert_stop_held_since(standin, signalled_at)


def test_ctrl_backslash_to_base_drive_stops_it(
        standin: KobukiStandIn, driving: tuple[subprocess.Popen[str], int]) -> None:
    drive, deadman = driving
    signalled_at = time.monotonic()
    os.killpg(drive.pid, signal.SIGQUIT)
    _, err = drive.communicate(timeout=3 * DEADLINE_S)
    assert drive.returncode == 130
    assert stderr_lines(err) == ["lanewarden: error: interrupted (SIGQUIT)"]
    assert_stop_held_since(standin, signalled_at)
    assert standin.wait_for(lambda _: _gone(deadman), DEADLINE_S)


@pytest.mark.parametrize("how", [signal.SIGSTOP, signal.SIGKILL])
def test_base_drive_halts_when_its_deadman_freezes_or_dies(
        standin: KobukiStandIn, driving: tuple[subprocess.Popen[str], int],
        how: signal.Signals) -> None:
    drive, deadman = driving
    signalled_at = time.monotonic()
    os.kill(deadman, how)
    _, err = drive.communicate(timeout=3 * DEADLINE_S)
    assert drive.returncode == 1
    lines = stderr_lines(err)
    assert len(lines) == 1 and lines[0].startswith("lanewarden: error: "), err
    assert standin.port in lines[0] and ("dead-man" in lines[0] or "no feedback" in lines[0])
    assert_stop_held_since(standin, signalled_at)


def test_base_drive_stops_when_the_base_falls_silent(standin: KobukiStandIn,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    def fall_silent_once_moving() -> None:
        if standin.wait_for(lambda pkts: any(map(is_motion, pkts)), 3 * DEADLINE_S):
            standin.stream = False  # the base stops streaming; the dead-man is fine

    threading.Thread(target=fall_silent_once_moving, daemon=True).start()
    assert main(["base", "drive", "--port", standin.port, "--linear", "0.1",
                 "--duration", "20"]) == 1
    lines = stderr_lines(capsys.readouterr().err)
    assert len(lines) == 1
    err = lines[0]
    assert standin.port in err
    # the gate's own watchdog or the dead-man's feedback timeout, whichever was first (both 0.2 s)
    assert ("BASE_LINK_LOST: link lost (no feedback, or a command not written)" in err
            or "DEADMAN_LATCHED: the dead-man latched a stop on its own, held until a resume "
               "(no feedback from the base for " in err), err
    assert standin.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)


def test_the_deadman_says_when_it_could_not_raise_its_priority(
        monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    monkeypatch.setattr(os, "setpriority", refuse)
    assert raise_priority() == (False, "normal priority: could not raise it (SCHED_FIFO: [Errno 1] "
                                       "Operation not permitted; nice -10: [Errno 1] Operation "
                                       "not permitted)")
