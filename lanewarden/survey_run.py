"""Running a survey: perception on every labelled frame, the real supervisor on the lane frames,
on a fake clock; out come the per-frame results, the engage figures and the report's pictures.

- Stills (class folders, a labels file of images): each image is analysed on its own, as
  `lanewarden detect` does (no previous observation). Each lane still is then held in view at the
  camera rate (`supervisor.camera_period_s`) after a start, through the very stack `run` drives
  (`lanewarden.replay.replay_steps`: detector, supervised controller, SafetyGate), for `hold_s`
  = max(1 s, twice the time `engage_confident_frames` take): the time until the supervisor leaves
  HALT is the still's engage time. The supervisor itself decides; nothing here restates its rule.
- A recording (a video, run folder, tub or image sequence with frame labels): its frames from the
  first labelled one to the last, in order at their own times, through the same stack, with a
  start at the first and a resume after every halt (an operator who resumes at once); each
  labelled frame's result is the loop's own observation (with the previous one, as on the robot),
  and the supervisor's state at it is recorded. Each labelled no-lane frame is also judged on its
  own, exactly as a still is (`OnItsOwn`): in sequence, a lane that "jumped" since the previous
  frame gets confidence 0 from the `consistency` component, but a robot that comes upon the same
  view gradually has no such jump to save it; a decision either way is a false lane. Lane frames
  keep the loop's judgement.

Confident is the supervisor's test (`supervisor.lane_evidence.LaneEvidence`), the decision is
`lanewarden.assembly.decision_rule`'s. Pictures (perception's own overlay drawing,
`perception.overlay.draw_detection`, of the detection that decided: the frame as judged, else the
shifted version or the frame judged on its own) are kept for the first `FALSE_LANE_PICTURES` false
lanes and, in `WEAK_PICTURES` stretches of the lane frames, the least confident lane frame of each
that is not confident; when every lane frame is confident, the least confident lane frame of each
stretch instead (so the report still shows what perception paired): memory stays bounded on a
long recording. Never reads a clock, never prints (the caller passes a progress callback).
"""

from __future__ import annotations

import itertools
import math
import zlib
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from functools import partial

import cv2
import numpy as np

from lanewarden.assembly import DecisionRule, decision_rule
from lanewarden.config import LanewardenConfig
from lanewarden.errors import ConfigError, InputFileError
from lanewarden.image_files import TURNED, is_turned, read_image, too_many_pixels
from lanewarden.perception.calibration import CameraCalibration
from lanewarden.perception.detector import DetectionDebug, LaneDetector
from lanewarden.perception.errors import PerceptionConfigError, PerceptionError
from lanewarden.perception.observation import LaneObservation
from lanewarden.perception.overlay import as_bgr, draw_detection, enlarged, perception_text
from lanewarden.replay import ReplayedStep, replay_steps
from lanewarden.replay_sources import FrameStore, ReplaySource, camera_steps, frame_name
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.lane_evidence import LaneEvidence
from lanewarden.supervisor.state_machine import ENGAGED_STATES, SupervisorState
from lanewarden.supervisor.watchdog import mark_capture
from lanewarden.survey import (
    LANE,
    NONE,
    EngageFigures,
    FrameResult,
    LabelledFrame,
    OnItsOwn,
    Shifted,
    not_engaged_counts,
    on_its_own_text,
)
from lanewarden.survey_source import StillFrame, SurveySource, problems_line
from lanewarden.wording import counted

CONTROLLER = "supervised"
#: Shortest time a lane still is held in view for the engage test, s.
HOLD_MIN_S = 1.0
FALSE_LANE_PICTURES = 24
WEAK_PICTURES = 8
#: Pictures of smaller frames are enlarged (nearest neighbour) to at least this many rows.
PICTURE_MIN_ROWS = 240
PICTURE_JPEG_QUALITY = 85
#: `survey --jitter`: each shifted version moves by up to this much along each axis, pixels...
SHIFT_MAX_PX = 0.5
#: ...drawn from this seed.
SHIFT_SEED = 0

Progress = Callable[[int], None]


@dataclass(frozen=True)
class Picture:
    """An annotated frame for the report: JPEG bytes and perception's words about it;
    `confident`: the frame as judged was (the supervisor's test)."""

    name: str
    expect: str
    confidence: float
    caption: tuple[str, ...]
    jpeg: bytes
    confident: bool = False


@dataclass
class SurveyRun:
    results: list[FrameResult]
    engage: EngageFigures | None
    false_lane_pictures: list[Picture] = field(default_factory=list)
    weak_pictures: list[Picture] = field(default_factory=list)


