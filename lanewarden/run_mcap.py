"""A recorded run as ROS 2 messages in one MCAP file, `run.mcap`: its topics, their message
definitions, and the writer.

- the frames, `sensor_msgs/msg/CompressedImage`, on one of two topics (the run's meta says
  which, `frames`; the message's `header.stamp`: the capture time; its MCAP `sequence`: the
  frame's index):
  - `/lanewarden/perception_input/compressed` (the default): what perception consumed of each
    frame (`LaneDetector.prepare`: gray, undistorted, blurred, before contrast normalisation),
    a PNG (`mono8; png compressed`), lossless: replay feeds it to the detector as it is, so the
    replay is exact, and it is about 60 % of the camera's gray frame on disk, because the blur
    has already removed most of the sensor noise PNG could not compress;
  - `/camera/image/compressed`: the camera's own view, its gray version as PNG (`--record-gray`:
    exact too, and what a replay with another blur or calibration needs) or a colour JPEG
    (`bgr8; jpeg compressed bgr8`, `--record-lossy`: not exact);
- `/cmd_vel` (`geometry_msgs/msg/Twist`): the command sent to the base, every step (`linear.x`
  m/s, `angular.z` rad/s);
- `/lanewarden/base_feedback` (`lanewarden_msgs/msg/BaseFeedback`): each new feedback packet of
  the base (bumper, wheel drop, cliff, buttons, battery, odometry);
- `/lanewarden/step` (`lanewarden_msgs/msg/Step`): every step: state, halt reason, events,
  confidence, raw and filtered slope sum, command, and `record`: the whole recorded step
  (lanewarden.run_record, JSON), which is what an exact replay reads.

Every channel carries, as rosbag2's own MCAP storage writes them, `offered_qos_profiles` (the QoS
the topic was offered with, YAML: reliable, volatile, keep last 10, which every subscriber's
request matches; `ros2 bag play` publishes with it); the image channel also `lanewarden.image`, a
sentence saying what its pictures are.

All CDR-encoded with `ros2msg` schemas (profile `ros2`), chunked with message and chunk indexes and
a summary section, so Foxglove and Lichtblick open it, `ros2 bag info` / `ros2 bag play` read it
(play skips the two `lanewarden_msgs` topics, whose package a ROS install lacks, with a warning)
and any MCAP library reads it back. The file is self-contained: a Metadata record `lanewarden`
(the format version and the run's meta: command line, camera, base, software), attachments
`config.yaml` and `calibration.yaml` (what the run used), and, once the run ended, a Metadata
record `lanewarden.summary` (the recording's summary.json). Log times are the step's time on the
wall clock (UNIX nanoseconds: the monotonic step time plus the offset taken once at start); the
exact step and frame times are in each step's record.

Written with Foxglove's own libraries (`mcap`'s writer for the container, `mcap-ros2-support`'s
CDR encoder, `serialize_dynamic`, for the messages): the reference implementation of the MCAP
ROS 2 profile (its ready-made ROS 2 writer registers channels without metadata, so the channels
are registered here, each with its QoS). Chunks are left uncompressed (the frames are PNG or JPEG
already) and small (`CHUNK_BYTES`), so a run that is killed loses at most its last chunk. Not
thread-safe: one writer thread owns it (lanewarden/recording.py).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from importlib import metadata
from typing import IO, Any

import mcap_ros2
from mcap.well_known import SchemaEncoding
from mcap.writer import CompressionType, Writer
from mcap_ros2._dynamic import serialize_dynamic

from lanewarden.actuation.base import BaseFeedback
from lanewarden.run_record import StepInput
from lanewarden.supervisor.loop import StepRecord

IMAGE_TOPIC = "/camera/image/compressed"
PERCEPTION_TOPIC = "/lanewarden/perception_input/compressed"
#: What each kind of recorded frame is (the run's meta `image`; the image channel's
#: `lanewarden.image` metadata says it in words).
PERCEPTION_INPUT = "perception input"
CAMERA_GRAY = "camera gray"
CAMERA_JPEG = "camera colour jpeg"
IMAGE_KINDS = {
    PERCEPTION_INPUT: (PERCEPTION_TOPIC, "perception input: the camera frame's gray version, "
                       "undistorted, blurred, before contrast normalisation (what the lane "
                       "detector consumed; lossless)"),
    CAMERA_GRAY: (IMAGE_TOPIC, "the camera frame's gray version (lossless)"),
    CAMERA_JPEG: (IMAGE_TOPIC, "the camera frame in colour, JPEG (lossy)"),
}
CMD_VEL_TOPIC = "/cmd_vel"
FEEDBACK_TOPIC = "/lanewarden/base_feedback"
STEP_TOPIC = "/lanewarden/step"
META_NAME = "lanewarden"
SUMMARY_NAME = "lanewarden.summary"
CONFIG_ATTACHMENT = "config.yaml"
CALIBRATION_ATTACHMENT = "calibration.yaml"
CAMERA_FRAME_ID = "camera"
#: The image channel's metadata key saying what its pictures are.
IMAGE_METADATA = "lanewarden.image"
PNG_FORMAT = "mono8; png compressed"
JPEG_FORMAT = "bgr8; jpeg compressed bgr8"
#: The QoS every channel was offered with, as rosbag2 (Humble and later) writes it: history
#: keep last (1), depth 10, reliable (1), volatile (2), liveliness automatic (1), no deadline,
#: lifespan or lease (rmw's "infinite" duration).
OFFERED_QOS_PROFILES = """\
- history: 1
  depth: 10
  reliability: 1
  durability: 2
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: 1
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false"""
#: The writing library, in the MCAP header.
LIBRARY = (f"mcap-python/{metadata.version('mcap')} "
           f"mcap-ros2-support/{mcap_ros2.__version__}")
#: A chunk is written once it holds this much: about one 640x480 frame, or a few seconds of
#: steps without frames. Small chunks bound what a killed run loses.
CHUNK_BYTES = 128 * 1024

_HEADER = """\
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""

COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
COMPRESSED_IMAGE_DEF = """\
std_msgs/Header header
string format
uint8[] data
""" + _HEADER

IMAGE = "sensor_msgs/msg/Image"
IMAGE_DEF = """\
std_msgs/Header header
uint32 height
uint32 width
string encoding
uint8 is_bigendian
uint32 step
uint8[] data
""" + _HEADER

TWIST = "geometry_msgs/msg/Twist"
TWIST_DEF = """\
geometry_msgs/Vector3 linear
geometry_msgs/Vector3 angular
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
"""

STEP = "lanewarden_msgs/msg/Step"
STEP_DEF = """\
# One step of Lanewarden's control loop (lanewarden run --record).
# header.stamp: the step's time.
std_msgs/Header header
# FOLLOW, TURN_LEFT, TURN_RIGHT, DEGRADED or HALT, and why it halted ("" when not halted)
string state
string halt_reason
# this step's events, highest priority first
string[] events
# the newest frame's index (-1: none yet)
int64 frame_index
# perception's confidence in a new frame, 0..1; raw and filtered slope sums (NaN: none this step)
float64 confidence
float64 slope_sum
float64 filtered_slope_sum
# the command sent to the base (m/s, rad/s)
float64 linear_m_s
float64 angular_rad_s
# the whole recorded step as JSON (lanewarden/run_record.py): what an exact replay reads
string record
""" + _HEADER

BASE_FEEDBACK = "lanewarden_msgs/msg/BaseFeedback"
BASE_FEEDBACK_DEF = """\
# One feedback packet of the base. header.stamp: when it was received.
std_msgs/Header header
# Kobuki bits: bumper 1 right, 2 centre, 4 left; wheel_drop 1 right, 2 left;
# cliff 1 right, 2 centre, 4 left; buttons 1 B0, 2 B1, 4 B2
uint8 bumper
uint8 wheel_drop
uint8 cliff
uint8 buttons
# volts (NaN: unknown)
float64 battery_v
# odometry: metres and radians in the base's start frame
float64 x_m
float64 y_m
float64 theta_rad
""" + _HEADER

#: Every message type a recording writes or a replay reads, by schema name.
DEFINITIONS = {COMPRESSED_IMAGE: COMPRESSED_IMAGE_DEF, IMAGE: IMAGE_DEF, TWIST: TWIST_DEF,
               STEP: STEP_DEF, BASE_FEEDBACK: BASE_FEEDBACK_DEF}
_NAN = float("nan")
_MAX_NS = 2**63 - 1


def _or_nan(value: float | None) -> float:
    return _NAN if value is None else float(value)


