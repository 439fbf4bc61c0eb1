"""Where commands write: every `--out` folder (or the folder of an `--out` file) is created with
any missing parents, the same way for every command.

A path that exists as the wrong kind (a file where a folder is wanted, or the reverse) is bad
input (UsageError, exit 2); so is a run's recording folder, which no command writes into (`sim`
and `replay` had written their run.jsonl over a format-1 recording's own); a folder that cannot
be created is an I/O failure (OSError from the system, reported as a one-line error, exit 1).
"""

from __future__ import annotations

from pathlib import Path

from lanewarden.documents import dangling_link
from lanewarden.errors import Interrupted, OutputError, UsageError
from lanewarden.output_files import unreplaceable
from lanewarden.scenarios.output_folder import PARTIAL


def refuse_a_recording_folder(folder: Path, flag: str = "--out",
                              given: Path | None = None) -> None:
    """UsageError when `folder` holds a run's recording (run.mcap, as `run --record` writes, or
    a format-1 recording's meta.json beside its run.jsonl and frames/): a command would write
    its outputs among the recording's files. `given`: the file the flag named in `folder` (a
    calibration's --out), named in the line."""
    from lanewarden.recording import RUN_MCAP  # (the recorder: imported only when writing)

    held = [name for name in (RUN_MCAP, "meta.json") if (folder / name).is_file()]
    if held:
        where = f"'{folder}': holds" if given is None else f"'{given}': its folder holds"
        raise UsageError(f"{flag} {where} a recording ({', '.join(held)}); recording folders "
                         "are never written into: expected another folder")


#: What each command leaves in its --out folder, by the file that tells it: (the file, what it
#: is). `sim` and `replay` write the same outputs (a run's).
OUTPUT_KINDS: dict[str, tuple[str, str]] = {
    "campaign": ("results.sqlite", "a campaign's results"),
    "run": ("metrics.json", "a simulated or replayed run's outputs"),
    "demo": ("supervised/metrics.json", "the demo's outputs"),
    "survey": ("survey.json", "a survey's outputs"),
}


def refuse_another_commands_folder(folder: Path, writes: str, flag: str = "--out") -> None:
    """UsageError when `folder` holds another command's outputs (OUTPUT_KINDS) than the kind
    this one `writes`: `sim --out` into a campaign's folder had replaced its report.html without
    a word, and `campaign --out` a run's (a safety reviewer's review). A folder of the same kind
    is replaced, as each command's help says."""
    for kind, (marker, what) in OUTPUT_KINDS.items():
        if kind != writes and (folder / marker).is_file():
            raise UsageError(f"{flag} '{folder}': holds {what} ({marker}), which these outputs "
                             "would mix with or replace; expected a new folder, or one this "
                             "command wrote before")


def create_output_folder(folder: Path, flag: str = "--out", writes: str | None = None) -> Path:
    """`folder`, created with its missing parents; UsageError if it exists and is not a folder
    (a file, a FIFO, a device), is a link to nothing, holds a recording or (`writes`: the kind
    of outputs the command writes, OUTPUT_KINDS) another command's outputs."""
    refuse_a_recording_folder(folder, flag)
    if writes is not None:
        refuse_another_commands_folder(folder, writes, flag)
    if link := dangling_link(folder):
        raise UsageError(f"{flag} '{folder}': {link}; expected a folder")
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{flag} '{folder}': exists and is not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise UsageError(
            f"{flag} '{folder}': a part of this path exists and is not a folder") from None
    except OSError as exc:
        raise OutputError(
            f"{flag} '{folder}': cannot create the folder ({exc.strerror or exc})") from exc
    return folder


def interrupted_in(out: Path) -> Interrupted:
    """Ctrl-C while `out` (an `OutputFolder`'s, with its PARTIAL marker) was being written: the
    one line names the marker, as `sim`, `demo` and `replay` say it."""
    return Interrupted(f"{out / PARTIAL} lists the outputs left incomplete")


def create_output_file_folder(file: Path, flag: str = "--out") -> Path:
    """`file`, after creating its folder; UsageError if `file` is a folder, a FIFO, socket or
    device (`output_files.unreplaceable`: `calibrate --out /dev/null` had replaced the device)."""
    if why := unreplaceable(file):
        raise UsageError(f"{flag} '{file}': {why}")
    refuse_a_recording_folder(file.parent, flag, given=file)
    create_output_folder(file.parent, flag)
    return file


def source_folder(source: str) -> Path | None:
    """The folder a SOURCE argument reads from: SOURCE itself when it is a folder, a glob's
    folder, None for a file (a video)."""
    given = Path(source)
    if given.is_dir():
        return given
    return given.parent if any(c in source for c in "*?[") else None


def lies_within(path: Path, folder: Path) -> bool:
    """Is `path` `folder` itself or inside it (both resolved)? False when either cannot be
    resolved (creating the output folder then says why)."""
    try:
        where, inside = path.resolve(), folder.resolve()
    except OSError:
        return False
    return where == inside or inside in where.parents