def hold_seconds(config: SupervisorConfig) -> float:
    """How long a lane still is held in view for the engage test."""
    return max(HOLD_MIN_S, 2.0 * config.engage_confident_frames * config.camera_period_s)


def is_engaged(state: str) -> bool:
    return SupervisorState(state) in ENGAGED_STATES


def frame_result(frame: LabelledFrame, observation: LaneObservation, decide: DecisionRule,
                 supervisor: SupervisorConfig, *, engaged_after_s: float | None = None,
                 engaged: bool | None = None, not_engaged: str | None = None,
                 shifted: Shifted | None = None,
                 on_its_own: OnItsOwn | None = None) -> FrameResult:
    return FrameResult(
        frame=frame, decision=decide(observation), confidence=observation.confidence,
        confident=LaneEvidence(supervisor).assess(observation).confident,
        components=observation.components, engaged_after_s=engaged_after_s, engaged=engaged,
        not_engaged=not_engaged, shifted=shifted, on_its_own=on_its_own)


def picture(result: FrameResult, observation: LaneObservation, debug: DetectionDebug,
            other: tuple[str, str] | None = None) -> Picture:
    """Perception's overlay (ROI, segments, tape partners, chosen edges) on the analysed frame.
    `other`: the detection is not the frame's as judged but (what it is, its decision): a
    shifted version of a still, or a recording's frame judged on its own; the caption's first
    line says which."""
    canvas = as_bgr(debug.image)
    draw_detection(canvas, observation, debug)
    canvas = enlarged(canvas, PICTURE_MIN_ROWS)
    ok, data = cv2.imencode(".jpg", canvas, [cv2.IMWRITE_JPEG_QUALITY, PICTURE_JPEG_QUALITY])
    assert ok, "OpenCV could not encode a picture"
    caption = tuple(perception_text(observation, result.decision if other is None else other[1]))
    if other is not None:
        caption = (other[0], *caption)
    return Picture(result.frame.name, result.frame.expect, observation.confidence, caption,
                   data.tobytes(), result.confident)


def shifted_caption(offset: tuple[float, float], shifted: Shifted) -> str:
    """The first caption line of a shifted version's picture: which copy, and how many such
    copies got a decision."""
    return (f"a copy shifted by ({offset[0]:+.2f}, {offset[1]:+.2f}) px (x, y); "
            f"{len(shifted.decided)} of {shifted.versions} such copies got a decision")


def on_its_own_caption(result: FrameResult) -> str:
    """The first caption line of a picture of a recording's frame judged on its own."""
    return (f"judged on its own, as a photo is (in sequence: "
            f"{on_its_own_text(OnItsOwn(result.decision, result.confidence))})")


class PictureKeeper:
    """The pictures the report shows, bounded (see the module docstring). `lane_orders`: the
    sequence order of every lane frame, to split them into stretches."""

    def __init__(self, lane_orders: Iterable[int]) -> None:
        ordered = sorted(lane_orders)
        self._rank = {order: i for i, order in enumerate(ordered)}
        self._lanes = max(1, len(ordered))
        self.false_lanes: list[Picture] = []
        self._weak: dict[int, tuple[tuple[float, int], Picture]] = {}
        #: the least confident confident lane frame of each stretch, kept only while no lane
        #: frame is weak (then the weak ones are shown)
        self._least: dict[int, tuple[tuple[float, int], Picture]] = {}

    def offer(self, result: FrameResult, draw: Callable[[], Picture]) -> None:
        if result.false_lane:
            if len(self.false_lanes) < FALSE_LANE_PICTURES:
                self.false_lanes.append(draw())
            return
        if result.frame.expect != LANE:
            return
        if not result.confident:
            self._least.clear()
            kept = self._weak
        elif self._weak:
            return
        else:
            kept = self._least
        stretch = self._rank[result.frame.order] * WEAK_PICTURES // self._lanes
        key = (result.confidence, result.frame.order)
        if stretch not in kept or key < kept[stretch][0]:
            kept[stretch] = (key, draw())

    @property
    def weak(self) -> list[Picture]:
        """The weakest lane frames in sequence order: not confident, or, when every lane frame
        was confident, the least confident (their pictures say `confident`)."""
        kept = self._weak or self._least
        return [kept[k][1] for k in sorted(kept)]


class HeldImage(FrameStore):
    """A still held in front of a live camera: the same view at every frame index. A live
    camera's frames of one view still differ in their sensor noise, and the supervisor does not
    count an image identical to one of its last few (a frozen camera, or one cycling through old
    buffers) towards engaging; so each capture is marked with its index (`mark_capture`: the
    lowest bit of a few pixels of the top row, outside every region perception reads; a test
    checks that the observation is unchanged)."""

    def __init__(self, image: np.ndarray) -> None:
        super().__init__()
        self._image = image

    def image(self, index: int) -> np.ndarray | None:
        return mark_capture(self._image.copy(), index)


