"""The messages between the control process (KobukiBase) and the dead-man process.

One message per SOCK_SEQPACKET record, ASCII words separated by spaces, binary as hex:

control -> dead-man: `ARM` | `CMD <linear_m_s> <angular_rad_s>` | `RAW <hex sub-payloads>`
                     | `CLOSE`
dead-man -> control: `OPEN <low_latency 0|1>` | `ERROR <text>`
                     | `FB <checksum_errors> <hex payload>` | `MODE <mode> <reason>` | `LOST <text>`

`CMD` doubles as the heartbeat. Decoding is strict: anything else raises ValueError (the
dead-man treats that as a missed heartbeat). Pure: no sockets here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.kobuki_commands import CommandId


# ---- control -> dead-man ------------------------------------------------------------------------
@dataclass(frozen=True)
class Arm:
    """Explicitly (re-)arm the dead-man: the only way out of DISARMED or TRIPPED."""


@dataclass(frozen=True)
class Command:
    """The velocity to execute from now on; also a heartbeat."""

    command: VelocityCommand


@dataclass(frozen=True)
class RawCommand:
    """Non-motion command sub-payloads (sound, request extra, GPO, gains) to write once."""

    sub_payloads: bytes


@dataclass(frozen=True)
class Close:
    """Stop the base, flush and exit."""


ControlMessage = Arm | Command | RawCommand | Close


# ---- dead-man -> control ------------------------------------------------------------------------
@dataclass(frozen=True)
class PortOpened:
    low_latency: bool


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


DeadmanMessage = PortOpened | OpenFailed | FeedbackReceived | ModeChanged | LinkLost

#: SOCK_SEQPACKET receive size: large enough for any message above.
MAX_MESSAGE_BYTES = 4096


def _one_line(text: str) -> str:
    return " ".join(text.split())


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


def encode_control(message: ControlMessage) -> bytes:
    if isinstance(message, Arm):
        return b"ARM"
    if isinstance(message, Command):
        return f"CMD {message.command.linear_m_s!r} {message.command.angular_rad_s!r}".encode()
    if isinstance(message, RawCommand):
        return b"RAW " + message.sub_payloads.hex().encode()
    return b"CLOSE"


def decode_control(data: bytes) -> ControlMessage:
    """Parse one control message; ValueError on anything malformed (including NaN speeds)."""
    words = data.decode("ascii").split(" ")
    kind, args = words[0], words[1:]
    if kind == "ARM" and not args:
        return Arm()
    if kind == "CLOSE" and not args:
        return Close()
    if kind == "CMD" and len(args) == 2:
        linear, angular = float(args[0]), float(args[1])
        if not (math.isfinite(linear) and math.isfinite(angular)):
            raise ValueError(f"non-finite command {args}")
        return Command(VelocityCommand(linear, angular))
    if kind == "RAW" and len(args) == 1 and args[0]:
        sub_payloads = bytes.fromhex(args[0])
        check_non_motion(sub_payloads)
        return RawCommand(sub_payloads)
    raise ValueError(f"unknown control message {data[:40]!r}")


def encode_deadman(message: DeadmanMessage) -> bytes:
    if isinstance(message, PortOpened):
        return f"OPEN {int(message.low_latency)}".encode()
    if isinstance(message, OpenFailed):
        return f"ERROR {_one_line(message.message)}".encode()
    if isinstance(message, FeedbackReceived):
        return f"FB {message.checksum_errors} {message.payload.hex()}".encode()
    if isinstance(message, ModeChanged):
        return f"MODE {message.mode.value} {_one_line(message.reason)}".encode()
    return f"LOST {_one_line(message.message)}".encode()


def decode_deadman(data: bytes) -> DeadmanMessage:
    """Parse one dead-man message; ValueError on anything malformed."""
    kind, _, rest = data.decode("utf-8").partition(" ")
    if kind == "OPEN" and rest in ("0", "1"):
        return PortOpened(rest == "1")
    if kind == "ERROR":
        return OpenFailed(rest)
    if kind == "FB":
        errors, _, payload = rest.partition(" ")
        return FeedbackReceived(int(errors), bytes.fromhex(payload))
    if kind == "MODE":
        mode, _, reason = rest.partition(" ")
        return ModeChanged(DeadmanMode(mode), reason)
    if kind == "LOST":
        return LinkLost(rest)
    raise ValueError(f"unknown dead-man message {data[:40]!r}")
