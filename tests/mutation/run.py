"""Mutation run for the safety rules: every mutant listed in mutants.toml must be killed.

A mutant is one safety rule broken on purpose, the way the project's mutation habit asks (a
constant instead of a check, a dropped call, a flipped comparison, an off-by-one in a debounce
count, a table row demoted): a file, the exact original snippet, its replacement, and the fast
tests that must fail because of it. For each mutant, in a scratch copy of the project (the
working tree is never written), the snippet is replaced, the listed tests run in a fresh pytest,
and the file is put back. The run fails when

- a listed original snippet is not found exactly once in its file (the code changed: the list is
  stale and must be brought up to date with it; checked before anything runs),
- the listed tests fail on the unmutated code (the baseline: a kill would mean nothing),
- a mutant survives (its tests all pass: the rule is untested), or
- a mutant cannot be judged (its replacement does not compile, a listed test does not exist).

    python -m tests.mutation.run                 # all, with as many workers as CPUs (max 4)
    python -m tests.mutation.run --only ID ...   # some (ids from mutants.toml)
    python -m tests.mutation.run --jobs 1 --list # the list only, nothing run

Exit 0 when every mutant was killed, 1 otherwise (one line per problem). CI runs it after the
test suite (.ci/run). Reads the wall clock only to report how long each mutant took.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from itertools import count
from pathlib import Path
from queue import Queue

ROOT = Path(__file__).resolve().parents[2]
MUTANTS = Path(__file__).with_name("mutants.toml")
#: A mutant that makes its tests hang is killed by this timeout (seconds per mutant).
TIMEOUT_S = 300.0
PYTEST = ("-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "--no-header", "-o",
          "addopts=", "--hypothesis-profile=mutation")
_FIELDS = {"id", "file", "rule", "original", "replacement", "tests"}


@dataclass(frozen=True)
class Mutant:
    id: str
    file: str
    rule: str
    original: str
    replacement: str
    tests: tuple[str, ...]


@dataclass(frozen=True)
class Outcome:
    mutant: Mutant
    verdict: str  # "killed", "survived" or "error"
    seconds: float
    detail: str = ""


def load(path: Path = MUTANTS) -> list[Mutant]:
    """The listed mutants; ValueError (one line per problem) for a malformed list."""
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    problems: list[str] = []
    mutants: list[Mutant] = []
    for i, entry in enumerate(data.get("mutant", [])):
        where = f"{path.name}: mutant #{i + 1} ({entry.get('id', 'no id')})"
        if set(entry) != _FIELDS:
            problems.append(f"{where}: fields {sorted(entry)}, expected {sorted(_FIELDS)}")
            continue
        tests = entry["tests"]
        if not (isinstance(tests, list) and tests and all(isinstance(t, str) for t in tests)):
            problems.append(f"{where}: tests must be a non-empty list of pytest node ids")
            continue
        if entry["original"] == entry["replacement"] or not entry["original"]:
            problems.append(f"{where}: original must be non-empty and differ from replacement")
            continue
        mutants.append(Mutant(entry["id"], entry["file"], entry["rule"], entry["original"],
                              entry["replacement"], tuple(tests)))
    ids = [m.id for m in mutants]
    problems += [f"{path.name}: id {i!r} is listed twice" for i in sorted(set(ids))
                 if ids.count(i) > 1]
    if not data.get("mutant"):
        problems.append(f"{path.name}: no [[mutant]] entries")
    if problems:
        raise ValueError("\n".join(problems))
    return mutants


def stale(mutants: Sequence[Mutant], root: Path = ROOT) -> list[str]:
    """One line per mutant whose original snippet is not in its file exactly once, or whose
    mutated file would not compile."""
    problems = []
    for m in mutants:
        path = root / m.file
        if not path.is_file():
            problems.append(f"{m.id}: {m.file} does not exist")
            continue
        text = path.read_text(encoding="utf-8")
        count = text.count(m.original)
        if count != 1:
            found = "not found" if count == 0 else f"found {count} times"
            problems.append(f"{m.id}: the original snippet is {found} in {m.file} (the code "
                            f"changed: update tests/mutation/mutants.toml): {_head(m.original)}")
            continue
        try:
            compile(text.replace(m.original, m.replacement), str(path), "exec")
        except SyntaxError as exc:
            problems.append(f"{m.id}: the mutated {m.file} does not compile ({exc.msg}, line "
                            f"{exc.lineno})")
    return problems


def _head(snippet: str) -> str:
    line = snippet.strip().splitlines()[0] if snippet.strip() else ""
    return line if len(line) <= 60 else line[:57] + "..."


#: Never copied when the project is not a git checkout (no .gitignore to ask).
_NOT_PROJECT = {".git", ".venv", "__pycache__", ".hypothesis", ".pytest_cache", ".mypy_cache",
                ".ruff_cache", "build", "dist", "lanewarden-out"}


def project_files(root: Path) -> list[str]:
    """The project's files as git sees them (tracked, plus new files not ignored); outside a git
    checkout, every file but caches, build output and virtual environments."""
    try:
        listed = subprocess.run(
            ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
            cwd=root, capture_output=True, check=True,
        ).stdout.decode().split("\0")
    except (OSError, subprocess.CalledProcessError):
        listed = []
        for folder, dirs, files in os.walk(root):
            dirs[:] = [d for d in dirs if d not in _NOT_PROJECT and not d.endswith(".egg-info")]
            listed += [os.path.relpath(os.path.join(folder, f), root) for f in files
                       if f not in _NOT_PROJECT]
    return sorted({f for f in listed if f and os.path.lexists(root / f)})


#: The layers setuptools maps into the package (pyproject's package-dir: lanewarden.<layer> is
#: <layer>/). PYTHONPATH cannot express that mapping, so the scratch copy gets the links
#: lanewarden/<layer> -> ../<layer> (scratch only: the project itself has no symlinks).
LAYERS = ("perception", "supervisor", "actuation", "scenarios")


def make_copy(root: Path, files: Sequence[str], into: Path) -> None:
    """Copy `files` under `into`, and link each layer into the copy's package."""
    for name in files:
        src, dst = root / name, into / name
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_symlink():
            os.symlink(os.readlink(src), dst)
        else:
            shutil.copy2(src, dst)
    for layer in LAYERS:
        link = into / "lanewarden" / layer
        if (into / layer).is_dir() and not os.path.lexists(link):
            os.symlink(os.path.join("..", layer), link)


