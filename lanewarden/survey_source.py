"""Where a survey's labelled frames come from: class folders, a labels file, or a recording.

`open_survey_source(FOLDER, labels)` recognises:
- FOLDER with the class folders `lane/` and/or `no-lane/`: the images in each (natural name
  order; then those of its sub-folders, such as `no-lane/seams/`), labelled by the class folder
  they are under; another sub-folder holding images is an error (an unknown label), so a
  misspelt `nolane/` is not silently left out, and so are images beside the class folders;
  hidden files and folders under a class folder (`.DS_Store`, `.thumbs/`) are skipped alike, and
  the images among them counted (`SurveySource.hidden`: the command names them in a note);
- FOLDER with a `labels.csv` (or `--labels FILE` naming one): `file,expect[,note]` rows name
  images by their path relative to FOLDER; the rows' order is the sequence order;
- a recording with `--labels FILE` of `frames,expect[,note]` rows (a frame index or an inclusive
  range `120-340`): a video, a folder or glob of images, a run folder (`lanewarden run --record`)
  or a Donkeycar tub, opened by `lanewarden.replay_sources.open_replay_source`, so every source
  replay knows is a source a survey knows. Frame indices are the recording's own (a run
  folder's frame numbers; a video's frames, a tub's records and an image sequence's files
  counted from 0).

Bounded: a labels file larger than `survey.MAX_LABELS_BYTES` is refused unread; image files are
checked against `perception.max_image_pixels` from their header before decoding (by
`lanewarden.image_files`, as `detect` does). Every problem is one `InputFileError`/`UsageError`
line naming the file (and line) and the value. Reads files, never decodes a video here, never
prints.
"""

from __future__ import annotations

import difflib
import os
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from lanewarden.camera_source import image_sequence_paths
from lanewarden.documents import NOT_A_REGULAR_FILE, is_special_file, leads_outside
from lanewarden.errors import InputFileError, UsageError
from lanewarden.image_files import IMAGE_SUFFIXES, file_problem, header_facts, read_image
from lanewarden.replay_sources import (
    RUN_MCAP,
    SOURCE_HELP,
    PathFrames,
    ReplaySource,
    frame_name,
    open_replay_source,
    recording_kind,
)
from lanewarden.survey import (
    CLASS_FOLDERS,
    MAX_LABELS_BYTES,
    LabelledFrame,
    LabelsTable,
    parse_labels,
    quoted,
)
from lanewarden.wording import counted, first_few, shown_name

LABELS_NAME = "labels.csv"
FOLDER_HELP = (f"a folder with lane/ and no-lane/ sub-folders of images, or with a {LABELS_NAME}"
               f" (file,expect[,note]); or {SOURCE_HELP} with --labels FILE (frames,expect"
               "[,note])")
#: Bad files named in one error line before "and N more".
PROBLEMS_SHOWN = 10


@dataclass(frozen=True)
class StillFrame:
    frame: LabelledFrame
    path: Path


@dataclass
class SurveySource:
    """What to survey: `stills` (independent images) or `sequence` (a recording, with the
    labelled frames by the recording's frame index in `labelled`). `unlabelled`: images in a
    labels file's folder that it does not name, `skipped`: frame indices within labelled ranges
    that the recording lacks, `hidden`: images under the class folders in hidden files or
    folders (none of these surveyed; the command says so). `labels`: the labels file as messages
    name it ("--labels 'clip.csv'", "floor/labels.csv"; None: class folders)."""

    name: str
    description: str
    stills: list[StillFrame] = field(default_factory=list)
    sequence: ReplaySource | None = None
    labelled: dict[int, LabelledFrame] = field(default_factory=dict)
    unlabelled: list[str] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    hidden: list[str] = field(default_factory=list)
    labels: str | None = None


def problems_line(what: str, total: int, problems: list[str]) -> str:
    """'2 of 19 frames cannot be used: a: why; b: why' (at most PROBLEMS_SHOWN named)."""
    shown = "; ".join(problems[:PROBLEMS_SHOWN])
    more = (f"; and {len(problems) - PROBLEMS_SHOWN} more" if len(problems) > PROBLEMS_SHOWN
            else "")
    return f"{len(problems)} of {total} {what}: {shown}{more}"


