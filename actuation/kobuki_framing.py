"""Kobuki packet framing: `AA 55 | LEN | payload | CS`, both directions, as pure bytes in/out.

`frame_packet` wraps a payload (a run of sub-payloads) for the wire. `PacketReader` is the
streaming parser for what the base sends: a length- and checksum-checked state machine that
resyncs one byte after a rejected header and never splits the stream on `AA 55` (which can occur
inside data). It only ever yields payloads whose checksum is valid.

Never does I/O, never reads a clock, never interprets a payload (see `kobuki_feedback`).
"""

from __future__ import annotations

HEADER = b"\xaa\x55"
#: The smallest and largest LEN a packet may carry (protocol: payload is 3..255 bytes).
MIN_PAYLOAD_LEN = 3
MAX_PAYLOAD_LEN = 255


def checksum(length_and_payload: bytes | bytearray) -> int:
    """XOR of LEN and every payload byte: the byte that makes the XOR of LEN..CS zero."""
    value = 0
    for byte in length_and_payload:
        value ^= byte
    return value


def frame_packet(payload: bytes) -> bytes:
    """The full wire packet for `payload` (the sub-payloads, without header, LEN or CS)."""
    if not MIN_PAYLOAD_LEN <= len(payload) <= MAX_PAYLOAD_LEN:
        raise ValueError(
            f"payload of {len(payload)} bytes: expected {MIN_PAYLOAD_LEN}..{MAX_PAYLOAD_LEN}"
        )
    body = bytes([len(payload)]) + payload
    return HEADER + body + bytes([checksum(body)])


class PacketReader:
    """Streaming framing parser: feed it bytes as they arrive, get back valid payloads.

    State is the unconsumed tail of the stream. For each header candidate it waits until LEN and
    the whole packet are there, then checks LEN's range and the checksum; a packet that fails
    either is counted and the search resumes one byte after the candidate's first byte, so a
    genuine packet that began inside the rejected one is still found. Bytes before a header are
    counted as skipped noise.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.checksum_errors = 0
        self.length_errors = 0
        self.skipped_bytes = 0
        self.packets = 0

    def feed(self, data: bytes) -> list[bytes]:
        """Append `data` to the stream; return the payloads of every packet completed by it."""
        self._buffer += data
        payloads: list[bytes] = []
        buffer = self._buffer
        start = 0
        while True:
            header_at = buffer.find(HEADER, start)
            if header_at < 0:
                # keep a trailing 0xAA: it may be the first half of a header split across reads
                keep_from = len(buffer) - 1 if buffer.endswith(HEADER[:1]) else len(buffer)
                self.skipped_bytes += max(0, keep_from - start)
                start = max(start, keep_from)
                break
            self.skipped_bytes += header_at - start
            start = header_at
            if len(buffer) < start + 3:
                break  # LEN not here yet
            length = buffer[start + 2]
            if not MIN_PAYLOAD_LEN <= length <= MAX_PAYLOAD_LEN:
                self.length_errors += 1
                self.skipped_bytes += 1
                start += 1
                continue
            end = start + 3 + length + 1
            if len(buffer) < end:
                break  # wait for the rest of this packet
            if checksum(buffer[start + 2:end]) != 0:
                self.checksum_errors += 1
                self.skipped_bytes += 1
                start += 1
                continue
            payloads.append(bytes(buffer[start + 3:end - 1]))
            self.packets += 1
            start = end
        del buffer[:start]
        return payloads

    @property
    def pending_bytes(self) -> int:
        """Bytes held back waiting for the rest of a possible packet."""
        return len(self._buffer)
