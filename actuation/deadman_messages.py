"""The messages between the control process (KobukiBase) and the dead-man process.

One message per SOCK_SEQPACKET record, ASCII words separated by spaces, binary as hex:

both ways, first:    `HELLO <protocol> <package version> <package folder>`
control -> dead-man: `ARM <seq> <sent_s>` | `RESUME <seq> <sent_s>` | `DISARM <seq> <sent_s>`
                     | `CMD <seq> <sent_s> <linear_m_s> <angular_rad_s>`
                     | `RAW <hex sub-payloads>` | `CLOSE`
dead-man -> control: `OPEN <low_latency 0|1> <priority_raised 0|1> <priority text>`
                     | `ERROR <text>` | `FB <checksum_errors> <hex payload>`
                     | `MODE <mode> <reason>` | `LOST <text>`
                     | `WIRE <seq> <written_s> <linear_m_s> <angular_rad_s>`

`HELLO` is the handshake, and its layout never changes: each side sends its own first and checks
the other's (`version_mismatch`) before anything else; the dead-man opens the port only after a
matching one, the control process uses the dead-man only after one (`PROTOCOL_VERSION` counts
changes to every other message; bump it with any change here).

`ARM`, `RESUME`, `DISARM` and `CMD` are heartbeats: `seq` counts up with every heartbeat the
control process sends and `sent_s` is its CLOCK_MONOTONIC time at sending (system-wide on Linux,
so the dead-man compares it with its own clock: a heartbeat that sat in the socket while the
sender was frozen is not fresh). `RESUME` is the operator's explicit start or resume: the only
message that clears the dead-man's own hazard latch. `WIRE` reports every command the dead-man
writes to the port, with the newest heartbeat sequence it had accepted (-1: none yet) and its
CLOCK_MONOTONIC time once the write returned: it is the dead-man's own heartbeat towards the
control process.

Decoding is strict (integers are digits, numbers finite decimals): anything else raises
ValueError (the dead-man treats that as a missed heartbeat). Pure: no sockets here.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import lanewarden
from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.deadman_logic import DeadmanMode, Heartbeat
from lanewarden.actuation.kobuki_commands import CommandId

#: The version of every message but HELLO: both sides must speak the same one.
PROTOCOL_VERSION = 2


# ---- both ways ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Hello:
    """Who is speaking: the message protocol, the lanewarden package's version and the folder it
    was imported from (so a dead-man that imported another copy of the code is named)."""

    protocol: int
    package_version: str
    package_folder: str

    @classmethod
    def ours(cls) -> Hello:
        """This process's own HELLO."""
        return cls(PROTOCOL_VERSION, lanewarden.__version__,
                   os.path.dirname(os.path.realpath(lanewarden.__file__)))

    def describe(self) -> str:
        return (f"lanewarden {self.package_version} (dead-man protocol {self.protocol}) from "
                f"{self.package_folder}")


def version_mismatch(ours: Hello, theirs: Hello) -> str | None:
    """Why the two sides cannot work together (protocol or package version differ), or None."""
    if (ours.protocol, ours.package_version) == (theirs.protocol, theirs.package_version):
        return None
    return f"{theirs.describe()}, but this side is {ours.describe()}"


# ---- control -> dead-man ------------------------------------------------------------------------
@dataclass(frozen=True)
class Arm:
    """Explicitly (re-)arm the dead-man: the way out of DISARMED or TRIPPED (not LATCHED)."""

    heartbeat: Heartbeat


@dataclass(frozen=True)
class Resume:
    """The operator's explicit start or resume: arms like ARM, and is the only way out of the
    dead-man's own hazard latch (once the hazard has cleared)."""

    heartbeat: Heartbeat


@dataclass(frozen=True)
class Disarm:
    """Stop at once and stay stopped without needing heartbeats (the control process is about to
    be suspended) until an explicit ARM."""

    heartbeat: Heartbeat