def labels_named(path: Path, flag: bool) -> str:
    """The labels file as messages name it (`flag`: given with --labels, else FOLDER's own
    labels.csv)."""
    return f"--labels '{path}'" if flag else str(path)


def read_labels(path: Path, flag: bool = True) -> LabelsTable:
    """The labels file at `path` (`flag`: named with --labels, else FOLDER's own labels.csv),
    refused unread above MAX_LABELS_BYTES."""
    named = labels_named(path, flag)
    if is_special_file(path):
        raise InputFileError(f"{named}: {NOT_A_REGULAR_FILE}, expected a labels file")
    try:
        with path.open("rb") as handle:
            data = handle.read(MAX_LABELS_BYTES + 1)
    except FileNotFoundError:
        raise InputFileError(f"{named}: no such file") from None
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if len(data) > MAX_LABELS_BYTES:
        raise InputFileError(f"{path}: larger than {MAX_LABELS_BYTES} bytes; a labels file is "
                             "one short line per image or frame range")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    return parse_labels(text, str(path))


def _class_folders(folder: Path) -> tuple[list[StillFrame], list[str]]:
    """The images of FOLDER/lane and FOLDER/no-lane, their sub-folders included (a user may sort
    no-lane/ into seams/, one-tape/, ...: every image under a class folder is of that class);
    an unknown sub-folder of images, or images beside the class folders, is an error: a frame
    the survey cannot label is never silently left out. Also the images skipped as hidden (a
    hidden file, or any file in a hidden folder, under a class folder), named relative to
    FOLDER."""
    by_folder = {name: expect for expect, name in CLASS_FOLDERS.items()}
    inside = folder.resolve()
    stills: list[StillFrame] = []
    hidden: list[str] = []
    subs = sorted(p for p in folder.iterdir() if p.is_dir())
    loose = image_sequence_paths(str(folder)) or []
    if loose and any(sub.name in by_folder for sub in subs):
        names = first_few([p.name for p in loose])
        raise UsageError(f"FOLDER '{folder}': {counted(len(loose), 'image')} beside lane/ and "
                         "no-lane/ "
                         f"({names}); expected every image in lane/ or no-lane/ (or a "
                         f"{LABELS_NAME})")
    for sub in subs:
        if sub.name not in by_folder and is_hidden(sub):
            continue  # .git/, .thumbs/ beside the class folders: no class, nothing to survey
        if sub.name in by_folder:
            _refuse_a_link_outside(sub, inside)  # lane -> /elsewhere: not the survey's photos
        # other folders beside them (docs/ of notes) are looked into only for images: images
        # there may be a misnamed class folder
        paths, skipped = _images_under(sub, inside, others_allowed=sub.name not in by_folder)
        if sub.name not in by_folder:
            if paths:
                close = difflib.get_close_matches(sub.name, list(by_folder), n=1, cutoff=0.5)
                hint = f" (did you mean {close[0]}/?)" if close else ""
                raise UsageError(f"{sub}: unknown class folder '{sub.name}' with "
                                 f"{counted(len(paths), 'image')}; expected lane/ or "
                                 f"no-lane/{hint}")
            continue
        hidden.extend(shown_name(path.relative_to(folder).as_posix()) for path in skipped)
        for path in paths:
            name = shown_name(path.relative_to(folder).as_posix())
            stills.append(StillFrame(LabelledFrame(name, by_folder[sub.name], 0), path))
    order = {"lane": 0, "none": 1}
    stills.sort(key=lambda s: order[s.frame.expect])  # stable: name order within a class
    seen: dict[tuple[int, int], str] = {}
    for still in stills:
        if (same := _same_file(still.path, still.frame.name, seen)) is not None:
            raise InputFileError(f"{folder}: {still.frame.name} is the same file as {same} (a "
                                 "link, or a hard link); expected each photo once, in lane/ or "
                                 "no-lane/")
    return [StillFrame(LabelledFrame(s.frame.name, s.frame.expect, i), s.path)
            for i, s in enumerate(stills)], hidden