def other_size(image: np.ndarray, size: tuple[int, int] | None, first: str,
               note: str = "") -> str:
    """'' when `image` is of the survey's `size` (None: any), else how it (`note`: more about it)
    differs from `first`, what set the size ("the first frame (a.jpg)", "the calibration's
    size")."""
    height, width = image.shape[:2]
    if size is None or (width, height) == size:
        return ""
    return f"decoded as {width}x{height}{note}; {first} is {size[0]}x{size[1]}"


class CheckedFrames(FrameStore):
    """A recording's frames, each checked as it is decoded: more pixels than the limit, or a size
    other than the calibration's (without one: the survey's first frame's, `size`), is a
    `problem` (the frame is not used); a frame that cannot be read is remembered in `missing`.
    Problems are not raised here: the control loop would turn them into a camera fault."""

    def __init__(self, store: FrameStore, max_pixels: int,
                 calibration: CameraCalibration | None,
                 size: tuple[int, int] | None = None) -> None:
        super().__init__()
        self._store = store
        self.undecoded = store.undecoded  # the recording's own: what the loop asks of it
        self._max_pixels = max_pixels
        self._size = size if calibration is None else calibration.image_size
        self._size_of = "the first frame" if calibration is None else "the calibration's size"
        self.problem: str | None = None
        self.missing: set[int] = set()

    def stream_end(self) -> int | None:
        return self._store.stream_end()

    def image(self, index: int) -> np.ndarray | None:
        image = self._store.image(index)
        if image is None:
            self.missing.add(index)
            return None
        height, width = image.shape[:2]
        if why := too_many_pixels(width, height, self._max_pixels):
            self.problem = f"frame {index}: {why}"
            return None
        if why := other_size(image, self._size, self._size_of):
            self.problem = f"frame {index}: {why}"
            return None
        return image

    def close(self) -> None:
        self._store.close()


def _steps(source: ReplaySource, config: LanewardenConfig,
           calibration: CameraCalibration | None) -> Iterator[ReplayedStep]:
    """`replay_steps`, with a config this camera cannot work with as a ConfigError."""
    try:
        yield from replay_steps(source, config, calibration, CONTROLLER)
    except PerceptionConfigError as exc:
        raise ConfigError(str(exc)) from None


def held_engage(image: np.ndarray, config: LanewardenConfig,
                calibration: CameraCalibration | None,
                hold_s: float) -> tuple[float | None, str | None]:
    """(seconds after a start until the supervisor engages on `image` held in view, None) or,
    when it does not within `hold_s`, (None, why: the supervisor's own halt reason at the last
    frame, e.g. a lane edge inside the robot's footprint)."""
    period = config.supervisor.camera_period_s
    count = math.floor(hold_s / period + 1e-9) + 1
    held = ReplaySource(kind="images", name="held", steps=camera_steps(
        ((k, k * period) for k in range(count)), later=("resume",)), frames=HeldImage(image))
    why: str | None = None
    for step in replay_steps(held, config, calibration, CONTROLLER):
        if is_engaged(step.record.state):
            return step.step_input.t, None
        why = step.record.halt_reason
    return None, why or "no reason given"


def shifted_image(image: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """`image` moved by (dx, dy) pixels (bilinear, its border repeated): the same view as a
    camera's next frame might show it; a fraction of a pixel changes every pixel's value a
    little and nothing a person would see."""
    move = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]], dtype=np.float32)
    return np.asarray(cv2.warpAffine(image, move, (image.shape[1], image.shape[0]),
                                     flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE))


def shifted_offsets(name: str, seed: int = SHIFT_SEED) -> Iterator[tuple[float, float]]:
    """The shifts of the still named `name`, uniform in +-SHIFT_MAX_PX on each axis, seeded by
    the seed and the name: a still's shifted versions are the same in every survey, whatever
    other stills it is surveyed with."""
    rng = np.random.default_rng([seed, zlib.crc32(name.encode("utf-8"))])
    while True:
        dx, dy = rng.uniform(-SHIFT_MAX_PX, SHIFT_MAX_PX, 2)
        yield float(dx), float(dy)


@dataclass(frozen=True)
class ShiftedSeen:
    """The first shifted version of a still that got a decision: its detection and its shift
    (dx, dy), pixels."""

    observation: LaneObservation
    debug: DetectionDebug
    offset: tuple[float, float]