def _environment(copy: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(copy), *filter(None, [env.get("PYTHONPATH")])])
    # The tests find the shared data beside the project; the copy has no such neighbour.
    if not env.get("LANEWARDEN_DATA", "").strip():
        env["LANEWARDEN_DATA"] = str(ROOT.parent / "shared" / "data")
    env.pop("PYTEST_ADDOPTS", None)
    return env


def check_copy_is_imported(copy: Path) -> None:
    """The tests in a copy must import the copy's code, not the installed (editable) one."""
    probe = subprocess.run(
        [sys.executable, "-c",
         "import lanewarden.supervisor.gate as g, pathlib; print(pathlib.Path(g.__file__))"],
        cwd=copy, env=_environment(copy), capture_output=True, text=True, check=False,
    )
    where = probe.stdout.strip()
    if probe.returncode != 0 or not where.startswith(str(copy)):
        raise RuntimeError(f"tests in the scratch copy import lanewarden from {where or '?'} "
                           f"instead of {copy} ({probe.stderr.strip()[-200:]})")


#: The pytest processes running now (killed when the run is interrupted).
_RUNNING: set[subprocess.Popen[str]] = set()


def run_tests(copy: Path, tests: Sequence[str]) -> tuple[int | None, str, bool]:
    """(pytest's exit code or None for a timeout, its last output line, whether a test module
    failed to import)."""
    with subprocess.Popen([sys.executable, *PYTEST, *tests], cwd=copy, env=_environment(copy),
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) as process:
        _RUNNING.add(process)
        try:
            stdout, stderr = process.communicate(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            return None, f"timed out after {TIMEOUT_S:g} s", False
        finally:
            _RUNNING.discard(process)
    lines = [line for line in stdout.splitlines() if line.strip()]
    return (process.returncode, lines[-1] if lines else stderr.strip()[-200:],
            "ERROR collecting" in stdout)


def _interrupted(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


#: Whole seconds, each used once (`next` on a count is atomic: the workers share it).
_MTIMES = count(int(time.time()) - 10_000_000, 2)


def _write(path: Path, text: str) -> None:
    """Write `text` and give the file an mtime it never had: a stale .pyc (matched on mtime and
    size) of the original or of another mutant of the same size can never be used."""
    path.write_text(text, encoding="utf-8")
    mtime = next(_MTIMES)
    os.utime(path, (mtime, mtime))


def judge(mutant: Mutant, copy: Path) -> Outcome:
    """Apply `mutant` in `copy`, run its tests, put the file back."""
    path = copy / mutant.file
    original = path.read_text(encoding="utf-8")
    started = time.monotonic()
    try:
        _write(path, original.replace(mutant.original, mutant.replacement, 1))
        code, last, collection_failed = run_tests(copy, mutant.tests)
    finally:
        _write(path, original)
    seconds = time.monotonic() - started
    if code is None or code in (1, 2) or (code == 4 and collection_failed):
        # failed; or a test module failed to import (an import-time check refused the mutant;
        # the baseline imported it), which pytest reports as 4 for a node id in that module
        return Outcome(mutant, "killed", seconds, last)
    if code == 0:
        return Outcome(mutant, "survived", seconds, last)
    return Outcome(mutant, "error", seconds, f"pytest exit {code}: {last}")


@contextmanager
def scratch_copies(count: int) -> Iterator[list[Path]]:
    files = project_files(ROOT)
    with tempfile.TemporaryDirectory(prefix="lanewarden-mutants-",
                                     ignore_cleanup_errors=True) as tmp:
        copies = []
        for k in range(count):
            copy = Path(tmp) / f"copy{k}"
            make_copy(ROOT, files, copy)
            copies.append(copy)
        yield copies


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", metavar="ID", help="run only these mutants")
    parser.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1),
                        help="mutants judged at once (one scratch copy each)")
    parser.add_argument("--list", action="store_true",
                        help="check the list against the code and print it; run nothing")
    parser.add_argument("--no-baseline", action="store_true",
                        help="skip running the listed tests on the unmutated code first")
    args = parser.parse_args(argv)
    try:
        mutants = load()
    except ValueError as exc:
        print(f"mutants: {exc}", file=sys.stderr)
        return 1
    if args.only:
        unknown = sorted(set(args.only) - {m.id for m in mutants})
        if unknown:
            print(f"mutants: --only: unknown id(s) {', '.join(unknown)}", file=sys.stderr)
            return 1
        mutants = [m for m in mutants if m.id in args.only]
    problems = stale(mutants)
    if problems:
        for line in problems:
            print(f"mutants: stale: {line}", file=sys.stderr)
        return 1
    if args.list:
        for m in mutants:
            print(f"{m.id:40} {m.file:32} {m.rule}")
        print(f"mutants: {len(mutants)} listed, every original snippet found once")
        return 0
    signal.signal(signal.SIGTERM, _interrupted)
    try:
        return _run(mutants, args.jobs, baseline=not args.no_baseline)
    except KeyboardInterrupt:
        for process in list(_RUNNING):  # the baseline's, if it was running
            process.kill()
        print("mutants: interrupted", file=sys.stderr)
        return 130


