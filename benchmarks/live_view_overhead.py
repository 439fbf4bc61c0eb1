"""Does watching the live page slow the control loop? (The issue's bound: within 10 %.)

Renders a 640x480 clip of a straight lane, then runs `lanewarden run --camera CLIP --base sim`
several times, alternating: without `--view`, and with `--view` and the page open in headless
Chromium (Debian's chromium + chromedriver, driven by selenium) for the whole run. Each run records
its steps' wall time and the control thread's CPU time per step (summary.json; the CPU time is not
inflated by other processes, so it is the figure to compare on a shared machine), the run
process's CPU time (rusage) and its peak resident memory (sampled from /proc). Prints them and the
with/without ratios. `--attack` also throws issue 18's hostile clients at the page for the whole
run (Content-Length -1 and a flood, smuggled requests, foreign Hosts, huge headers, slow and idle
connections): the loop's step times and the memory must stay where they are. On demand only:
    python benchmarks/live_view_overhead.py [--seconds 20] [--pairs 2] [--attack]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.operator.clips import lane_end_frames, write_video  # noqa: E402
from tests.operator.runs import free_port  # noqa: E402


def browser():  # type: ignore[no-untyped-def]
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
                 f"--user-data-dir={tempfile.mkdtemp(prefix='lw-bench-')}"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)


def descendants(pid: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry.name))
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def renice_browser(driver, niceness: int) -> None:  # type: ignore[no-untyped-def]
    pid = driver.service.process.pid
    for child in [pid, *descendants(pid)]:
        try:
            os.setpriority(os.PRIO_PROCESS, child, niceness)
        except OSError:
            pass


def attack(port: int, stop: threading.Event) -> dict[str, int]:
    """Hostile clients, one after another, until `stop`: what they got (counted)."""
    import socket

    host = f"Host: 127.0.0.1:{port}\r\n"
    resume = f"POST /resume HTTP/1.1\r\n{host}X-Lanewarden: 1\r\nContent-Length: 0\r\n\r\n"
    payloads = [
        f"POST /resume HTTP/1.1\r\n{host}X-Lanewarden: 1\r\nContent-Length: -1\r\n\r\n".encode()
        + b"x" * (1 << 20),
        f"POST /stop HTTP/1.1\r\n{host}Content-Length: {4096 + len(resume)}\r\n\r\n".encode()
        + b"a" * 4096 + resume.encode(),
        f"POST /resume HTTP/1.1\r\nHost: evil.example:{port}\r\nX-Lanewarden: 1\r\n"
        "Content-Length: 0\r\n\r\n".encode(),
        f"GET /status HTTP/1.1\r\n{host}".encode() + b"X-Big: " + b"z" * 20000 + b"\r\n\r\n",
    ]
    counts = {"connections": 0, "answered": 0, "resumes_served": 0}
    idle: list[socket.socket] = []
    while not stop.is_set():
        for payload in payloads:
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
                    counts["connections"] += 1
                    try:
                        s.sendall(payload)
                    except OSError:
                        pass
                    answer = s.recv(200)
                    counts["answered"] += bool(answer)
                    counts["resumes_served"] += b'"request": "resume"' in answer
            except OSError:
                pass
        try:  # idle and slow connections, held until the server cuts them off
            while len(idle) < 12:
                s = socket.create_connection(("127.0.0.1", port), timeout=5)
                s.sendall(b"GET /status HTTP/1.1\r\n")
                idle.append(s)
        except OSError:
            pass
        if len(idle) >= 12:
            for s in idle:
                s.close()
            idle.clear()
        stop.wait(0.05)
    for s in idle:
        s.close()
    return counts


def peak_rss_mib(pid: int, stop: threading.Event, into: dict[str, float]) -> None:
    """The process's resident memory, its peak over the run (VmRSS sampled every 0.1 s)."""
    while not stop.is_set():
        try:
            for line in Path(f"/proc/{pid}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    into["peak_rss_mib"] = max(into.get("peak_rss_mib", 0.0),
                                               int(line.split()[1]) / 1024)
        except OSError:
            return
        stop.wait(0.1)


