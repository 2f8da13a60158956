"""Long jobs' memory: 150 ``timing`` jobs of ~13 MB results each, one after another, each
polled until done and its result read once (as a client would). The table gives the server
process's resident memory (``VmRSS``) and the store file's size after every 25 jobs, against
``PLANNER_JOBS_MAX_MB`` (the bound on the results kept; the results live in the store's
``jobs`` table, so the server holds one result at a time while it answers a poll). Before the
bounds, the same jobs took the server from 662 to 2,528 MB, kept for the TTL.

    python benchmarks/job_memory.py               # 150 jobs, PLANNER_JOBS_MAX_MB=512
    python benchmarks/job_memory.py --jobs 40 --jobs-max-mb 128
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from _light import LightClient
from _machine import machine_line
from _server import start_service

#: A timing job whose answer is ~13 MB: a 6 s joint path sampled at 10 kHz (61,000 samples: the
#: service runs with PLANNER_MAX_TRAJECTORY_SAMPLES raised to 70,000).
TIMING = {
    "waypoints": [[-1.2, 2.0, 1.0], [1.2, 2.8, 0.4]],
    "method": "ruckig",
    "sample_rate_hz": 10000,
    "limits": {"velocity": [0.4, 0.4, 0.4]},
}


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def _store_mb(path: Path) -> float:
    return sum(p.stat().st_size for p in path.parent.glob(path.name + "*")) / 2**20


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--jobs", type=int, default=150)
    ap.add_argument("--jobs-max-mb", type=float, default=512.0)
    args = ap.parse_args()
    print(f"# long jobs' memory ({machine_line()})")
    with tempfile.TemporaryDirectory() as tmp:
        store = Path(tmp) / "store.sqlite3"
        settings = {
            "PLANNER_WORKERS": "2",
            "PLANNER_SCENE_STORE": str(store),
            "PLANNER_JOBS_MAX_MB": str(args.jobs_max_mb),
            "PLANNER_MAX_JOBS": "1000",
            "PLANNER_JOBS_PER_TENANT": "1000",
            "PLANNER_MAX_TRAJECTORY_SAMPLES": "70000",
        }
        proc, url = start_service(settings, quiet=True)
        try:
            c = LightClient(url, timeout_s=120)
            base = _rss_mb(proc.pid)
            sizes: list[int] = []
            rows = [(0, base, 0.0, 0)]
            for i in range(1, args.jobs + 1):
                status, body, _ = c.request(
                    "POST", "/v1/jobs", {"kind": "timing", "request": TIMING}
                )
                assert status == 202, body[:300]
                job_id = json.loads(body)["id"]
                while True:
                    status, body, _ = c.request("GET", f"/v1/jobs/{job_id}")
                    state = json.loads(body)
                    if state["status"] in ("done", "failed", "cancelled"):
                        break
                    time.sleep(0.05)
                assert state["status"] == "done", body[:500]
                sizes.append(len(body))
                if i % 25 == 0 or i == args.jobs:
                    _, listing, _ = c.request("GET", "/v1/jobs")
                    kept = sum(j["status"] == "done" for j in json.loads(listing))
                    rows.append((i, _rss_mb(proc.pid), _store_mb(store), kept))
                    print(f"{i} jobs", flush=True)
            print()
            print(
                f"result of one job: {sizes[0] / 2**20:.1f} MB; PLANNER_JOBS_MAX_MB = "
                f"{args.jobs_max_mb:g}; server at start {base:.0f} MB"
            )
            print()
            print(
                "| jobs done | server RSS MB | over the start, MB | store file MB | results kept |"
            )
            print("|---|---|---|---|---|")
            for n, rss, size, kept in rows:
                print(f"| {n} | {rss:.0f} | {rss - base:+.0f} | {size:.0f} | {kept} |")
        finally:
            proc.terminate()
            proc.wait(30)


if __name__ == "__main__":
    main()