@dataclass(frozen=True)
class Command:
    """The velocity to execute from now on; also a heartbeat."""

    command: VelocityCommand
    heartbeat: Heartbeat


@dataclass(frozen=True)
class RawCommand:
    """Non-motion command sub-payloads (sound, request extra, GPO, gains) to write once."""

    sub_payloads: bytes


@dataclass(frozen=True)
class Close:
    """Stop the base, flush and exit."""


ControlMessage = Hello | Arm | Resume | Disarm | Command | RawCommand | Close


# ---- dead-man -> control ------------------------------------------------------------------------
@dataclass(frozen=True)
class PortOpened:
    low_latency: bool
    priority_raised: bool = False
    priority: str = "normal"


@dataclass(frozen=True)
class OpenFailed:
    message: str


@dataclass(frozen=True)
class FeedbackReceived:
    checksum_errors: int
    payload: bytes


@dataclass(frozen=True)
class ModeChanged:
    mode: DeadmanMode
    reason: str


@dataclass(frozen=True)
class LinkLost:
    message: str


@dataclass(frozen=True)
class OnTheWire:
    """The dead-man wrote `command` to the port (the write returned at `written_s`, its
    CLOCK_MONOTONIC), having accepted heartbeats up to `heartbeat_seq` (-1: none yet)."""

    heartbeat_seq: int
    written_s: float
    command: VelocityCommand


DeadmanMessage = (Hello | PortOpened | OpenFailed | FeedbackReceived | ModeChanged | LinkLost
                  | OnTheWire)

#: SOCK_SEQPACKET receive size: large enough for any message above.
MAX_MESSAGE_BYTES = 4096

_DIGITS = re.compile(r"[0-9]{1,18}")
_SIGNED_DIGITS = re.compile(r"-1|[0-9]{1,18}")
#: A finite decimal as repr(float) writes it; no inf, nan, underscores or spaces.
_DECIMAL = re.compile(r"-?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:e[-+]?[0-9]+)?")


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _sequence(text: str, *, allow_none: bool = False) -> int:
    if not (_SIGNED_DIGITS if allow_none else _DIGITS).fullmatch(text):
        raise ValueError(f"bad sequence number {text[:20]!r}")
    return int(text)


def _number(text: str) -> float:
    value = float(text) if _DECIMAL.fullmatch(text) else math.nan
    if not math.isfinite(value):  # also 1e999, which float() reads as inf
        raise ValueError(f"bad number {text[:30]!r} (expected a finite decimal)")
    return value


def _heartbeat(seq: str, sent_s: str) -> Heartbeat:
    return Heartbeat(_sequence(seq), _number(sent_s))


def check_non_motion(sub_payloads: bytes) -> None:
    """A RAW message must be whole command sub-payloads, none of them Base Control: motion only
    ever reaches the wire through the dead-man's logic."""
    index = 0
    while index < len(sub_payloads):
        if index + 2 > len(sub_payloads):
            raise ValueError("RAW sub-payloads end inside a header")
        if sub_payloads[index] == CommandId.BASE_CONTROL:
            raise ValueError("RAW may not carry base control (motion goes through CMD)")
        index += 2 + sub_payloads[index + 1]
    if index != len(sub_payloads) or not 3 <= len(sub_payloads) <= 255:
        raise ValueError("RAW sub-payload lengths do not add up to a packet payload")


_HEARTBEAT_KINDS: dict[type, str] = {Arm: "ARM", Resume: "RESUME", Disarm: "DISARM"}


def encode_hello(message: Hello) -> bytes:
    return (f"HELLO {message.protocol} {_one_line(message.package_version)} "
            f"{message.package_folder}").encode()


def decode_hello(data: bytes) -> Hello:
    """Parse a HELLO (the one message whose layout never changes); ValueError otherwise."""
    kind, protocol, version, folder = (data.decode("utf-8").split(" ", 3) + ["", "", ""])[:4]
    if kind != "HELLO" or not version or not folder:
        raise ValueError(f"not a HELLO: {data[:60]!r}")
    return Hello(_sequence(protocol), version, folder)