def _same_file(path: Path, name: str, seen: dict[tuple[int, int], str]) -> str | None:
    """The name under which the file at `path` was seen before (`seen`: by device and inode, so
    a link or a hard link to it, or a path through a linked folder, is the same file), else
    None, remembering it as `name`. A file that cannot be looked at is left to the checks that
    say why."""
    try:
        info = path.stat()
    except (OSError, ValueError):
        return None
    key = (info.st_dev, info.st_ino)
    if key in seen:
        return seen[key]
    seen[key] = name
    return None


#: Files an operating system leaves in a folder of photos (Windows' thumbnail caches and folder
#: settings), passed over like hidden files (macOS's .DS_Store): no photo of a class.
SYSTEM_FILES = frozenset({"thumbs.db", "ehthumbs.db", "ehthumbs_vista.db", "desktop.ini"})


def is_hidden(path: Path) -> bool:
    """A hidden file or folder (its name starts with a dot: .DS_Store, macOS's ._IMG_0001.jpg
    beside a copied photo, .thumbs/, .git/)."""
    return path.name.startswith(".")


def _refuse_a_link_outside(path: Path, inside: Path) -> None:
    """InputFileError when `path` is a link that leads out of `inside` (the survey's FOLDER,
    resolved): a class folder, a folder under one or a photo, all by one rule (a linked photo or
    class folder leading out had been surveyed without a word, a linked sub-folder refused). A
    link inside FOLDER is followed."""
    if path.is_symlink() and leads_outside(path, inside):
        target = shown_name(str(path.resolve()))
        raise InputFileError(f"{shown_name(str(path))}: a link to {target}, outside {inside}; "
                             "expected the survey's photos inside its folder (copy them in)")


def _images_under(folder: Path, inside: Path, others_allowed: bool = False
                  ) -> tuple[list[Path], list[Path]]:
    """The images in `folder` (natural name order), then those of its sub-folders, each in
    turn, in name order; and the images skipped as hidden: hidden files, and every image in a
    hidden folder (such as .thumbs/ or .git/), walked only to count them (a folder reached
    twice through a link is read once, so a link loop ends). A loop over a stack, not
    recursion: a folder nested thousands deep is walked, not a RecursionError; an unreadable
    folder is one line. A file that is not an image is an error (a photo the survey cannot
    read), unless `others_allowed` (a folder beside the class folders: only its images
    matter). A link to a photo or a folder (one that is walked: not hidden, not beside the class
    folders) must lead inside `inside`, the survey's FOLDER resolved (`_refuse_a_link_outside`)."""
    paths: list[Path] = []
    skipped: list[Path] = []
    seen: set[tuple[int, int]] = set()  # (device, inode): one stat, not a walk of the path
    stack = [(folder, False)]
    while stack:
        here, in_hidden = stack.pop()
        try:
            info = here.stat()
            if (info.st_dev, info.st_ino) in seen:
                continue
            seen.add((info.st_dev, info.st_ino))
            for image in image_sequence_paths(str(here)) or []:
                surveyed = not (in_hidden or is_hidden(image))
                if surveyed and not others_allowed:
                    _refuse_a_link_outside(image, inside)
                (paths if surveyed else skipped).append(image)
            others = [] if in_hidden or others_allowed else sorted(
                p for p in here.iterdir() if not is_hidden(p)
                and p.name.lower() not in SYSTEM_FILES
                and p.suffix.lower() not in IMAGE_SUFFIXES and p.is_file())
            subs = sorted(p for p in here.iterdir() if p.is_dir())
        except OSError as exc:
            raise InputFileError(f"{here}: cannot read this folder ({exc.strerror or exc})"
                                 ) from None
        if others:
            # a photo the survey cannot read (HEIC from a phone, a GIF) is never silently left
            # out: the survey would judge fewer frames than the user put there, or none
            more = f" and {counted(len(others) - 1, 'other file')}" if len(others) > 1 else ""
            raise InputFileError(
                f"{shown_name(str(others[0]))}{more}: not an image the survey reads (a file "
                "under a class folder is a photo of that class); expected "
                f"{', '.join(sorted(IMAGE_SUFFIXES))}: convert them, or move other files out of "
                "lane/ and no-lane/")
        # a link in a hidden folder, or a hidden link, or one in a folder beside the class
        # folders, is not followed: those are walked only to count or find images, and a link
        # there is nobody's photo (a link to /tmp in no-lane/.thumbs/ had refused the survey)
        subs = [sub for sub in subs if not (sub.is_symlink() and (
            in_hidden or others_allowed or is_hidden(sub)))]
        for sub in subs:
            _refuse_a_link_outside(sub, inside)
        # the first in name order is walked next
        stack.extend((sub, in_hidden or is_hidden(sub)) for sub in reversed(subs))
    return paths, skipped


