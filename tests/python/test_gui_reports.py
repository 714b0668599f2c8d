#!/usr/bin/env python3
"""The GUI's reports read by other software (issue 8): DS9 and astropy.

Runs the Reports-dialog QTest (tests/ui/test_report_dialog.cpp, offscreen) with ST_REPORT_OUT so its outputs
stay in a temporary folder: a moving-dot cube with a TAN WCS (1"/px), candidates 1 and 2 labelled real with
fits whose RA/Dec come from that WCS. Then:
  astropy: reads the object- and sky-tracked FITS stacks; their WCS maps candidate 1's pixel to its fitted
    RA/Dec (1e-7 deg; the sky rate is 0, so t_ref and the first frame's WCS agree); provenance keywords; the
    object-tracked stack holds the dot at the candidate's pixel at 1 count per frame (the stacks are the mean per
    contributing frame minus the background, BUNIT set, a COVERAGE extension of 40 frames there), the
    sky-tracked one < 3;
  DS9 (Debian's saods9 under xvfb-run): loads the stack and our icrs region file and saves the regions in
    image coordinates: one circle per candidate, candidate 1's at its 1-based pixel (0.002 px with the stack
    labelled FK5 like the region file; 0.03 px with its RADESYS = ICRS, where DS9 applies the ~20 mas FK5-ICRS
    frame tie), labels kept.
    Skipped (not failed) when ds9 or xvfb-run is missing.
Skipped when the GUI tests were not built (-DST_BUILD_GUI=OFF).

usage: test_gui_reports.py PATH-TO-synthtrack-cli     (prints "N passed, N failed"; exit 1 on failure)
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _support  # noqa: E402

_support.require_astropy()
from _support import check, finish  # noqa: E402
from astropy.io import fits  # noqa: E402
from astropy.wcs import WCS  # noqa: E402


def ui_test_binary(cli):
    build = os.path.dirname(os.path.dirname(os.path.abspath(cli)))
    path = os.path.join(build, "tests", "st_ui_test_report_dialog")
    return path if os.access(path, os.X_OK) else None


def run_gui_reports(binary, out):
    # Its own settings folder: the QTest saves report settings, which must not meet a concurrent run's.
    env = dict(os.environ, ST_REPORT_OUT=out, QT_QPA_PLATFORM="offscreen", XDG_CONFIG_HOME=os.path.join(out, "cfg"))
    r = subprocess.run([binary, "--gtest_filter=ReportDialogTest.OnlyReal*"], env=env, capture_output=True,
                       text=True, timeout=300)
    check(r.returncode == 0, "the Reports-dialog QTest failed:\n" + r.stdout[-3000:] + r.stderr[-2000:])
    return r.returncode == 0


def check_fits(out, cand, fit):
    x, y = cand["x"], cand["y"]
    for kind in ("object", "sky"):
        path = os.path.join(out, "run_c001_%s.fits" % kind)
        with fits.open(path) as hdul:
            h = hdul[0].header
            data = hdul[0].data
            wcs = WCS(h)
            names = [x.name for x in hdul]
            coverage = hdul["COVERAGE"].data if "COVERAGE" in names else None
        check(coverage is not None and int(coverage[y, x]) == 40, "%s: COVERAGE extension (%s)" % (path, names))
        check(h.get("BUNIT") == "adu", "%s: BUNIT %s" % (path, h.get("BUNIT")))
        check(data.shape == (96, 96), "%s: shape %s" % (path, data.shape))
        for key in ("STVX", "STVY", "SKYVX", "SKYVY", "TREFMJD", "NFRAMES", "STMODE", "WCSEPOCH"):
            check(key in h, "%s: no %s card" % (path, key))
        check(h.get("NFRAMES") == 40, "%s: NFRAMES %s" % (path, h.get("NFRAMES")))
        ra, dec = wcs.all_pix2world([[x, y]], 0)[0]
        check(abs(ra - fit["ra_deg"]) < 1e-7 and abs(dec - fit["dec_deg"]) < 1e-7,
              "%s: WCS gives (%.8f, %.8f) at the candidate, the fit (%.8f, %.8f)" %
              (path, ra, dec, fit["ra_deg"], fit["dec_deg"]))
        peak = float(data[y, x])
        if kind == "object":
            check(abs(peak - 1.0) < 1e-6, "%s: object-tracked value %.3f at the candidate, expected 1 per frame" % (path, peak))
        else:
            check(float(data.max()) < 3.0, "%s: sky-tracked maximum %.3f, expected a streak < 3" % (path, data.max()))


def ds9_image_regions(out, fits_path, tag):
    """Runs DS9 on `fits_path` with our region file; returns the regions it saves in image coordinates."""
    saved = os.path.join(out, "ds9_%s.reg" % tag)
    cmd = [shutil.which("xvfb-run"), "-a", shutil.which("ds9"), fits_path, "-regions", "load",
           os.path.join(out, "run.reg"), "-regions", "system", "image", "-regions", "save", saved, "-exit"]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    except subprocess.TimeoutExpired:
        check(False, "ds9 did not exit within 180 s: " + " ".join(cmd))
        return None
    check(r.returncode == 0, "ds9 exited %d: %s" % (r.returncode, r.stderr[-2000:]))
    if not os.path.exists(saved):
        check(False, "ds9 saved no regions (%s)" % saved)
        return None
    text = open(saved).read()
    check("\nimage\n" in text, "ds9 did not save in image coordinates:\n" + text[:500])
    return re.findall(r"circle\(([-\d.]+),([-\d.]+),([-\d.]+)\)\s*#[^\n]*text=\{([^}]*)\}", text)


def check_ds9(out, cands):
    if not shutil.which("ds9") or not shutil.which("xvfb-run"):
        print("skipped: DS9 check (ds9 or xvfb-run not installed; apt-get install saods9 xvfb)")
        return
    fx, fy = cands[0]["fit"]["x"] + 1, cands[0]["fit"]["y"] + 1  # DS9 pixels are 1-based
    # Our region file is in the stack's frame (RADESYS = ICRS: icrs), so DS9 must put it on the exact pixel.
    # A copy labelled FK5 makes DS9 apply the FK5-ICRS frame tie (~20 mas, 0.02 px at 1"/px): that shows the
    # frame name is read, within 0.03 px.
    fk5 = os.path.join(out, "stack_fk5.fits")
    with fits.open(os.path.join(out, "run_c001_object.fits")) as hdul:
        hdul[0].header["RADESYS"] = "FK5"
        hdul.writeto(fk5)
    for path, tag, tol in ((fk5, "fk5", 0.03), (os.path.join(out, "run_c001_object.fits"), "icrs", 0.002)):
        circles = ds9_image_regions(out, path, tag)
        if not circles:
            continue
        check(len(circles) == len(cands), "ds9 lists %d circles, we wrote %d" % (len(circles), len(cands)))
        x1, y1 = float(circles[0][0]), float(circles[0][1])
        check(abs(x1 - fx) < tol and abs(y1 - fy) < tol,
              "ds9 (%s) puts candidate 1 at (%.4f, %.4f), expected the 1-based pixel (%.4f, %.4f) within %g px" %
              (tag, x1, y1, fx, fy, tol))
        check(circles[0][3].startswith("#1 SNR 14.0 real"), "ds9 label: " + circles[0][3])


def main():
    binary = ui_test_binary(sys.argv[1])
    if not binary:
        print("skipped: the GUI tests were not built (-DST_BUILD_GUI=ON)")
        return 0
    with tempfile.TemporaryDirectory() as out:
        if run_gui_reports(binary, out):
            doc = json.load(open(os.path.join(out, "run_candidates.json")))
            cands = doc["candidates"]
            check(cands[0]["label"] == "real" and "fit" in cands[0], "candidate 1 is not real with a fit")
            check_fits(out, cands[0], cands[0]["fit"])
            check_ds9(out, cands)
    return finish()


if __name__ == "__main__":
    sys.exit(main())