def _run(mutants: Sequence[Mutant], jobs: int, *, baseline: bool) -> int:
    started = time.monotonic()
    jobs = max(1, min(jobs, len(mutants)))
    with scratch_copies(jobs) as copies:
        check_copy_is_imported(copies[0])
        if baseline:
            tests = sorted({t for m in mutants for t in m.tests})
            code, last, _ = run_tests(copies[0], tests)
            if code != 0:
                print(f"mutants: the listed tests fail without any mutant ({last})",
                      file=sys.stderr)
                return 1
            print(f"mutants: baseline: {len(tests)} test targets pass unmutated ({last}), "
                  f"{time.monotonic() - started:.0f} s")
        free: Queue[Path] = Queue()
        for copy in copies:
            free.put(copy)

        def one(mutant: Mutant) -> Outcome:
            copy = free.get()
            try:
                outcome = judge(mutant, copy)
            finally:
                free.put(copy)
            print(f"{outcome.verdict:8} {outcome.seconds:5.1f} s  {mutant.id}: {mutant.rule}"
                  + ("" if outcome.verdict == "killed" else f"  [{outcome.detail}]"), flush=True)
            return outcome

        pool = ThreadPoolExecutor(max_workers=jobs)
        try:
            outcomes = list(pool.map(one, mutants))
        except KeyboardInterrupt:
            pool.shutdown(wait=False, cancel_futures=True)
            for process in list(_RUNNING):
                process.kill()
            pool.shutdown()  # the workers put their files back before the copies go
            raise
        pool.shutdown()
    bad = [o for o in outcomes if o.verdict != "killed"]
    killed = len(outcomes) - len(bad)
    print(f"mutants: {len(outcomes)} listed, {killed} killed, "
          f"{sum(o.verdict == 'survived' for o in outcomes)} survived, "
          f"{sum(o.verdict == 'error' for o in outcomes)} errors; "
          f"{time.monotonic() - started:.0f} s with {jobs} worker(s)")
    for o in bad:
        print(f"mutants: {o.verdict}: {o.mutant.id} ({o.mutant.file}): {o.mutant.rule}; "
              f"tests {' '.join(o.mutant.tests)}: {o.detail}", file=sys.stderr)
    return 0 if not bad else 1


if __name__ == "__main__":
    sys.exit(main())