def _labelled_files(folder: Path, table: LabelsTable) -> list[StillFrame]:
    stills = []
    seen: dict[tuple[int, int], str] = {}
    for order, row in enumerate(table.rows):
        assert row.file is not None
        path = folder / row.file
        where = f"{table.source}:{row.line}: {quoted(row.file)}"  # no escapes sent
        if Path(row.file).is_absolute() or leads_outside(path, folder.resolve()):
            raise InputFileError(f"{where}: outside {folder}; expected a path relative to it, "
                                 "inside it")
        if why := file_problem(path):
            raise InputFileError(f"{where}: {why}{_closest_file(path, row.file)} (paths are "
                                 f"relative to {folder})")
        # 'a.jpg' and './a.jpg' (or a link to it) are one image: labelled twice
        if (same := _same_file(path, f"line {row.line}", seen)) is not None:
            raise InputFileError(f"{where}: the same file as {same}; expected each image "
                                 "labelled once")
        stills.append(StillFrame(LabelledFrame(shown_name(row.file), row.expect, order, row.note),
                                 path))
    return stills


def _closest_file(path: Path, written: str) -> str:
    """"; did you mean 'lane/a.jpg'?" for a labelled file (`path`, `written` so in the labels
    file) that is not there but whose folder holds one of a close name (a typo in labels.csv);
    '' otherwise. Only that one folder is read, at most MAX_LISTED_NAMES of its names."""
    if os.path.lexists(path):  # (there, but unreadable: a link loop, a broken link)
        return ""
    try:
        with os.scandir(path.parent) as entries:
            names = [e.name for e, _ in zip(entries, range(MAX_LISTED_NAMES), strict=False)]
    except OSError:
        return ""
    close = difflib.get_close_matches(path.name, names, n=1, cutoff=0.8)
    if not close:
        return ""
    parent = PurePosixPath(written.replace("\\", "/")).parent
    return f"; did you mean {quoted(str(parent / close[0]) if str(parent) != '.' else close[0])}?"


#: Names of a folder read at most for a labelled file's did-you-mean (`_closest_file`).
MAX_LISTED_NAMES = 10_000


#: Images looked for beyond a labels file's rows (a bound on a huge folder's walk).
UNLABELLED_SCAN_LIMIT = 100_000


def _unlabelled(folder: Path, stills: list[StillFrame]) -> list[str]:
    """Images under `folder` (hidden folders and linked folders left out) that no row names, in
    name order. A loop over a stack: Path.rglob recursed once per level, and a folder nested
    1200 deep was a RecursionError traceback."""
    named = {s.path.resolve() for s in stills}
    found = []
    stack = [folder]
    looked = 0
    while stack and looked < UNLABELLED_SCAN_LIMIT:
        here = stack.pop()
        try:
            entries = sorted(here.iterdir())
        except OSError:  # an unreadable folder: its images cannot be named anyway
            continue
        for path in entries[:UNLABELLED_SCAN_LIMIT - looked]:
            looked += 1
            if path.name.startswith("."):
                continue
            if path.is_dir() and not path.is_symlink():
                stack.append(path)
            elif (path.suffix.lower() in IMAGE_SUFFIXES and path.is_file()
                  and path.resolve() not in named):
                found.append(shown_name(path.relative_to(folder).as_posix()))
    return sorted(found)