class RunMcapWriter:
    """Writes one run.mcap onto `stream` (opened by the caller; closed by it after `finish`).
    `epoch_offset_s`: add to a step time (monotonic seconds) to get UNIX seconds. `image_kind`:
    which frames it holds (IMAGE_KINDS)."""

    def __init__(self, stream: IO[bytes], epoch_offset_s: float = 0.0,
                 image_kind: str = PERCEPTION_INPUT) -> None:
        self._offset = epoch_offset_s
        self._writer = Writer(stream, chunk_size=CHUNK_BYTES, compression=CompressionType.NONE)
        self._writer.start(profile="ros2", library=LIBRARY)
        self.image_topic, description = IMAGE_KINDS[image_kind]
        self._channels: dict[str, tuple[int, Callable[[Any], bytes]]] = {}
        for topic, name, extra in (
                (self.image_topic, COMPRESSED_IMAGE, {IMAGE_METADATA: description}),
                (STEP_TOPIC, STEP, {}), (CMD_VEL_TOPIC, TWIST, {}),
                (FEEDBACK_TOPIC, BASE_FEEDBACK, {})):
            text = DEFINITIONS[name]
            schema = self._writer.register_schema(name, SchemaEncoding.ROS2, text.encode())
            channel = self._writer.register_channel(
                topic, "cdr", schema, {"offered_qos_profiles": OFFERED_QOS_PROFILES, **extra})
            self._channels[topic] = (channel, serialize_dynamic(name, text)[name])
        self._feedback_at: float | None = None

    def _write(self, topic: str, message: dict[str, Any], log_time: int,
               sequence: int = 0) -> None:
        channel, encode = self._channels[topic]
        self._writer.add_message(channel, log_time=log_time, data=encode(message),
                                 publish_time=log_time, sequence=sequence)

    def _ns(self, t: float) -> int:
        ns = (t + self._offset) * 1e9
        return min(max(round(ns), 0), _MAX_NS) if math.isfinite(ns) else 0

    def _header(self, t: float, frame_id: str = "") -> dict[str, Any]:
        ns = self._ns(t)
        return {"stamp": {"sec": min(ns // 1_000_000_000, 2**31 - 1),
                          "nanosec": ns % 1_000_000_000}, "frame_id": frame_id}

    def start(self, meta: dict[str, Any], attachments: dict[str, bytes], t: float) -> None:
        """The run's meta and the files it used, before its first step."""
        self._writer.add_metadata(META_NAME, {"format": str(meta.get("format")),
                                              "meta": json.dumps(meta)})
        for name, data in attachments.items():
            self._writer.add_attachment(create_time=0, log_time=self._ns(t), name=name,
                                        media_type="application/yaml", data=data)

    def frame(self, index: int, time_s: float, logged_at: float, image_format: str,
              data: bytes) -> None:
        """One camera frame (an encoded image), sequence = its index."""
        self._write(self.image_topic, {"header": self._header(time_s, CAMERA_FRAME_ID),
                                       "format": image_format, "data": data},
                    self._ns(logged_at), index & 0xFFFFFFFF)

    def step(self, record: StepRecord, step_input: StepInput, record_json: str) -> None:
        """One step: its Step message, the command on /cmd_vel, and the feedback if new."""
        log_time = self._ns(record.time_s)
        observation = record.observation
        command = record.command
        self._write(STEP_TOPIC, {
            "header": self._header(record.time_s),
            "state": record.state,
            "halt_reason": record.halt_reason or "",
            "events": list(record.events),
            "frame_index": -1 if record.frame_index is None else record.frame_index,
            "confidence": _NAN if observation is None else observation.confidence,
            "slope_sum": _or_nan(None if observation is None else observation.slope_sum),
            "filtered_slope_sum": _or_nan(record.filtered_slope_sum),
            "linear_m_s": command.linear_m_s,
            "angular_rad_s": command.angular_rad_s,
            "record": record_json,
        }, log_time)
        self._write(CMD_VEL_TOPIC, {
            "linear": {"x": command.linear_m_s, "y": 0.0, "z": 0.0},
            "angular": {"x": 0.0, "y": 0.0, "z": command.angular_rad_s}}, log_time)
        feedback = step_input.feedback
        if feedback is not None and feedback.received_at_s != self._feedback_at:
            self._feedback_at = feedback.received_at_s
            self._base_feedback(feedback, log_time)

    def _base_feedback(self, feedback: BaseFeedback, log_time: int) -> None:
        pose = feedback.odometry
        received = feedback.received_at_s
        self._write(FEEDBACK_TOPIC, {
            "header": self._header(0.0 if received is None else received),
            "bumper": feedback.bumper & 0xFF, "wheel_drop": feedback.wheel_drop & 0xFF,
            "cliff": feedback.cliff & 0xFF, "buttons": feedback.buttons & 0xFF,
            "battery_v": _or_nan(feedback.battery_v),
            "x_m": pose.x_m, "y_m": pose.y_m, "theta_rad": pose.theta_rad}, log_time)

    def finish(self, summary: dict[str, Any]) -> None:
        """The summary record, then MCAP's summary section and footer."""
        self._writer.add_metadata(SUMMARY_NAME, {"summary": json.dumps(summary)})
        self._writer.finish()
