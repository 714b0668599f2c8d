"""`batch` and `search --mpi` under mpirun (issue 17; registered only when MPI was found). Usage:
test_batch_mpi.py CLI MPIEXEC. With 3 ranks (rank 0 hands out, 2 workers) over 6 small simulated
observations: the catalogue equals the one-process one and 6 separate `search --fit` runs; a worker killed with SIGKILL mid-run ends the job (no hang) with a catalogue naming what was
not done (and rank 0's message saying so, where mpirun forwards it), and a rerun gives the clean catalogue; under --enable-recovery rank 0 notices the silent worker by
its heartbeat and names it; `search --mpi` returns exactly the candidates of `search`."""
import json
import os
import signal
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "python"))
from _support import check, finish, run_cli  # noqa: E402
from _batch_support import SEARCH, differences_from_searches, load, same, simulate  # noqa: E402

ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", ST_THREADS="1")


def mpirun(mpiexec, args, extra=()):
    return [mpiexec, "--oversubscribe", "--allow-run-as-root", *extra, "-np", "3"] + args


def kill_a_worker_mid_run(out, timeout=60):
    """Waits for a worker (rank != 0) to log an observation as running, SIGKILLs it, returns its name."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        logs = os.path.join(out, "logs")
        for f in sorted(os.listdir(logs)) if os.path.isdir(logs) else []:
            try:
                log = load(os.path.join(logs, f))
            except (ValueError, OSError):
                continue
            if log.get("status") == "running" and log.get("rank", 0) != 0:
                os.kill(log["pid"], signal.SIGKILL)
                return log["observation"]
        time.sleep(0.05)
    return None


def main(cli, mpiexec):
    with tempfile.TemporaryDirectory() as tmp:
        obs = simulate(cli, tmp, [1, 2, 3, 4, 5, 6])
        clean = os.path.join(tmp, "clean")
        r = subprocess.run([cli, "batch"] + obs + ["--out", clean] + SEARCH, capture_output=True, text=True,
                           env=ENV)
        check(r.returncode == 0, "one-process batch: %s" % r.stderr)
        want = load(os.path.join(clean, "catalogue.json"))

        out = os.path.join(tmp, "mpi")
        r = subprocess.run(mpirun(mpiexec, [cli, "batch"] + obs + ["--out", out] + SEARCH), capture_output=True,
                           text=True, env=ENV, timeout=300)
        check(r.returncode == 0, "mpirun -np 3 batch: %s" % r.stderr)
        check("2 worker ranks" in r.stderr, "rank 0 hands out to 2 workers: %s" % r.stderr[:300])
        check("6/6 observations" in r.stderr and "ETA" in r.stderr and "/h" in r.stderr,
              "rank 0 prints done/total, rate and ETA: %s" % r.stderr[-400:])
        d = same(load(os.path.join(out, "catalogue.json")), want)
        check(not d, "MPI catalogue equals the one-process one: %s" % d[:5])
        d = differences_from_searches(cli, load(os.path.join(out, "catalogue.json")), obs)
        check(not d, "MPI catalogue equals 6 separate search --fit runs: %s" % d[:5])
        ranks = {load(os.path.join(out, "logs", f))["rank"] for f in os.listdir(os.path.join(out, "logs"))}
        check(ranks == {1, 2}, "both workers ran observations, rank 0 none: %s" % ranks)

        # A worker killed mid-run: mpirun ends the job; rank 0 names what was not done; a rerun finishes.
        killed = os.path.join(tmp, "killed")
        p = subprocess.Popen(mpirun(mpiexec, [cli, "batch"] + obs + ["--out", killed] + SEARCH),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        victim = kill_a_worker_mid_run(killed)
        check(victim is not None, "a worker was seen running an observation")
        try:
            _, err = p.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            _, err = p.communicate()
            check(False, "the job hung after a worker was killed")
        check(p.returncode != 0, "the killed job exits non-zero, got %s" % p.returncode)
        # Rank 0 names what was not done from its SIGTERM handler, in one write(2) with "stopped by SIGTERM".
        # mpirun (Open MPI 4.1) sometimes takes the job down without forwarding that output: 2 of 7 full test
        # runs on 2026-11-28 had mpirun's own lines and rank 0's earlier progress but none of the handler's.
        # (When it wrote the two in two calls, a CI run got the first and not the second.) Where the
        # handler's output arrived it must name the victim; where none did, the catalogue (checked below,
        # written before any kill) is the record.
        if "stopped by SIGTERM" in err or "NOT DONE" in err:
            check("NOT DONE" in err and victim in err, "the message names %s as not done: %s" % (victim, err[-600:]))
        else:
            print("note: rank 0's SIGTERM message was not forwarded by mpirun this time: %s" % err[-300:])
        cat = load(os.path.join(killed, "catalogue.json"))
        check(victim in [e["observation"] for e in cat["not_done"]], "the catalogue lists it as not done")
        r = subprocess.run(mpirun(mpiexec, [cli, "batch"] + obs + ["--out", killed] + SEARCH), capture_output=True,
                           text=True, env=ENV, timeout=300)
        check(r.returncode == 0, "rerun after the kill: %s" % r.stderr[-500:])
        d = same(load(os.path.join(killed, "catalogue.json")), want)
        check(not d, "after the rerun the catalogue equals the clean one: %s" % d[:5])

        # Under --enable-recovery the job goes on: rank 0 declares the silent worker dead by its heartbeat.
        rec = os.path.join(tmp, "recovery")
        p = subprocess.Popen(mpirun(mpiexec, [cli, "batch"] + obs + ["--out", rec, "--worker-timeout", "3"] + SEARCH,
                                    ["--enable-recovery"]),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        victim = kill_a_worker_mid_run(rec)
        try:
            _, err = p.communicate(timeout=300)  # a hang detector: generous for a loaded 2-core CI machine
        except subprocess.TimeoutExpired:
            p.kill()
            _, err = p.communicate()
            check(False, "rank 0 hung after a worker died under --enable-recovery")
        check("stopped answering" in err and "NOT DONE: %s" % victim in err,
              "recovery: the dead rank and %s are named: %s" % (victim, err[-600:]))
        cat = load(os.path.join(rec, "catalogue.json"))
        check([e["observation"] for e in cat["not_done"]] == [victim], "recovery: only %s not done: %s" %
              (victim, cat["not_done"]))
        others = [c for c in want["candidates"] if c["observation"] != victim]
        d = same(cat["candidates"], others)
        check(not d, "recovery: the surviving worker did the other 5, their candidates as the clean run's: %s" %
              d[:5])

        # search --mpi: the vy rows over 3 ranks give exactly the candidates of one search.
        one = run_cli(cli, ["search", obs[1], "--method", "exact", "--json"] + SEARCH)
        r = subprocess.run(mpirun(mpiexec, [cli, "search", obs[1], "--mpi", "--fit", "--json"] + SEARCH[:2]),
                           capture_output=True, text=True, env=ENV, timeout=300)
        check(r.returncode == 0, "search --mpi: %s" % r.stderr[-500:])
        a, b = json.loads(one.stdout), json.loads(r.stdout)
        check(len(a["candidates"]) > 0, "search found the object")
        strip = [{k: v for k, v in c.items() if k != "fit"} for c in b["candidates"]]
        check(strip == a["candidates"], "search --mpi candidates equal search's exactly")
        check(a["cells_above_threshold"] == b["cells_above_threshold"], "same cells above threshold")
        check(all("fit" in c for c in b["candidates"]), "rank 0 fitted them")
    return finish()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