def _labelled_frames(source: ReplaySource, table: LabelsTable
                     ) -> tuple[dict[int, LabelledFrame], list[int]]:
    """The labelled frames by the recording's frame index, and the indices within labelled
    ranges the recording lacks. A range labels the frames the recording has within it (a run
    folder may lack frames the camera dropped or the loop skipped: the command says how many); a
    frame index or a range end beyond the recording, a single frame it lacks, or a range without
    any frame, is an error naming its line."""
    available = sorted({s.frame[0] for s in source.steps if s.frame is not None})
    present = set(available)
    # sequence order: the place among the recording's frames (a dropped frame is no gap)
    position = {index: k for k, index in enumerate(available)}
    labelled: dict[int, LabelledFrame] = {}
    skipped: list[int] = []
    for row in table.rows:
        assert row.frames is not None
        first, last = row.frames
        span = f"{first}" if first == last else f"{first}-{last}"
        have = f"frames {available[0]}-{available[-1]}" if available else "no frames"
        if not available or last > available[-1] or (first == last and first not in present):
            missing = last if not available or last > available[-1] else first
            what = f"frame {first}" if first == last else f"frames {span}: frame {missing}"
            gap = ("; it has no frame there (one dropped or skipped while recording)"
                   if available and available[0] < missing < available[-1] else "")
            raise InputFileError(f"{table.source}:{row.line}: {what} is not in {source.name} "
                                 f"({source.kind}, {have}){gap}")
        inside = [i for i in range(first, last + 1) if i in present]  # last is within the source
        skipped.extend(i for i in range(first, last + 1) if i not in present)
        if not inside:
            raise InputFileError(f"{table.source}:{row.line}: frames {span}: none of these "
                                 f"frames is in {source.name} ({source.kind}, {have})")
        for index in inside:
            labelled[index] = LabelledFrame(frame_name(source, index), row.expect,
                                            position[index], row.note)
    return labelled, skipped


def _class_folder_names(path: Path) -> list[str]:
    """The class folders (lane, no-lane) `path` holds."""
    return [name for name in CLASS_FOLDERS.values() if (path / name).is_dir()]


def _name(folder: Path) -> str:
    """The folder's own name, also for '.' or '..'."""
    name = folder.name if folder.name not in ("", ".", "..") else folder.resolve().name
    return name or "folder"


def _check_headers(paths: list[tuple[str, Path]], max_pixels: int) -> None:
    """Every image within the pixel limit, and all of one size: a survey judges one camera (a
    frame of another size was another camera, or a crop, and would be judged through the wrong
    ground model)."""
    problems: list[str] = []
    sizes: dict[tuple[int, int], list[str]] = {}
    for name, path in paths:
        if why := file_problem(path):  # a FIFO: opening it to read the header waits forever
            problems.append(f"{name}: {why}")
            continue
        size, why = header_facts(path, max_pixels)  # one read of each header
        if size is None and not why:  # a format Pillow cannot tell (or no image at all): decoded
            # now, so an unreadable file is named before the survey starts, not after its work
            image, why = read_image(path, max_pixels=max_pixels)
            size = None if image is None else (image.shape[1], image.shape[0])
        if size is not None:
            sizes.setdefault(size, []).append(name)
        if why:
            problems.append(f"{name}: {why}")
    if problems:
        raise InputFileError(problems_line("frames cannot be used", len(paths), problems))
    if len(sizes) > 1:
        ranked = sorted(sizes.items(), key=lambda item: -len(item[1]))
        listed = "; ".join(f"{w}x{h}: {counted(len(names), 'frame')} ({names[0]}"
                           f"{', ...' if len(names) > 1 else ''})"
                           for (w, h), names in ranked[:4])
        raise InputFileError(f"frames of {len(sizes)} sizes ({listed}); expected every frame "
                             "from the one camera at one size (survey each camera on its own)")


