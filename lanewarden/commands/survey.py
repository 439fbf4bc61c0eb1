"""`lanewarden survey FOLDER [--labels FILE] [--calibration FILE] [--config FILE] [--out DIR]
[--json] [--jitter N]`: judge a camera on a real floor before trusting it with motors.

FOLDER holds frames sorted by what they show (`lane/`, `no-lane/`), or a `labels.csv`; a video, a
run folder, an image sequence or a Donkeycar tub works with `--labels FILE` (frame indices or
ranges). Prints the figures per class, the verdict and whether the supervisor engaged, and writes
OUT/report.html and OUT/survey.json. Exit 0 when SAFE (no decision on any no-lane frame), 3 when
NOT SAFE (the false lanes named in one line on stderr), 2 for bad input (one line naming the file,
line or flag and the value), 1 when an output cannot be written.

A thin shell: `lanewarden.survey_source` finds the labelled frames, `lanewarden.survey_run` runs
perception and the supervisor over them, `lanewarden.survey` judges, `lanewarden.survey_report`
writes.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import json
import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import click

from lanewarden import __version__
from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import PathFlag, WholeRange
from lanewarden.commands.output_folders import create_output_folder
from lanewarden.errors import (
    EXIT_OK,
    EXIT_SAFETY_STOP,
    ConfigError,
    InputFileError,
    OutputError,
    UsageError,
)

if TYPE_CHECKING:
    from lanewarden.config import LanewardenConfig
    from lanewarden.perception.calibration import CameraCalibration
    from lanewarden.survey import LabelledFrame, StricterSetting
    from lanewarden.survey_source import SurveySource

#: Most shifted versions `--jitter` makes of each no-lane still.
MAX_JITTER = 64

SURVEY_EXAMPLES = """\b
Examples:
  lanewarden survey floor/ --calibration camera.yaml
  lanewarden survey clip.mp4 --labels clip-labels.csv --out out/clip-survey
