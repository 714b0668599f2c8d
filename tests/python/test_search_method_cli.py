#!/usr/bin/env python3
"""`synthtrack-cli search --method auto|exact|tree` end to end (issue 9, part 4).

With ST_THREADS=2 (the cost model depends on the worker count):
  - the small preset (64 x 128^2, +-12 deg/day = 23^2 velocities): auto resolves to exact, with an "auto:"
    reason; stderr shows both estimates (exact marked) and the choice; the JSON and every CSV row (read with
    Python's csv module, the reason quoted) carry the same method and reason;
  - 500 x 256^2 over 31^2 velocities (exact ~3e10 additions, the tree ~100x fewer): auto resolves to tree,
    which runs and reports the same trial counts;
  - --method tree and --method exact are kept with reason "requested"; --method bogus exits 2.

usage: test_search_method_cli.py PATH-TO-synthtrack-cli     (prints "N passed, N failed"; exit 1 on failure)
"""
import csv
import json
import os
import subprocess
import sys
import tempfile

from _support import check, finish


def search(cli, args):
    env = dict(os.environ, ST_THREADS="2")
    return subprocess.run([cli, "search"] + args, capture_output=True, text=True, env=env)


def small_preset(cli, tmp):
    obs = os.path.join(tmp, "small.fits")
    r = subprocess.run([cli, "simulate", "--preset", "small", "-o", obs], capture_output=True, text=True)
    check(r.returncode == 0, "simulate small: " + r.stderr)
    out_csv = os.path.join(tmp, "small.csv")
    # +-40 deg/day: the small preset's object moves at ~29 deg/day, beyond the default +-12.
    r = search(cli, [obs, "--backend", "cpu", "--vmax-deg-day", "40", "--json", "--out", out_csv])
    check(r.returncode == 0, "search small: " + r.stderr)
    j = json.loads(r.stdout)
    check(j["method"] == "exact", "small preset, auto -> exact: %s" % j["method"])
    check(j["method_reason"].startswith("auto: exact"), "reason: %s" % j["method_reason"])
    check("> exact:" in r.stderr and "tree:" in r.stderr, "both estimates, exact marked: %s" % r.stderr)
    check("method: exact (auto: exact" in r.stderr, "choice printed before the run: %s" % r.stderr)
    with open(out_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    check(len(rows) == len(j["candidates"]) and len(rows) >= 1, "CSV rows %d" % len(rows))
    check(all(row["method"] == "exact" and row["method_reason"] == j["method_reason"] for row in rows),
          "CSV method columns equal the JSON's: %s" % (rows[:1],))
    # The session made from the result keeps the method and why.
    cpath, spath = os.path.join(tmp, "small.json"), os.path.join(tmp, "session.json")
    with open(cpath, "w") as f:
        f.write(r.stdout)
    r = subprocess.run([cli, "report", cpath, "--session", spath], capture_output=True, text=True)
    check(r.returncode == 0, "report --session: " + r.stderr)
    session = json.load(open(spath)) if r.returncode == 0 else {"search": {}}
    check(session["search"].get("method") == "exact" and
          session["search"].get("method_reason") == j["method_reason"], "session: %s" % session["search"].keys())
    r = search(cli, [obs, "--backend", "cpu", "--vmax-deg-day", "40", "--method", "tree", "--json"])
    t = json.loads(r.stdout) if r.returncode == 0 else {}
    check(t.get("method") == "tree" and t.get("method_reason") == "requested", "--method tree kept: %s" % r.stderr)
    check(t.get("trials") == j["trials"], "same trials for tree and exact")
    r = search(cli, [obs, "--backend", "cpu", "--vmax-deg-day", "40", "--method", "exact", "--json"])
    e = json.loads(r.stdout) if r.returncode == 0 else {}
    check(e.get("method") == "exact" and e.get("method_reason") == "requested", "--method exact kept")
    r = search(cli, [obs, "--method", "bogus"])
    check(r.returncode == 2 and "bogus" in r.stderr, "--method bogus: rc %d %s" % (r.returncode, r.stderr))


def larger_cube(cli, tmp):
    # 500 frames at 10 Hz (span 49.9 s, grid step 1 px / span = 0.02 px/s): +-0.3 px/s is 31 x 31 velocities.
    obs = os.path.join(tmp, "larger.fits")
    r = subprocess.run([cli, "simulate", "--preset", "small", "--frames", "500", "--size", "256x256", "-o", obs],
                       capture_output=True, text=True)
    check(r.returncode == 0, "simulate 500 x 256^2: " + r.stderr)
    # Pre-processed, then searched with an unreachable threshold: only the method and the run matter here.
    prepared = os.path.join(tmp, "larger_prepared.fits")
    r = subprocess.run([cli, "preprocess", obs, "-o", prepared], capture_output=True, text=True)
    check(r.returncode == 0, "preprocess 500 x 256^2: " + r.stderr)
    r = search(cli, [prepared, "--preprocessed", "--sigma-f", "1", "--snr", "1e9", "--vmax-px-s", "0.3",
                     "--backend", "cpu", "--json"])
    check(r.returncode == 0, "search 500 x 256^2: " + r.stderr)
    j = json.loads(r.stdout) if r.returncode == 0 else {"trials": {}, "method": "", "method_reason": ""}
    check(j["trials"].get("nvx") == 31 and j["trials"].get("nx") == 256, "trials %s" % j["trials"])
    check(j["method"] == "tree", "500 x 256^2 x 31^2, auto -> tree: %s (%s)" % (j["method"], j["method_reason"]))
    check(j["method_reason"].startswith("auto: tree"), "reason: %s" % j["method_reason"])
    check("> tree:" in r.stderr, "tree estimate marked: %s" % r.stderr)


def main():
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    cli = sys.argv[1]
    with tempfile.TemporaryDirectory() as tmp:
        small_preset(cli, tmp)
        larger_cube(cli, tmp)
    return finish()


if __name__ == "__main__":
    sys.exit(main())
