"""Helpers shared by the batch CLI tests (tests/python/test_batch_cli.py, tests/mpi/test_batch_mpi.py): small
simulated observations, and comparing catalogues (not a test itself)."""
import json
import math
import os
import subprocess

SEARCH = ["--vmax-deg-day", "40", "--backend", "cpu"]


def simulate(cli, folder, seeds):
    """Writes obsS.fits for each seed (the small preset: 128x128x64) and returns their paths."""
    paths = []
    for s in seeds:
        p = os.path.join(folder, "obs%d.fits" % s)
        subprocess.run([cli, "simulate", "--preset", "small", "--seed", str(s), "-o", p], check=True,
                       capture_output=True)
        paths.append(p)
    return paths


def corrupt(source, path):
    """A truncated copy of `source` (a FITS whose header promises more data than it holds)."""
    with open(source, "rb") as f:
        head = f.read(100000)
    with open(path, "wb") as f:
        f.write(head)
    return path


def load(path):
    with open(path) as f:
        return json.load(f)


def same(a, b, path="", ignore=("iterations",)):
    """Differences between two JSON values: numbers within 1e-9 relative (a fit's last bits depend on the
    thread count), everything else equal. Returns a list of 'path: a != b' strings."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k in ignore:
                continue
            if k not in a or k not in b:
                out.append("%s/%s: only in one" % (path, k))
            else:
                out += same(a[k], b[k], path + "/" + k, ignore)
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return ["%s: %d != %d items" % (path, len(a), len(b))]
        out = []
        for i, (x, y) in enumerate(zip(a, b)):
            out += same(x, y, "%s[%d]" % (path, i), ignore)
        return out
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if a == b or math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12):
            return []
    elif a == b:
        return []
    return ["%s: %r != %r" % (path, a, b)]


def differences_from_searches(cli, catalogue, observations, options=SEARCH):
    """What differs between `catalogue` and separate `synthtrack-cli search OBS --fit --json` runs of each
    observation (candidates in order, x, y, velocity, SNR, frames and the fit): a list of strings, empty
    when the catalogue holds exactly what the separate searches found."""
    out = []
    for p in observations:
        name = os.path.basename(p)[:-5]
        s = subprocess.run([cli, "search", p, "--fit", "--json"] + list(options), capture_output=True, text=True)
        if s.returncode != 0:
            out.append("search --fit %s exited %d: %s" % (p, s.returncode, s.stderr[-300:]))
            continue
        want = json.loads(s.stdout)["candidates"]
        got = [c for c in catalogue["candidates"] if c["observation"] == name]
        if len(got) != len(want):
            out.append("%s: %d candidates in the catalogue, search --fit found %d" % (name, len(got), len(want)))
            continue
        for g, w in zip(got, want):
            for k in ("x", "y", "vx_px_s", "vy_px_s", "snr", "n_frames", "fit"):
                out += ["%s: %s" % (name, d) for d in same(g.get(k), w.get(k), k)[:3]]
    return out
