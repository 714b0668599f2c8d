"""Helpers shared by the astropy cross-checks in tests/python (not a test itself: CMake registers only
test_*.py files).

Usage, before importing numpy or astropy:

    import _support
    _support.require_astropy()
    from _support import check, finish, run_cli
"""
import os
import subprocess
import sys

_COUNTS = {"passed": 0, "failed": 0}


def require_astropy():
    """Re-executes the script under /usr/bin/python3 when this interpreter lacks numpy or astropy (ctest may
    find a python3, e.g. pyenv's, without Debian's python3-astropy); exits 1 with a message when no
    interpreter has them."""
    try:
        import numpy  # noqa: F401
        import astropy.io.fits  # noqa: F401
    except ImportError:
        if sys.executable != "/usr/bin/python3" and os.path.exists("/usr/bin/python3"):
            os.execv("/usr/bin/python3", ["/usr/bin/python3"] + sys.argv)
        print("0 passed, 1 failed (astropy is not installed: apt-get install python3-astropy)")
        sys.exit(1)


def check(ok, what):
    """Counts one check; prints `what` when it failed."""
    if ok:
        _COUNTS["passed"] += 1
    else:
        _COUNTS["failed"] += 1
        print("FAIL:", what)


def failed():
    """Number of failed checks so far."""
    return _COUNTS["failed"]


def finish():
    """Prints "N passed, N failed" and returns the exit status (1 when a check failed)."""
    print("%d passed, %d failed" % (_COUNTS["passed"], _COUNTS["failed"]))
    return 0 if _COUNTS["failed"] == 0 else 1


def run_cli(cli, args):
    """Runs `cli args...`, returns the CompletedProcess (text stdout/stderr captured)."""
    return subprocess.run([cli] + list(args), capture_output=True, text=True)


def run_ok(cli, *args):
    """Runs `cli args...` and returns its stdout; stops the script naming the command when it fails."""
    r = run_cli(cli, args)
    if r.returncode != 0:
        raise SystemExit(f"{cli} {' '.join(args)} exited {r.returncode}: {r.stderr.strip()}")
    return r.stdout
