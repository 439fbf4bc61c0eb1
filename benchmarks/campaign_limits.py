"""What hostile campaign sizes and a damaged results.sqlite cost: wall time and peak memory (RSS)
of each refusal, of `--recover`, and how soon the largest campaign allowed starts running.

Each case is `lanewarden campaign` (or a store opening) in a process of its own, measured from
outside: wall time to its exit (or to a line on stderr, when it is then stopped), and that
child's own CPU time and peak RSS (`os.wait4`). On a loaded machine the wall times grow with the
load; the CPU times do not (most of a refusal's is importing the CLI: about 2.8 s of CPU, scipy
through filterpy the largest part).

    python benchmarks/campaign_limits.py [--rows 20000] [--keep DIR]

- `--runs 1000000` and `--runs 10**12`: refused in one line (exit 2);
- a results.sqlite of `--rows` realistic rows (about 2 KB of metrics each) with one damaged page:
  refused in one line (exit 2), then carried over by `--recover` (the store alone: no run);
- `--runs 100000` of the default spec, piped, in this process: the time to its start line, to its
  first progress line and to its first finished run, and the peak RSS then (it is then stopped).

Targets (issue 18): each refusal within 5 s and 500 MB.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SPEC = """\
name: limits
scenarios: [straight]
max_time_s: 6
faults:
  - kind: bumper
"""


def _run(args: list[str], cwd: Path, until: str | None = None,
         timeout_s: float = 600.0, module: bool = True) -> dict[str, object]:
    """Run `python -m lanewarden ARGS` (or `python ARGS`); wall time to its exit (or to the first
    stderr line holding `until`, when it is then stopped), its peak RSS."""
    started = time.perf_counter()
    command = [sys.executable, "-m", "lanewarden", *args] if module else [sys.executable, *args]
    process = subprocess.Popen(command, cwd=cwd,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    marks: dict[str, float] = {}
    assert process.stderr is not None
    for line in process.stderr:
        lines.append(line.rstrip())
        now = round(time.perf_counter() - started, 2)
        marks.setdefault(line.split(":")[0], now)
        if until is not None and until in line:
            marks["until"] = now
            process.send_signal(signal.SIGINT)
            break
        if time.perf_counter() - started > timeout_s:
            process.kill()
            break
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    return {"exit": process.returncode, "wall_s": round(time.perf_counter() - started, 2),
            "cpu_s": round(usage.ru_utime + usage.ru_stime, 2),
            "peak_rss_mb": round(usage.ru_maxrss / 1024.0, 1), "first_lines": lines[:3],
            "marks_s": marks}


def _damaged_store(folder: Path, rows: int) -> Path:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from lanewarden.scenarios.campaign.cases import load_campaign_spec, spec_fingerprint
    from lanewarden.scenarios.campaign.store import COLUMN_NAMES, ResultStore

    (folder / "spec.yaml").write_text(SPEC, encoding="utf-8")
    spec, _ = load_campaign_spec(str(folder / "spec.yaml"))
    out = folder / "out"
    out.mkdir()
    metrics = json.dumps({f"metric_{i}": i * 0.001 for i in range(90)})  # ~2 KB
    path = out / "results.sqlite"
    with ResultStore(path) as store:
        store.claim({"spec": spec_fingerprint(spec, {}), "seed": "0"})
    row = {"scenario": "straight", "camera": "320x240", "outcome": "nominal", "reason": "-",
           "metrics_json": metrics, "effects_json": "[]"}
    with sqlite3.connect(path) as db:  # one transaction (a commit per row, as a campaign does,
        db.executemany(                # would make this set-up minutes long)
            f"INSERT INTO runs ({', '.join(COLUMN_NAMES)}) VALUES "
            f"({', '.join('?' for _ in COLUMN_NAMES)})",
            ([{**row, "id": f"r{i:05d}", "idx": i}.get(n) for n in COLUMN_NAMES]
             for i in range(rows)))
    data = bytearray(path.read_bytes())
    page = len(data) // 4096 // 2
    data[page * 4096:(page + 1) * 4096] = bytes(range(256)) * 16
    data[24:28] = (int.from_bytes(data[24:28], "big") + 1).to_bytes(4, "big")
    path.write_bytes(bytes(data))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=20_000)
    parser.add_argument("--keep", type=Path, default=None, help="work in this folder")
    options = parser.parse_args()
    folder = options.keep or Path(tempfile.mkdtemp(prefix="campaign-limits-"))
    folder.mkdir(parents=True, exist_ok=True)
    results: dict[str, object] = {"load": os.getloadavg()}
    base = ["campaign", "--spec", "spec.yaml", "--scheduler", "in-process"]
    (folder / "spec.yaml").write_text(SPEC, encoding="utf-8")
    for runs in ("1000000", str(10**12)):
        results[f"--runs {runs}"] = _run([*base, "--out", "hostile", "--runs", runs], folder)
    out = _damaged_store(folder, options.rows)
    size_mb = round((out / "results.sqlite").stat().st_size / 2**20, 1)
    results[f"damaged results.sqlite ({options.rows} rows, {size_mb} MB)"] = _run(
        [*base, "--out", str(out), "--runs", str(options.rows)], folder)
    results["--recover (the store alone)"] = _run(
        ["-c", "import sys; from pathlib import Path; "
         "from lanewarden.scenarios.campaign.store import ResultStore; "
         "s = ResultStore(Path(sys.argv[1]), recover=True); "
         "print('carried', s.recovered.count, 'lost', s.recovered.lost_ids, file=sys.stderr)",
         str(out / "results.sqlite")], folder, module=False)
    largest = _run(["campaign", "--spec", "default", "--out", "largest", "--runs", "100000",
                    "--scheduler", "in-process"], folder, until="campaign default: 1/100000")
    largest["case_files_then"] = len(list((folder / "largest" / "cases").iterdir()))
    results["--runs 100000 (default spec, in this process)"] = largest
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
