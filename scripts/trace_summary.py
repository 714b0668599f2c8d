#!/usr/bin/env python3
"""Prints a run's timeline from an ST_TRACE file (Chrome trace events), one line per part, by start time.

    ST_TRACE=run.json synthtrack-cli bench preprocess --frames 1500 --backend cuda
    python3 scripts/trace_summary.py run.json [--min-ms 0.5] [--from NAME]

Each line: start and end (ms from the first part), duration, thread number, name; parts shorter than
--min-ms are left out. --from NAME starts the clock at the first part of that name (e.g. "calibrate").
"""
import argparse
import json
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("trace")
    ap.add_argument("--min-ms", type=float, default=0.5)
    ap.add_argument("--from", dest="origin", default=None)
    a = ap.parse_args()
    with open(a.trace) as f:
        events = json.load(f)["traceEvents"]
    events.sort(key=lambda e: (e["ts"], -e["dur"]))
    if not events:
        print("no events")
        return 0
    t0 = events[0]["ts"]
    if a.origin:
        starts = [e["ts"] for e in events if e["name"] == a.origin]
        if not starts:
            print(f"no part named {a.origin!r}", file=sys.stderr)
            return 1
        t0 = starts[0]
    for e in events:
        ms = e["dur"] / 1e3
        if ms < a.min_ms:
            continue
        start = (e["ts"] - t0) / 1e3
        print(f"{start:9.1f} {start + ms:9.1f} {ms:8.1f}  t{e['tid']:<3} {e['name']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