"""


@click.command("survey", epilog=SURVEY_EXAMPLES)
@click.argument("folder", metavar="FOLDER",
                type=PathFlag("a folder, a video, a run or a tub", readable=False))
@click.option("--labels", "labels_path", type=PathFlag("a labels file", dir_okay=False),
              default=None,
              metavar="FILE", help="Labels for FOLDER's frames: file,expect[,note] (paths "
              "relative to FOLDER) or frames,expect[,note] (frame indices or ranges of a video, "
              "run folder, image sequence or Donkeycar tub). Default: FOLDER/labels.csv or "
              "the lane/ and no-lane/ sub-folders, whichever FOLDER has (with both, name "
              "the labels with --labels).")
@click.option("--calibration", "calibration_path",
              type=PathFlag("a calibration file", dir_okay=False, exists=True), default=None,
              metavar="FILE", help="Camera calibration (default: a run folder's own, else none).")
@config_option
@click.option("--out", "out_dir", type=PathFlag("a folder", file_okay=False), default=None,
              metavar="DIR",
              help="Output directory for report.html and survey.json (default: "
              "lanewarden-out/survey-<folder name>).")
@click.option("--json", "as_json", is_flag=True,
              help="Print survey.json on stdout instead of the text summary.")
@click.option("--jitter", type=WholeRange(0, MAX_JITTER), default=0, metavar="N",
              help="Also judge every no-lane still in N versions shifted by a random fraction "
              "of a pixel (seeded), as the camera's next frame might show it; a decision on any "
              "of them is a false lane. Stills only. Default 0.")
def survey_command(folder: str, labels_path: str | None, calibration_path: str | None,
                   config_path: str | None, out_dir: str | None, as_json: bool,
                   jitter: int) -> int:
    """Judge this camera on this floor before it drives: perception on frames labelled lane
    (two tapes) or none (bare floor, seams, one tape, a tape's end, clutter, a dark frame), and
    the real supervisor on the lane frames. Prints per class the frames with a decision, the
    confident ones, the false lanes (a decision on a no-lane frame), the weakest confidence
    components and the longest runs of confident frames; the verdict, SAFE or NOT SAFE, and
    whether the supervisor engages; when NOT SAFE, what a stricter setting makes of the same
    frames. Exit 0 when SAFE, 3 when NOT SAFE."""
    from lanewarden.config import load_config
    from lanewarden.image_files import read_image
    from lanewarden.perception.detector import too_small
    from lanewarden.replay import check_preparation
    from lanewarden.replay_sources import replay_config, usable_calibration
    from lanewarden.survey_source import open_survey_source

    config = load_config(config_path)
    config_origin = config_path or "defaults"
    source = open_survey_source(folder, labels_path, 1.0 / config.supervisor.camera_period_s,
                                config.perception.max_image_pixels)
    if jitter and source.sequence is not None:
        raise UsageError(f"--jitter {jitter}: shifts stills (class folders or a labels file of "
                         f"images); '{folder}' is a recording, whose frames already differ from "
                         "one to the next: survey it without --jitter")
    if source.sequence is not None:
        config = replay_config(source.sequence, config_path)
        config_origin = source.sequence.config_origin
    calibration = usable_calibration(
        calibration_path, None if source.sequence is None else source.sequence.calibration,
        config.calibration, "--calibration of the recording")
    if source.sequence is not None:
        # a run folder holds perception's prepared input: refused, as replay refuses it, when
        # --config or --calibration would prepare frames otherwise (its figures would be the
        # recording's camera's, not the one named)
        check_preparation(source.sequence, config, calibration, command="survey",
                          config_path=config_path, calibration_path=calibration_path)
    frames = ([s.frame for s in source.stills] if source.sequence is None
              else list(source.labelled.values()))
    _refuse_a_missing_class(folder, source, frames)
    # the frames' own size (the first frame's: a survey's stills are of one size), for the
    # ground model as detect describes it, and to check the calibration before any work
    first = (source.sequence.frames.image(0) if source.sequence is not None
             else read_image(source.stills[0].path, max_pixels=config.perception.max_image_pixels
                             )[0])
    size = None if first is None else (first.shape[1], first.shape[0])
    example = source.stills[0].frame.name if source.sequence is None else "frame 0"
    if size is not None and (why := too_small(*size)):
        raise InputFileError(f"FOLDER '{folder}': {example}: {why}")
    if calibration is not None and size is not None and size != calibration.image_size:
        named = (f"--calibration '{calibration_path}'" if calibration_path
                 else "the recording's calibration")
        raise UsageError(f"{named}: for {calibration.image_size[0]}x{calibration.image_size[1]} "
                         f"images, the frames are {size[0]}x{size[1]} ({example}); expected the "
                         "calibration of the camera that took them, at their size")
    out = Path(out_dir) if out_dir else Path("lanewarden-out") / f"survey-{source.name}"
    _refuse_out_among_inputs(out, folder, source, flag=out_dir is not None)
    made = not out.exists()
    create_output_folder(out, writes="survey")
    try:
        return _survey_into(out, folder, source, config, config_origin, calibration,
                            calibration_path, size, as_json, jitter, partial(
                                open_survey_source, folder, labels_path,
                                1.0 / config.supervisor.camera_period_s,
                                config.perception.max_image_pixels))
    except BaseException:
        if made:  # a survey that fails leaves no empty folder behind (nothing was written)
            with contextlib.suppress(OSError):
                out.rmdir()
        raise


#: Why a survey needs frames of each class, and what such a frame shows.
NEEDED = {
    "none": ("a survey shows that perception sees no lane on bare floor, seams, one tape alone, "
             "a tape's end"),
    "lane": "a survey also shows that perception finds your lane and the supervisor engages on it",
}


def _refuse_a_missing_class(folder: str, source: SurveySource,
                            frames: list[LabelledFrame]) -> None:
    """UsageError when no frame is of one class, in the words of how the frames were labelled:
    the class folder to fill, or the label the labels file lacks (with a row's form)."""
    from lanewarden.survey import CLASS_FOLDERS, EXPECTS

    for expect in EXPECTS:
        if any(f.expect == expect for f in frames):
            continue
        title = CLASS_FOLDERS[expect]
        if source.labels is None:
            raise UsageError(f"FOLDER '{folder}': no {title} frame; {NEEDED[expect]}: put such "
                             f"photos in {title}/")
        row = "120-180" if source.sequence is not None else "photo.jpg"
        raise UsageError(f"{source.labels}: no frame labelled {expect}; {NEEDED[expect]}: "
                         f"expected at least one row labelling such frames {expect} (e.g. "
                         f"{row},{expect})")


def _refuse_out_among_inputs(out: Path, folder: str, source: SurveySource, flag: bool) -> None:
    """UsageError when OUT lies where the survey's outputs would be taken for its input the next
    time: in a class folder (report.html under no-lane/ is then 'not an image the survey
    reads'), or in a recording's folder of frames, tub or run (a folder of frames holding a
    report.html is then refused as a sim output folder), as replay refuses it. `flag`: OUT was
    given with --out (else it is the default, named so)."""
    from lanewarden.commands.output_folders import lies_within, source_folder
    from lanewarden.survey import CLASS_FOLDERS

    if source.sequence is None:
        inputs = [Path(folder) / name for name in CLASS_FOLDERS.values()]
    else:  # a recording's folder of frames, tub or run, a glob's folder; a video's is no input
        read_from = source_folder(folder)
        inputs = [] if read_from is None else [read_from]
    for inside in inputs:
        if lies_within(out, inside):
            named = (f"--out '{out}'" if flag else f"the default output folder '{out}' "
                     "(give --out, or run the survey from another folder)")
            raise UsageError(f"{named}: inside {inside}, where the survey's report.html and "
                             "survey.json would be read as input the next time; expected a "
                             "folder outside it")


def _survey_into(out: Path, folder: str, source: SurveySource, config: LanewardenConfig,
                 config_origin: str, calibration: CameraCalibration | None,
                 calibration_path: str | None, size: tuple[int, int] | None,
                 as_json: bool, jitter: int, reopen: Callable[[], SurveySource]) -> int:
    """The survey proper, once its inputs passed their checks: into the output folder `out`.
    `reopen`: opens the source again, for a recording surveyed a second time (a stricter setting
    tried on its frames)."""
    from lanewarden.documents import shorten
    from lanewarden.perception.calibration import Undistorter
    from lanewarden.perception.detector import LaneDetector
    from lanewarden.perception.errors import PerceptionConfigError
    from lanewarden.scenarios.camera_clip import clip_calibration_hint
    from lanewarden.scenarios.progress import Progress
    from lanewarden.survey import (
        WhatIf,
        false_lanes_named,
        judge,
        summary_lines,
        survey_notes,
        what_if_lines,
    )
    from lanewarden.survey_report import OUTPUTS, write_outputs
    from lanewarden.survey_run import SurveyRun, survey_sequence, survey_stills
    from lanewarden.wording import counted, first_few

    try:
        for name in OUTPUTS:  # a failed survey leaves no stale verdict behind
            (out / name).unlink(missing_ok=True)
    except OSError as exc:
        raise OutputError(f"--out '{out}': cannot replace old outputs ({exc.strerror or exc})"
                          ) from exc
    try:  # a folder the outputs cannot be written into is found now, not after all the work
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise OutputError(f"--out '{out}': cannot write there ({exc.strerror or exc})") from exc
    try:
        detector = LaneDetector(config.perception,
                                Undistorter(calibration) if calibration is not None else None)
    except PerceptionConfigError as exc:
        raise ConfigError(str(exc)) from None
    named = calibration_path or ("the recording's calibration" if calibration else None)
    try:
        ground = detector.describe_ground(named, size)
    except PerceptionConfigError as exc:
        raise ConfigError(str(exc)) from None
    click.echo(f"lanewarden: {ground}" if as_json else ground, err=as_json)
    total = len(source.stills) if source.sequence is None else (
        max(source.labelled) - min(source.labelled) + 1)
    # on stderr as the other long commands: a bar on a terminal (wiped at the end: the figures
    # follow), else a line every few seconds
    def surveyed(frames: SurveySource, with_config: LanewardenConfig, surveyor: LaneDetector,
                 what: str) -> SurveyRun:
        with Progress(total, what, "frames", leave=False) as bar:
            if frames.sequence is None:
                return survey_stills(frames.stills, with_config, calibration, surveyor,
                                     bar.update, jitter, size)
            return survey_sequence(frames, with_config, calibration, surveyor, bar.update, size)

    run = surveyed(source, config, detector, "survey")
    figures = judge(run.results, run.engage)
    what_ifs: list[WhatIf] = []
    for setting, stricter in ([] if figures.verdict.safe else _stricter_configs(config)):
        # a recording's frames are read once: opened again (stills are files, read again)
        again = source if source.sequence is None else reopen()
        tried = surveyed(again, stricter, LaneDetector(stricter.perception, detector.undistorter),
                         f"survey with {setting.key} {setting.value:g}")
        what_ifs.append(WhatIf(setting, judge(tried.results, tried.engage)))
    # what a survey.json read months later needs to stand alone: which lanewarden, when
    about = {"source": folder, "labelled": source.description, "config": config_origin,
             "calibration": calibration_path or ("the recording's" if calibration else "none"),
             "ground_model": ground, "jitter": jitter, "lanewarden": __version__,
             "surveyed": dt.datetime.now(dt.UTC).isoformat(timespec="seconds")}
    notes = survey_notes(figures, calibration is not None,
                         calibration is None or calibration.ground is not None,
                         f"--calibration {calibration_path}" if calibration_path
                         else "the recording's calibration",
                         "" if calibration is not None else clip_calibration_hint(folder))
    if source.unlabelled:
        some = first_few([shorten(name) for name in source.unlabelled[:4]])
        notes.append(f"note: {counted(len(source.unlabelled), 'image')} in {folder} not in the "
                     f"labels file, not surveyed ({some})")
    if source.hidden:
        some = first_few([shorten(name) for name in source.hidden[:4]])
        notes.append(f"note: {counted(len(source.hidden), 'image')} in hidden files or folders "
                     f"under lane/ and no-lane/ skipped, not surveyed ({some})")
    if source.skipped:
        notes.append(f"note: {counted(len(source.skipped), 'labelled frame')} not in the "
                     f"recording, not surveyed (dropped or skipped while recording: frame "
                     f"{source.skipped[0]}{', ...' if len(source.skipped) > 1 else ''})")
    document = write_outputs(out, figures, about, run.false_lane_pictures, run.weak_pictures,
                             notes, what_ifs, config.model_dump(mode="json"))
    if as_json:
        click.echo(json.dumps(document))
    else:
        for line in summary_lines(figures):
            click.echo(line)
        for what_if in what_ifs:
            for line in what_if_lines(what_if, figures):
                click.echo(line)
    for note in notes:
        click.echo(note, err=as_json)
    click.echo(f"outputs in {out}/ (report: {out / 'report.html'})", err=as_json)
    verdict = figures.verdict
    if not verdict.safe:
        click.echo(f"lanewarden: not safe: {false_lanes_named(verdict.false_lanes)}", err=True)
        return EXIT_SAFETY_STOP
    return EXIT_OK


def _stricter_configs(config: LanewardenConfig) -> list[tuple[StricterSetting, LanewardenConfig]]:
    """Each stricter setting a NOT SAFE survey tries (`survey.STRICTER_SETTINGS`) that `config`
    does not already have, with `config` changed by it."""
    from lanewarden.scenarios.spec import with_overrides
    from lanewarden.survey import STRICTER_SETTINGS

    tried = []
    for setting in STRICTER_SETTINGS:
        stricter = with_overrides(config, setting.nested(), "survey.STRICTER_SETTINGS")
        if stricter != config:
            tried.append((setting, stricter))
    return tried


def commands() -> list[click.Command]:
    return [survey_command]