def one_run(clip: Path, folder: Path, view: bool, niceness: int,
            hostile: bool = False) -> dict[str, float]:
    args = [sys.executable, "-m", "lanewarden", "run", "--camera", str(clip), "--base", "sim",
            "--record", str(folder)]
    port = free_port()
    if view:
        args += ["--view", str(port)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    process = subprocess.Popen(args, cwd=ROOT, stdout=subprocess.DEVNULL)
    memory: dict[str, float] = {}
    done = threading.Event()
    sampler = threading.Thread(target=peak_rss_mib, args=(process.pid, done, memory), daemon=True)
    sampler.start()
    attacked: dict[str, int] = {}
    attacker = None
    if view and hostile:
        def attack_when_up() -> None:
            attacked.update(attack(port, done))

        attacker = threading.Thread(target=attack_when_up, daemon=True)
        attacker.start()
    driver = None
    if view:
        driver = browser()
        stop = threading.Event()

        def watch() -> None:
            while not stop.is_set():
                try:
                    driver.get(f"http://127.0.0.1:{port}/")
                    renice_browser(driver, niceness)
                    break
                except Exception:  # noqa: BLE001 (not up yet)
                    stop.wait(0.2)

        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
    process.wait()
    done.set()
    if attacker is not None:
        attacker.join(10)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if driver is not None:
        stop.set()
        driver.quit()
    summary = json.loads((folder / "summary.json").read_text())
    loop = summary["loop_time_ms"]
    cpu = summary["loop_cpu_ms"]
    return {"mean": loop["mean"], "p50": loop["p50"], "p95": loop["p95"], "max": loop["max"],
            "cpu_mean": cpu["mean"], "cpu_p50": cpu["p50"], "cpu_p95": cpu["p95"],
            "cpu_s": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
            "steps": summary["steps"], "view_dropped": summary.get("view_frames_dropped") or 0,
            "peak_rss_mib": memory.get("peak_rss_mib", 0.0),
            "attack_connections": attacked.get("connections", 0),
            "resumes_served": attacked.get("resumes_served", 0)}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--pairs", type=int, default=2)
    parser.add_argument("--browser-nice", type=int, default=19,
                        help="run Chromium at this niceness: 19 stands for a browser on another "
                        "machine (the page's cost to the robot is then only serving it); 0 puts "
                        "it on the robot's own cores")
    parser.add_argument("--attack", action="store_true",
                        help="with the page open, also throw hostile clients at it all along")
    options = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="lw-view-bench-"))
    started = time.perf_counter()
    clip = write_video(lane_end_frames(start_m=0.3, end_m=0.3 + 0.15 * options.seconds,
                                       speed_m_s=0.15, size=(640, 480)), work / "clip.mp4")
    print(f"clip: {options.seconds:g} s at 640x480, rendered in "
          f"{time.perf_counter() - started:.1f} s; browser niceness {options.browser_nice}")
    results: dict[bool, list[dict[str, float]]] = {False: [], True: []}
    for pair in range(options.pairs):
        for view in (False, True):
            result = one_run(clip, work / f"run-{pair}-{int(view)}", view, options.browser_nice,
                             options.attack)
            results[view].append(result)
            attacked = (f"; under attack: {result['attack_connections']:.0f} hostile "
                        f"connections, {result['resumes_served']:.0f} resumes served"
                        if view and options.attack else "")
            print(f"{'page open' if view else 'no page  '}: step mean {result['mean']:.2f} ms, "
                  f"p50 {result['p50']:.2f}, p95 {result['p95']:.2f}, max {result['max']:.1f}; "
                  f"{result['steps']:.0f} steps; step CPU mean {result['cpu_mean']:.2f} ms, "
                  f"p95 {result['cpu_p95']:.2f}; run CPU {result['cpu_s']:.2f} s; peak RSS "
                  f"{result['peak_rss_mib']:.0f} MiB"
                  + (f"; view frames dropped {result['view_dropped']:.0f}" if view else "")
                  + attacked)
    for key in ("cpu_mean", "cpu_p50", "cpu_p95", "mean", "p50", "p95"):
        without = statistics.mean(r[key] for r in results[False])
        with_page = statistics.mean(r[key] for r in results[True])
        what = ("control thread CPU per step " + key[4:] if key.startswith("cpu_")
                else "step wall time " + key)
        print(f"{what}: {without:.2f} ms without, {with_page:.2f} ms with the page "
              f"open: ratio {with_page / without:.3f}")
    cpu_without = statistics.mean(r["cpu_s"] for r in results[False])
    cpu_with = statistics.mean(r["cpu_s"] for r in results[True])
    print(f"run process CPU: {cpu_without:.2f} s without, {cpu_with:.2f} s with: ratio "
          f"{cpu_with / cpu_without:.3f} (the page's JPEG encoding runs in the run's process)")
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