def open_survey_source(folder: str, labels: str | None, camera_rate_hz: float,
                       max_pixels: int) -> SurveySource:
    """Recognise FOLDER (and --labels), see the module docstring."""
    path = Path(folder)
    labels_path = Path(labels) if labels is not None else None
    if labels_path is None:
        if not path.exists():
            raise UsageError(f"FOLDER '{folder}': no such folder; expected {FOLDER_HELP}")
        if not path.is_dir():
            raise UsageError(f"FOLDER '{folder}': a file; a video or a run needs --labels FILE "
                             f"(frames,expect[,note]); expected {FOLDER_HELP}")
        if os.path.lexists(path / LABELS_NAME):  # a broken link too: read_labels says why
            if classes := _class_folder_names(path):
                raise UsageError(f"FOLDER '{folder}': has both {LABELS_NAME} and "
                                 f"{'/ and '.join(classes)}/: keep one way of labelling, or "
                                 "name the labels with --labels")
            labels_path = path / LABELS_NAME
    if labels_path is None and (kind := recording_kind(path)) is not None:
        # (a tub's images/ had been refused as an unknown class folder, which sent a new user
        # to rename it)
        raise UsageError(f"FOLDER '{folder}': {kind}; a recording needs --labels FILE "
                         "(frames,expect[,note]: which of its frames show the lane)")
    if labels_path is None:
        stills, hidden = _class_folders(path)
        if not stills:
            # photos there, unsorted: name them, and the two ways to label them
            loose = image_sequence_paths(str(path)) or []
            there = (f" ({counted(len(loose), 'image')} there, unlabelled: "
                     f"{first_few([p.name for p in loose])}; move each into lane/ or no-lane/, "
                     f"or list them in {LABELS_NAME} as file,expect)" if loose else "")
            raise UsageError(f"FOLDER '{folder}': no images in lane/ or no-lane/ and no "
                             f"{LABELS_NAME}{there}; expected {FOLDER_HELP}")
        _check_headers([(s.frame.name, s.path) for s in stills], max_pixels)
        return SurveySource(_name(path), f"{folder} (class folders lane/, no-lane/)",
                            stills=stills, hidden=hidden)
    table = read_labels(labels_path, flag=labels is not None)
    named = labels_named(labels_path, labels is not None)
    if table.kind == "file":
        if not path.is_dir():
            raise UsageError(f"FOLDER '{folder}': {table.source} names image files, so FOLDER "
                             "must be the folder they are in")
        if (path / RUN_MCAP).is_file():  # its frames are in run.mcap, not files beside it
            raise UsageError(f"FOLDER '{folder}': a recorded run, but {table.source} labels "
                             "image files (file,expect); expected its frames by number: "
                             "frames,expect[,note] (e.g. 0-120,lane)")
        stills = _labelled_files(path, table)
        _check_headers([(s.frame.name, s.path) for s in stills], max_pixels)
        return SurveySource(_name(path), f"{folder} (labels: {table.source})",
                            stills=stills, unlabelled=_unlabelled(path, stills),
                            labels=named)
    if classes := _class_folder_names(path):
        raise UsageError(f"FOLDER '{folder}': {table.source} labels frame numbers "
                         f"(frames,expect) of a recording, but FOLDER holds "
                         f"{'/ and '.join(classes)}/ of photos: label the photos by file "
                         "(file,expect), or drop --labels")
    try:
        source = open_replay_source(folder, camera_rate_hz)
    except (UsageError, InputFileError) as exc:  # replay's SOURCE is the survey's FOLDER
        message = str(exc)
        if message.startswith("SOURCE '"):
            raise type(exc)("FOLDER '" + message.removeprefix("SOURCE '")) from None
        raise
    labelled, skipped = _labelled_frames(source, table)
    if isinstance(source.frames, PathFrames):
        first, last = min(labelled), max(labelled)
        _check_headers([(f"frame {i}", p) for i, p in enumerate(source.frames.paths)
                        if first <= i <= last], max_pixels)
    return SurveySource(source.name, f"{folder} ({source.kind}; labels: {table.source})",
                        sequence=source, labelled=labelled, skipped=skipped,
                        labels=named)
