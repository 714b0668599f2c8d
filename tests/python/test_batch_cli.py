"""`synthtrack-cli batch` in one process (issue 17): over 4 small simulated observations and a corrupt one,
the merged catalogue holds exactly the candidates (and fits) of separate `search --fit` runs; the corrupt
input lands in the catalogue's errors without stopping the rest; a rerun skips everything complete; a
deleted output is redone and the catalogue comes out the same; a SIGTERM mid-run names, at once, what is
not done; a manifest's per-observation option is used."""
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(__file__))
from _support import check, finish, run_cli  # noqa: E402
from _batch_support import SEARCH, corrupt, load, same, simulate  # noqa: E402


def main(cli):
    with tempfile.TemporaryDirectory() as tmp:
        obs = simulate(cli, tmp, [1, 2, 3, 4])
        bad = corrupt(obs[0], os.path.join(tmp, "bad.fits"))
        out = os.path.join(tmp, "out")
        r = run_cli(cli, ["batch"] + obs + [bad, "--out", out] + SEARCH)
        check(r.returncode == 1, "batch with a corrupt input exits 1 (errors listed), got %d: %s" %
              (r.returncode, r.stderr))
        cat = load(os.path.join(out, "catalogue.json"))
        check(len(cat["errors"]) == 1 and cat["errors"][0]["observation"] == "bad" and
              "truncated" in cat["errors"][0]["error"], "the corrupt input is in errors: %s" % cat["errors"])
        check(cat["not_done"] == [], "nothing left undone")
        check("5/5 observations" in r.stderr and "ETA" in r.stderr,
              "progress lines: %s" % r.stderr[-400:])
        # The same as separate `search --fit` runs, observation by observation.
        for p in obs:
            name = os.path.basename(p)[:-5]
            s = run_cli(cli, ["search", p, "--fit", "--json"] + SEARCH)
            check(s.returncode == 0, "search --fit %s: %s" % (p, s.stderr))
            import json
            want = json.loads(s.stdout)["candidates"]
            got = [c for c in cat["candidates"] if c["observation"] == name]
            check(len(got) == len(want), "%s: %d candidates in the catalogue, search found %d" %
                  (name, len(got), len(want)))
            for g, w in zip(got, want):
                for k in ("x", "y", "vx_px_s", "vy_px_s", "snr", "n_frames", "fit"):
                    d = same(g.get(k), w.get(k), k)
                    check(not d, "%s: %s" % (name, d[:3]))
            log = load(os.path.join(out, "logs", name + ".json"))
            check(log["status"] == "done" and log["seconds"] > 0, "%s log: %s" % (name, log))
        check(len(cat["candidates"]) >= 4, "every observation has its object: %d" % len(cat["candidates"]))

        # A rerun skips every complete observation (the corrupt one is tried again).
        r2 = run_cli(cli, ["batch"] + obs + [bad, "--out", out] + SEARCH)
        summary = load(os.path.join(out, "batch.json"))
        check(summary["skipped"] == 4, "rerun skips the 4 complete ones: %s" % summary)
        check(not same(load(os.path.join(out, "catalogue.json")), cat), "rerun: the same catalogue")
        # A deleted output is redone; a changed option redoes everything.
        import shutil
        shutil.rmtree(os.path.join(out, "observations", "obs3"))
        run_cli(cli, ["batch"] + obs + [bad, "--out", out] + SEARCH)
        summary = load(os.path.join(out, "batch.json"))
        check(summary["skipped"] == 3, "the deleted one is redone: %s" % summary)
        check(not same(load(os.path.join(out, "catalogue.json")), cat), "after the redo: the same catalogue")
        check(r2.returncode == 1, "rerun exit code %d" % r2.returncode)
        # A flag option (--no-register: no per-frame registration) is an option like any other: it is
        # accepted, changes the digest (everything redone), and a rerun with it skips again.
        r3 = run_cli(cli, ["batch"] + obs + [bad, "--out", out, "--no-register"] + SEARCH)
        check(r3.returncode == 1, "batch --no-register exit code %d: %s" % (r3.returncode, r3.stderr[-400:]))
        summary = load(os.path.join(out, "batch.json"))
        check(summary["skipped"] == 0, "--no-register redoes every observation: %s" % summary)
        run_cli(cli, ["batch"] + obs + [bad, "--out", out, "--no-register"] + SEARCH)
        summary = load(os.path.join(out, "batch.json"))
        check(summary["skipped"] == 4, "a rerun with --no-register skips the 4 complete ones: %s" % summary)

        # A manifest: one observation with its own velocity range (a smaller grid).
        man = os.path.join(tmp, "m.csv")
        with open(man, "w") as f:
            f.write("name,inputs,vmax-deg-day\nwide,%s,\nnarrow,%s,20\n" % (obs[0], obs[0]))
        out2 = os.path.join(tmp, "out2")
        r = run_cli(cli, ["batch", "--manifest", man, "--out", out2] + SEARCH)
        check(r.returncode == 0, "manifest batch: %s" % r.stderr)
        wide = load(os.path.join(out2, "observations", "wide", "candidates.json"))
        narrow = load(os.path.join(out2, "observations", "narrow", "candidates.json"))
        check(narrow["grid"]["nvx"] < wide["grid"]["nvx"], "the manifest's vmax-deg-day is used: %d vs %d" %
              (narrow["grid"]["nvx"], wide["grid"]["nvx"]))
        # SIGTERM mid-run (what mpirun sends every rank when one dies): the handler names what is not done on
        # stderr at once, every observation not yet started among them (test_batch_mpi.py checks it under
        # mpirun only where mpirun forwards it).
        import signal
        import subprocess
        import time
        term = os.path.join(tmp, "term")
        p = subprocess.Popen([cli, "batch"] + obs + ["--out", term] + SEARCH, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        names = [os.path.basename(o)[:-5] for o in obs]
        running, pending = None, []
        deadline = time.time() + 60
        while running is None and time.time() < deadline and p.poll() is None:
            logs = os.path.join(term, "logs")
            started = {}
            for f in sorted(os.listdir(logs)) if os.path.isdir(logs) else []:
                try:
                    log = load(os.path.join(logs, f))
                except (ValueError, OSError):
                    continue
                started[log["observation"]] = log.get("status")
                if log.get("status") == "running":
                    running = log["observation"]
            # Not started yet: not done when the signal lands a few ms later (each takes ~1 s).
            pending = [n for n in names if n not in started]
            if running is None:
                time.sleep(0.02)
        check(running is not None and pending, "an observation was seen running, others not started: %s %s" %
              (running, pending))
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=120)
        i = err.find("batch: stopped by SIGTERM")
        check(i >= 0, "SIGTERM is reported: %s" % err[-400:])
        handler = err[i:].split("\n")
        check(len(handler) > 1 and handler[1].startswith("batch: NOT DONE: ") and
              all(n in handler[1] for n in pending),
              "the handler's next line names %s as not done: %s" % (pending, handler[:2]))
        check(p.returncode != 0, "a batch stopped by SIGTERM exits non-zero, got %s" % p.returncode)
        # Usage errors.
        check(run_cli(cli, ["batch", obs[0]]).returncode == 2, "--out is required")
        check(run_cli(cli, ["batch", obs[0], "--out", out2, "--overlap", "3"]).returncode == 2,
              "--overlap without --split")
    return finish()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