def encode_control(message: ControlMessage) -> bytes:
    if isinstance(message, Hello):
        return encode_hello(message)
    if isinstance(message, Arm | Resume | Disarm):
        kind = _HEARTBEAT_KINDS[type(message)]
        return f"{kind} {message.heartbeat.seq} {message.heartbeat.sent_s!r}".encode()
    if isinstance(message, Command):
        beat, command = message.heartbeat, message.command
        return (f"CMD {beat.seq} {beat.sent_s!r} {command.linear_m_s!r} "
                f"{command.angular_rad_s!r}").encode()
    if isinstance(message, RawCommand):
        return b"RAW " + message.sub_payloads.hex().encode()
    return b"CLOSE"


def decode_control(data: bytes) -> ControlMessage:
    """Parse one control message after the handshake (a HELLO now is malformed); ValueError on
    anything malformed (including NaN speeds)."""
    words = data.decode("ascii").split(" ")
    kind, args = words[0], words[1:]
    if kind == "ARM" and len(args) == 2:
        return Arm(_heartbeat(*args))
    if kind == "RESUME" and len(args) == 2:
        return Resume(_heartbeat(*args))
    if kind == "DISARM" and len(args) == 2:
        return Disarm(_heartbeat(*args))
    if kind == "CLOSE" and not args:
        return Close()
    if kind == "CMD" and len(args) == 4:
        beat = _heartbeat(args[0], args[1])
        return Command(VelocityCommand(_number(args[2]), _number(args[3])), beat)
    if kind == "RAW" and len(args) == 1 and args[0]:
        sub_payloads = bytes.fromhex(args[0])
        check_non_motion(sub_payloads)
        return RawCommand(sub_payloads)
    raise ValueError(f"unknown control message {data[:40]!r}")


def encode_deadman(message: DeadmanMessage) -> bytes:
    if isinstance(message, Hello):
        return encode_hello(message)
    if isinstance(message, PortOpened):
        return (f"OPEN {int(message.low_latency)} {int(message.priority_raised)} "
                f"{_one_line(message.priority)}").encode()
    if isinstance(message, OpenFailed):
        return f"ERROR {_one_line(message.message)}".encode()
    if isinstance(message, FeedbackReceived):
        return f"FB {message.checksum_errors} {message.payload.hex()}".encode()
    if isinstance(message, ModeChanged):
        return f"MODE {message.mode.value} {_one_line(message.reason)}".encode()
    if isinstance(message, OnTheWire):
        command = message.command
        return (f"WIRE {message.heartbeat_seq} {message.written_s!r} {command.linear_m_s!r} "
                f"{command.angular_rad_s!r}").encode()
    return f"LOST {_one_line(message.message)}".encode()


def decode_deadman(data: bytes) -> DeadmanMessage:
    """Parse one dead-man message; ValueError on anything malformed."""
    kind, _, rest = data.decode("utf-8").partition(" ")
    if kind == "HELLO":
        return decode_hello(data)
    if kind == "OPEN":
        low_latency, raised, priority = (rest.split(" ", 2) + ["", ""])[:3]
        if low_latency in ("0", "1") and raised in ("0", "1") and priority:
            return PortOpened(low_latency == "1", raised == "1", priority)
    if kind == "ERROR":
        return OpenFailed(rest)
    if kind == "FB":
        errors, _, payload = rest.partition(" ")
        return FeedbackReceived(_sequence(errors), bytes.fromhex(payload))
    if kind == "MODE":
        mode, _, reason = rest.partition(" ")
        return ModeChanged(DeadmanMode(mode), reason)
    if kind == "LOST":
        return LinkLost(rest)
    if kind == "WIRE":
        args = rest.split(" ")
        if len(args) == 4:
            return OnTheWire(_sequence(args[0], allow_none=True), _number(args[1]),
                             VelocityCommand(_number(args[2]), _number(args[3])))
    raise ValueError(f"unknown dead-man message {data[:40]!r}")
