"""The streaming feedback framing parser: unit cases and hypothesis properties."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from lanewarden.actuation.kobuki_framing import PacketReader, checksum, frame_packet

PROPERTY = settings(derandomize=True, max_examples=300, deadline=None)


def _valid(packet: bytes) -> bool:
    return packet[:2] == b"\xaa\x55" and packet[2] == len(packet) - 4 and \
        checksum(packet[2:]) == 0


def test_frame_and_parse_round_trip() -> None:
    payload = bytes.fromhex("01 04 00 00 00 00")
    assert frame_packet(payload) == bytes.fromhex("AA 55 06 01 04 00 00 00 00 03")
    assert PacketReader().feed(frame_packet(payload)) == [payload]


def test_header_bytes_inside_data_do_not_split_a_packet() -> None:
    payload = bytes.fromhex("01 0F AA 55 06 AA 55 AA 55 00 00 AA AA 55 55 00 00")
    reader = PacketReader()
    assert reader.feed(frame_packet(payload) * 2) == [payload, payload]
    assert reader.checksum_errors == 0


def test_byte_by_byte_feeding() -> None:
    payloads = [bytes([1, 2, 3]), bytes.fromhex("AA 55 03 AA 55 01"), bytes(255)]
    reader = PacketReader()
    out: list[bytes] = []
    for byte in b"".join(frame_packet(p) for p in payloads):
        out += reader.feed(bytes([byte]))
    assert out == payloads


def test_bad_checksum_resyncs_one_byte_after_the_header() -> None:
    good = frame_packet(bytes([1, 2, 3]))
    # a corrupt packet whose data hides a complete valid packet: found after resync
    corrupt = b"\xaa\x55\x0e" + good + bytes([9, 9, 9, 9]) + b"\x00"
    assert checksum(corrupt[2:]) != 0
    reader = PacketReader()
    assert reader.feed(corrupt + good) == [bytes([1, 2, 3]), bytes([1, 2, 3])]
    assert reader.checksum_errors == 1


def test_length_below_three_is_rejected_and_skipped() -> None:
    reader = PacketReader()
    good = frame_packet(bytes([7, 7, 7]))
    assert reader.feed(b"\xaa\x55\x01\x01\x00" + good) == [bytes([7, 7, 7])]
    assert reader.length_errors == 1


def test_incomplete_packet_waits_for_more() -> None:
    packet = frame_packet(bytes(range(20)))
    reader = PacketReader()
    assert reader.feed(packet[:-1]) == []
    assert reader.pending_bytes == len(packet) - 1
    assert reader.feed(packet[-1:]) == [bytes(range(20))]
    assert reader.pending_bytes == 0


payloads_st = st.binary(min_size=3, max_size=255)
# noise between packets: anything but 0xAA, so it cannot start a header that swallows a packet
noise_st = st.binary(max_size=40).map(lambda b: bytes(x for x in b if x != 0xAA))


def _feed_in_chunks(data: bytes, sizes: list[int]) -> list[bytes]:
    """Feed `data` to a fresh reader split at the given chunk sizes (the rest in one go)."""
    reader = PacketReader()
    out: list[bytes] = []
    position = 0
    for size in sizes:
        out += reader.feed(data[position:position + size])
        position += size
    return out + reader.feed(data[position:])


@PROPERTY
@given(st.binary(max_size=2000), st.lists(st.integers(1, 64), max_size=50))
def test_random_bytes_never_crash_and_never_yield_a_bad_packet(data: bytes,
                                                                chunks: list[int]) -> None:
    for payload in _feed_in_chunks(data, chunks):
        # every yielded payload came from a checksum-valid frame present in the input
        assert 3 <= len(payload) <= 255
        assert frame_packet(payload) in data


@PROPERTY
@given(st.lists(st.tuples(noise_st, payloads_st), min_size=1, max_size=12),
       st.lists(st.integers(1, 300), max_size=40))
def test_every_valid_packet_is_recovered_through_noise_and_splits(
        stream: list[tuple[bytes, bytes]], cuts: list[int]) -> None:
    data = b"".join(noise + frame_packet(payload) for noise, payload in stream)
    assert _feed_in_chunks(data, cuts) == [payload for _, payload in stream]


@PROPERTY
@given(st.lists(payloads_st, min_size=1, max_size=8), st.binary(min_size=1, max_size=60))
def test_garbage_with_headers_in_front_never_invents_a_packet(payloads: list[bytes],
                                                              garbage: bytes) -> None:
    data = b"\xaa\x55" + garbage + b"".join(frame_packet(p) for p in payloads)
    reader = PacketReader()
    out = reader.feed(data)
    for payload in out:
        assert _valid(frame_packet(payload)) and frame_packet(payload) in data
    # whatever the garbage swallowed, the last packet is always recovered once more data flows
    last = frame_packet(payloads[-1])
    out += reader.feed(last * (260 // len(last) + 2))  # more than any LEN can swallow
    assert out[-1] == payloads[-1]