def judge_shifted(image: np.ndarray, name: str, detector: LaneDetector, decide: DecisionRule,
                  versions: int, order: int = 0,
                  ) -> tuple[Shifted, ShiftedSeen | None]:
    """A still judged in `versions` copies shifted by `shifted_offsets(name)`: which got a
    decision, and the first such copy's detection and shift (for its picture)."""
    decided: list[float] = []
    first: tuple[np.ndarray, tuple[float, float]] | None = None
    for dx, dy in itertools.islice(shifted_offsets(name), versions):
        copy = shifted_image(image, dx, dy)
        observation = detector.detect(copy, order, 0.0)
        if decide(observation) != "none":
            decided.append(observation.confidence)
            first = (copy, (dx, dy)) if first is None else first
    if first is None:
        return Shifted(versions, tuple(decided)), None
    # the debug data (and its undistorted picture) only for the copy the report shows
    return Shifted(versions, tuple(decided)), ShiftedSeen(
        *detector.detect_debug(first[0], order, 0.0), first[1])


def judge_on_its_own(image: np.ndarray, index: int, time_s: float, detector: LaneDetector,
                     name: str) -> LaneObservation:
    """A recording's frame (the image the loop analysed) judged on its own: no previous
    observation, as `survey_stills` judges a still (`detect`: the debug data only for a picture,
    `on_its_own_picture`)."""
    try:
        return detector.detect(image, index, time_s)
    except PerceptionConfigError as exc:
        raise ConfigError(f"{name}: {exc}") from None
    except PerceptionError as exc:  # the loop analysed it: only a detector that differs
        raise InputFileError(f"{name}: {exc}") from None


def on_its_own_picture(result: FrameResult, image: np.ndarray, index: int, time_s: float,
                       detector: LaneDetector, decide: DecisionRule) -> Picture:
    """The picture of a frame that decided only on its own: that detection (made again with its
    debug data: pictures are drawn for a bounded few, the judging is done for every frame)."""
    observation, debug = detector.detect_debug(image, index, time_s)
    return picture(result, observation, debug,
                   (on_its_own_caption(result), decide(observation)))


def survey_stills(stills: list[StillFrame], config: LanewardenConfig,
                  calibration: CameraCalibration | None, detector: LaneDetector,
                  progress: Progress, jitter: int = 0,
                  size: tuple[int, int] | None = None) -> SurveyRun:
    """Every still on its own, and every lane still held in view (see the module docstring);
    with `jitter`, every no-lane still also in that many versions shifted by a fraction of a
    pixel (`shifted_image`), any of which with a decision makes it a false lane. An image that
    cannot be used, or one decoded at another size than `size` (the first still's), is an
    InputFileError naming each, after all were tried."""
    decide = decision_rule(config)
    hold_s = hold_seconds(config.supervisor)
    keeper = PictureKeeper(s.frame.order for s in stills if s.frame.expect == LANE)
    results: list[FrameResult] = []
    problems: list[str] = []
    times: list[float] = []
    attempts = 0
    first = ""
    for still in stills:
        progress(1)
        image, why = read_image(still.path, max_pixels=config.perception.max_image_pixels)
        if image is not None:
            turn = is_turned(still.path, image)
            first = first or f"the first frame ({still.frame.name}{', ' + TURNED if turn else ''})"
            why = other_size(image, size, first, f" ({TURNED})" if turn else "")
        if image is None or why:
            problems.append(f"{still.frame.name}: {why}")
            continue
        try:
            observation, debug = detector.detect_debug(image, still.frame.order, 0.0)
        except PerceptionConfigError as exc:
            raise ConfigError(f"{still.frame.name}: {exc}") from None
        except PerceptionError as exc:
            problems.append(f"{still.frame.name}: {exc}")
            continue
        engaged_after = why_not = None
        if still.frame.expect == LANE:
            attempts += 1
            engaged_after, why_not = held_engage(image, config, calibration, hold_s)
            if engaged_after is not None:
                times.append(engaged_after)
        shifted = seen = None
        if jitter and still.frame.expect == NONE:
            shifted, seen = judge_shifted(image, still.frame.name, detector, decide, jitter,
                                          still.frame.order)
        result = frame_result(still.frame, observation, decide, config.supervisor,
                              engaged_after_s=engaged_after,
                              engaged=None if still.frame.expect != LANE else
                              engaged_after is not None, not_engaged=why_not, shifted=shifted)
        results.append(result)
        if seen is not None and shifted is not None and not result.has_decision:
            # a false lane only when shifted: the picture of the copy that decided
            keeper.offer(result, partial(
                picture, result, seen.observation, seen.debug,
                (shifted_caption(seen.offset, shifted), decide(seen.observation))))
        else:
            keeper.offer(result, partial(picture, result, observation, debug))
    if problems:
        raise InputFileError(problems_line("frames cannot be used", len(stills), problems))
    engage = EngageFigures(how="held", window_s=hold_s, attempts=attempts, engaged=len(times),
                           times_s=tuple(times),
                           not_engaged=not_engaged_counts(r.not_engaged for r in results))
    return SurveyRun(results, engage, keeper.false_lanes, keeper.weak)


def survey_sequence(source: SurveySource, config: LanewardenConfig,
                    calibration: CameraCalibration | None, detector: LaneDetector,
                    progress: Progress, size: tuple[int, int] | None = None) -> SurveyRun:
    """The recording's labelled span through the loop, and each labelled no-lane frame also on
    its own through `detector` (as `survey_stills` judges a still; see the module docstring); a
    frame of another size than the calibration's (without one: `size`, the first frame's) is an
    InputFileError."""
    recording = source.sequence
    assert recording is not None
    labelled = source.labelled
    first, last = min(labelled), max(labelled)
    frames: dict[int, float] = {}
    for recorded in recording.steps:
        if recorded.frame is not None and first <= recorded.frame[0] <= last:
            frames.setdefault(recorded.frame[0], recorded.frame[1])
    checked = CheckedFrames(recording.frames, config.perception.max_image_pixels, calibration,
                            size)
    span = ReplaySource(kind=recording.kind, name=recording.name,
                        steps=camera_steps(frames.items(), later=("resume",)), frames=checked)
    decide = decision_rule(config)
    keeper = PictureKeeper(f.order for f in labelled.values() if f.expect == LANE)
    results: list[FrameResult] = []
    unread: list[str] = []
    halts: list[str] = []
    first_engaged: tuple[str, float] | None = None
    was_engaged = False
    engaged_lane = 0
    start_s = span.steps[0].t
    for step in _steps(span, config, calibration):
        progress(1)
        if checked.problem is not None:
            raise InputFileError(f"{recording.name}: {checked.problem}")
        assert step.step_input.frame is not None
        index = step.step_input.frame[0]
        record = step.record
        engaged = is_engaged(record.state)
        if engaged and first_engaged is None:
            first_engaged = (frame_name(recording, index), step.step_input.t - start_s)
        if was_engaged and not engaged:
            halts.append(f"{frame_name(recording, index)} {record.halt_reason}")
        was_engaged = engaged
        frame = labelled.get(index)
        if frame is None:
            continue
        if index in checked.missing or step.detection is None:
            unread.append(frame.name)
            continue
        observation, debug = step.detection
        alone = None
        if frame.expect == NONE:
            assert step.image is not None  # the image the loop's detection analysed
            alone = judge_on_its_own(step.image, index, step.step_input.t, detector, frame.name)
        result = frame_result(frame, observation, decide, config.supervisor, engaged=engaged,
                              on_its_own=None if alone is None else OnItsOwn(
                                  decide(alone), alone.confidence))
        results.append(result)
        engaged_lane += engaged and frame.expect == LANE
        if alone is not None and result.decided_on_its_own and not result.has_decision:
            # a false lane only on its own: the picture of that detection
            assert step.image is not None
            keeper.offer(result, partial(on_its_own_picture, result, step.image, index,
                                         step.step_input.t, detector, decide))
        else:
            keeper.offer(result, partial(picture, result, observation, debug))
    if (end := checked.stream_end()) is not None and (beyond := [
            f.name for i, f in sorted(labelled.items()) if i >= end]):
        # (its header claims frames its stream does not hold: the loop stopped at its end)
        raise InputFileError(f"{recording.name}: {counted(len(beyond), 'labelled frame')} "
                             f"beyond the end of its stream ({beyond[0]}"
                             f"{', ...' if len(beyond) > 1 else ''}): it ends after "
                             f"{counted(end, 'frame')}, where its header claims "
                             f"{len(recording.steps)}; label only the frames it holds")
    if unread:
        raise InputFileError(problems_line(f"labelled frames of {recording.name} could not be "
                                           "read or analysed", len(labelled), unread))
    engage = EngageFigures(
        how="sequence", window_s=span.steps[-1].t - start_s, attempts=1,
        engaged=int(first_engaged is not None),
        times_s=() if first_engaged is None else (first_engaged[1],),
        first_engaged=None if first_engaged is None else first_engaged[0],
        engaged_lane_frames=engaged_lane,
        lane_frames=sum(f.expect == LANE for f in labelled.values()), halts=tuple(halts))
    return SurveyRun(results, engage, keeper.false_lanes, keeper.weak)
