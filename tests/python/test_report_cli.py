#!/usr/bin/env python3
"""astropy cross-check of `synthtrack-cli report` (issue 8, reports and sessions).

`synthtrack-cli simulate --preset small` writes a cube with a TAN WCS and a FRAMES time table; this script
writes a candidates JSON (the keys of core/report/search_report.cpp) with a sky rate, three candidates and
fits whose RA/Dec astropy computes from the cube's WCS, then runs `report` with a session, labels, ADES, MPC,
DS9 regions and FITS stacks, and checks with astropy and by column:
  MPC 80-column: 80 characters, designation cols 6-12, note 2 col 15, date cols 16-32 (to 0.5e-6 day),
    RA cols 33-44 and Dec cols 45-56 (sexagesimal parsed by astropy, to 0.5 ms of time / 5 mas), station 78-80;
  ADES PSV: header blocks, field names, obsTime (astropy isot, to 0.5 ms), ra/dec (1e-7 deg), stn, logSNR;
  only candidates labelled real are reported, the SNR-5 one with a warning on stderr;
  DS9: icrs circles at astropy's sky position of the t_ref pixel moved to the WCS's epoch (1e-6 deg);
  FITS stack: astropy reads it; its WCS maps pixel (x, y) to the cube WCS at (x, y) + sky * (t_0 - t_ref)
    (1e-9 deg); provenance keywords present;
  session: labels kept; a corrupted session exits 1 naming a backup copy that exists;
  vetting on `synthtrack-cli demo --preset small`: a fake candidate along the saturated star's bleed column
    gets the charge-leakage flag (from prepared.json's catalog), the simulated asteroid does not and matches a
    known-object list holding its astropy position (< 0.01 arcsec).

usage: test_report_cli.py PATH-TO-synthtrack-cli     (prints "N passed, N failed"; exit 1 on failure)
"""
import json
import math
import os
import sys
import tempfile

import _support

_support.require_astropy()
import numpy as np  # noqa: E402
from astropy.coordinates import Angle  # noqa: E402
from astropy.io import fits  # noqa: E402
from astropy.time import Time  # noqa: E402
from astropy.wcs import WCS  # noqa: E402

from _support import check, finish  # noqa: E402
from _support import run_cli as run  # noqa: E402


def main():
    cli = sys.argv[1]
    with tempfile.TemporaryDirectory() as tmp:
        obs = os.path.join(tmp, "obs.fits")
        r = run(cli, ["simulate", "--preset", "small", "-o", obs])
        check(r.returncode == 0, "simulate: " + r.stderr)
        with fits.open(obs) as hdul:
            wcs = WCS(hdul[0].header, naxis=2)
            mjd = np.array(hdul["FRAMES"].data["MJD_MID"], dtype=float)
        t_ref = float(mjd.mean())
        t0 = (mjd[0] - t_ref) * 86400.0  # the WCS is the first frame's
        sky = (1.5, -0.5)  # px/s (a drifting telescope)

        def sky_at_tref(x, y):
            ra, dec = wcs.all_pix2world([[x + sky[0] * t0, y + sky[1] * t0]], 0)[0]
            return float(ra), float(dec)

        cands = []
        for i, (x, y, snr) in enumerate([(60.25, 70.5, 20.0), (30.0, 40.0, 5.0), (90.0, 20.0, 9.0)]):
            ra, dec = sky_at_tref(x, y)
            c = {"x": int(x), "y": int(y), "vx_px_s": 3.46, "vy_px_s": 2.0, "snr": snr, "n_frames": 64,
                 "fap": 1e-9, "sum": 1.0, "cluster_cells": 1, "ivx": 0, "ivy": 0,
                 "fit": {"status": "converged", "x": x, "y": y, "vx_px_s": 3.4641, "vy_px_s": 2.0,
                         "sigma_x_px": 0.05, "sigma_y_px": 0.07, "snr": snr, "ra_deg": ra, "dec_deg": dec}}
            cands.append(c)
        result = {"inputs": [obs], "backend": "cpu", "method": "exact", "t_ref_mjd": t_ref, "frames": 64,
                  "sigma_f": 1.0, "psf_fwhm_px": 2.34, "plate_scale_arcsec_px": 0.305,
                  "sky_rate": {"vx_px_s": sky[0], "vy_px_s": sky[1]}, "candidates": cands}
        cpath = os.path.join(tmp, "candidates.json")
        with open(cpath, "w") as f:
            json.dump(result, f)
        session = os.path.join(tmp, "s.json")
        ades, mpc, reg, stacks = (os.path.join(tmp, n) for n in ("out.psv", "out.txt", "out.reg", "stacks"))
        r = run(cli, ["report", cpath, "--session", session, "--label", "1=real", "--label", "2=real",
                      "--label", "3=artifact:ghost", "--note", "3=ghost of the bright star", "--station", "X05",
                      "--observer", "A. Observer, B. Second", "--ast-cat", "Gaia3", "--telescope-aperture", "0.5",
                      "--ades", ades, "--mpc", mpc,
                      "--ds9", reg, "--wcs", obs, "--stacks", stacks])
        check(r.returncode == 0, "report exit code %d: %s" % (r.returncode, r.stderr))
        check("SNR 5.00 is below the safe 7.0" in r.stderr, "low-SNR warning on stderr: " + r.stderr)
        check("st00001: SNR" not in r.stderr, "no warning for the SNR-20 detection")

        # MPC 80-column, by column.
        all_lines = open(mpc).read().splitlines()
        head = [l for l in all_lines if l[:4] in ("COD ", "OBS ", "MEA ", "TEL ", "NET ", "ACK ")]
        check(head[:3] == ["COD X05", "OBS A. Observer, B. Second", "MEA A. Observer"] and "NET Gaia-DR3" in head,
              "MPC header lines %s" % head)
        lines = all_lines[len(head):]
        check(len(lines) == 2, "two real detections in the MPC file, got %d" % len(lines))
        for line, c in zip(lines, cands[:2]):
            check(len(line) == 80, "80 columns: %r" % line)
            check(line[0:5] == " " * 5 and line[5:12].startswith("st0000"), "cols 1-12: %r" % line[:12])
            check(line[14] == "C", "col 15 note 2 = C")
            y, m, d = line[15:32].split()
            day = float(d)
            tt = Time("%s-%s-%02dT00:00:00" % (y, m, int(day)), scale="utc").mjd + day - int(day)
            check(abs(tt - t_ref) <= 0.5e-6 + 1e-9, "date cols 16-32 %s vs t_ref %.8f" % (line[15:32], t_ref))
            ra = Angle(line[32:44], unit="hourangle").deg
            dec = Angle(line[44:56], unit="deg").deg
            check(abs(ra - c["fit"]["ra_deg"]) * 3600 <= 0.0075 + 1e-6, "RA cols 33-44 %s" % line[32:44])
            check(abs(dec - c["fit"]["dec_deg"]) * 3600 <= 0.005 + 1e-6, "Dec cols 45-56 %s" % line[44:56])
            check(line[56:65] == " " * 9 and line[65:71] == " " * 6, "cols 57-71 blank (no magnitude)")
            check(line[71] == " ", "col 72 blank: the MPC fills the catalogue code (%r)" % line[71])
            check(line[77:80] == "X05", "station cols 78-80")

        # ADES PSV, field by field.
        text = open(ades).read().splitlines()
        check(text[0] == "# version=2022" and text[1] == "# observatory" and text[2] == "! mpcCode X05",
              "ADES header: %r" % text[:3])
        check("! name A. Observer" in text and "! name B. Second" in text, "ADES observers")
        body = [l for l in text if not l.startswith(("#", "!"))]
        names = [f.strip() for f in body[0].split("|")]
        check(names[:8] == ["trkSub", "mode", "stn", "obsTime", "ra", "dec", "rmsRA", "rmsDec"], "names %s" % names)
        check(len(body) == 3, "ADES: header line + 2 observations")
        for row, c in zip(body[1:], cands[:2]):
            f = dict(zip(names, (v.strip() for v in row.split("|"))))
            check(f["mode"] == "CCD" and f["stn"] == "X05" and f["astCat"] == "Gaia3", "mode/stn/astCat %s" % f)
            check(f["obsTime"].endswith("Z"), "obsTime ends in Z")
            check(abs(Time(f["obsTime"][:-1], format="isot", scale="utc").mjd - t_ref) * 86400 <= 0.0005 + 1e-6,
                  "obsTime %s" % f["obsTime"])
            check(abs(float(f["ra"]) - c["fit"]["ra_deg"]) <= 1e-7, "ra %s" % f["ra"])
            check(abs(float(f["dec"]) - c["fit"]["dec_deg"]) <= 1e-7, "dec %s" % f["dec"])
            check(abs(float(f["rmsRA"]) - 0.05 * 0.305) <= 0.0005 and abs(float(f["rmsDec"]) - 0.07 * 0.305) <= 0.0005,
                  "rmsRA/rmsDec %s %s" % (f["rmsRA"], f["rmsDec"]))
            check(abs(float(f["logSNR"]) - math.log10(c["snr"])) <= 0.005, "logSNR %s" % f["logSNR"])

        # DS9 regions in the WCS's frame (RADESYS ICRS: icrs) at astropy's position.
        reg_lines = open(reg).read().splitlines()
        check(reg_lines[0] == "# Region file format: DS9 version 4.1" and "icrs" in reg_lines, "DS9 header / icrs")
        circles = [l for l in reg_lines if l.startswith("circle(")]
        check(len(circles) == 3, "three DS9 circles")
        for l, c in zip(circles, cands):
            ra, dec, _ = l[len("circle("):l.index(")")].split(",")
            want = sky_at_tref(c["fit"]["x"], c["fit"]["y"])
            check(abs(float(ra) - want[0]) <= 1e-6 and abs(float(dec) - want[1]) <= 1e-6, "DS9 circle %s vs %s" % (l, want))
        check("color=red" in circles[2] and "ghost" in circles[2], "artifact drawn red with its reason")
        tracks = [l for l in reg_lines if l.startswith("line(")]
        check(len(tracks) == 3, "a track line per candidate")
        if tracks:  # the fitted motion relative to the stars over the frames' span, mapped like the circles
            a = [float(v) for v in tracks[0][len("line("):tracks[0].index(")")].split(",")]
            f = cands[0]["fit"]
            # At the first frame (t0 before t_ref) the object sat at (x, y) + v t0 on the detector, where the
            # first frame's WCS (astropy's) puts the sky position it had then.
            ra0, dec0 = (float(v) for v in wcs.all_pix2world([[f["x"] + f["vx_px_s"] * t0,
                                                                f["y"] + f["vy_px_s"] * t0]], 0)[0])
            check(abs(a[0] - ra0) <= 1e-6 and abs(a[1] - dec0) <= 1e-6, "track start %s vs %s" % (a, (ra0, dec0)))

        # FITS stacks of the real candidates.
        names = sorted(os.listdir(stacks)) if os.path.isdir(stacks) else []
        check(names == ["stack_candidate001.fits", "stack_candidate002.fits"], "stacks %s" % names)
        if names:
            with fits.open(os.path.join(stacks, names[0])) as h:
                hdr = h[0].header
                check(h[0].data.shape == (128, 128) and h[0].data.dtype.kind == "f", "stack shape/type")
                check(abs(hdr["WCSEPOCH"] - t_ref) < 1e-9 and abs(hdr["STVX"] - 3.4641) < 1e-12, "WCSEPOCH/STVX")
                check("synthtrack" in hdr["SOFTWARE"], "SOFTWARE")
                sw = WCS(hdr)
                for x, y in [(0.0, 0.0), (60.25, 70.5), (127.0, 5.0)]:
                    a = sw.all_pix2world([[x, y]], 0)[0]
                    b = sky_at_tref(x, y)
                    check(abs(a[0] - b[0]) <= 1e-9 and abs(a[1] - b[1]) <= 1e-9, "stack WCS at (%g, %g)" % (x, y))

        # A fit without RA/Dec, labelled real, mapped through --wcs: its position, and its rate and position
        # angle from the motion relative to the stars (astropy: the separation and position angle of the
        # positions 1 s apart through the same t_ref mapping).
        from astropy.coordinates import SkyCoord
        import astropy.units as u
        bare = json.loads(json.dumps(result))
        f0 = bare["candidates"][0]["fit"]
        del f0["ra_deg"], f0["dec_deg"]
        bpath, bjson = os.path.join(tmp, "bare.json"), os.path.join(tmp, "bare_out.json")
        with open(bpath, "w") as f:
            json.dump(bare, f)
        r = run(cli, ["report", bpath, "--label", "1=real", "--wcs", obs, "--candidates-json", bjson])
        check(r.returncode == 0, "report --wcs of a bare fit: %d %s" % (r.returncode, r.stderr))
        if r.returncode == 0:
            got = json.load(open(bjson))["candidates"][0]["fit"]
            ux, uy = f0["vx_px_s"] - sky[0], f0["vy_px_s"] - sky[1]
            a0 = SkyCoord(*sky_at_tref(f0["x"], f0["y"]), unit="deg")
            a1 = SkyCoord(*sky_at_tref(f0["x"] + ux, f0["y"] + uy), unit="deg")
            want_rate = a0.separation(a1).deg * 86400.0
            want_pa = a0.position_angle(a1).deg % 360.0
            check(abs(got["rate_deg_day"] - want_rate) <= 1e-4 * want_rate,
                  "rate %s vs astropy %s deg/day" % (got.get("rate_deg_day"), want_rate))
            check(abs(got["pa_deg"] - want_pa) <= 0.01, "PA %s vs astropy %s" % (got.get("pa_deg"), want_pa))

        # The session kept the labels; a corrupted session is refused with a backup.
        s = json.load(open(session))
        check([c["label"] for c in s["candidates"]] == ["real", "real", "artifact"], "session labels")
        check(s["candidates"][2]["reason"] == "ghost" and s["candidates"][2]["note"] == "ghost of the bright star",
              "reason and note")
        check(s["settings"]["station"] == "X05", "settings kept")
        with open(session, "r+") as f:
            data = f.read()
            f.seek(0)
            f.write(data[: len(data) // 2])
            f.truncate()
        r = run(cli, ["report", cpath, "--session", session])
        check(r.returncode == 1 and "corrupted" in r.stderr, "corrupted session: %d %s" % (r.returncode, r.stderr))
        backups = [n for n in os.listdir(tmp) if n.startswith("s.corrupt-") and n.endswith(".json")]
        check(len(backups) == 1 and backups[0] in r.stderr, "backup named: %s" % backups)
    vetting_on_the_demo(cli)
    return finish()


def vetting_on_the_demo(cli):
    """The demo's small observation has a saturated star with bleed columns: a fake candidate moving along its
    column with the sky must get the charge-leakage flag, the simulated asteroid must not; a known-object list
    holding the asteroid's position (astropy, from the cube's WCS at the fitted position) must match it."""
    with tempfile.TemporaryDirectory() as tmp:
        r = run(cli, ["demo", "--preset", "small", "--out", tmp, "--vmax-deg-day", "35", "--fits", "1"])
        check(r.returncode == 0, "demo: " + r.stdout + r.stderr)
        prep = json.load(open(os.path.join(tmp, "prepared.json")))
        result = json.load(open(os.path.join(tmp, "candidates.json")))
        sat = [s for s in prep["stars"] if s["saturated"] and s["bleed_columns"]]
        check(len(sat) >= 1 and len(result["candidates"]) >= 1, "demo has a bleeding star and a candidate")
        if not sat or not result["candidates"]:
            return
        star, real = sat[0], result["candidates"][0]
        sky = prep["sky_rate_px_s"]
        result["candidates"].append({"x": int(round(star["bleed_columns"][0])), "y": int(star["y_px"] + 50) % 128,
                                     "vx_px_s": sky["vx"], "vy_px_s": 0.8, "snr": 8.0})
        cpath = os.path.join(tmp, "c.json")
        json.dump(result, open(cpath, "w"))
        obs = os.path.join(tmp, "observation.fits")
        with fits.open(obs) as hdul:
            wcs = WCS(hdul[0].header, naxis=2)
            mjd = np.array(hdul["FRAMES"].data["MJD_MID"], dtype=float)
        t0 = (mjd[0] - mjd.mean()) * 86400.0
        fx, fy = real["fit"]["x"], real["fit"]["y"]
        ra, dec = wcs.all_pix2world([[fx + sky["vx"] * t0, fy + sky["vy"] * t0]], 0)[0]
        known = os.path.join(tmp, "known.csv")
        with open(known, "w") as f:
            f.write("name,ra_deg,dec_deg,epoch_mjd,ra_rate_arcsec_min,dec_rate_arcsec_min\n")
            f.write("asteroid,%.9f,%.9f,%.9f,0,0\n" % (ra, dec, result["t_ref_mjd"]))
        session = os.path.join(tmp, "s.json")
        r = run(cli, ["report", cpath, "--session", session, "--prepared", os.path.join(tmp, "prepared.json"),
                      "--known", known, "--wcs", obs])
        check(r.returncode == 0, "report --prepared --known: " + r.stderr)
        s = json.load(open(session))
        flags = [{f["kind"]: f for f in c["artifacts"]} for c in s["candidates"]]
        check(flags[-1]["charge_leakage"]["triggered"], "bleed-column candidate flagged: %s" % flags[-1]["charge_leakage"])
        check(not flags[0]["charge_leakage"]["triggered"], "asteroid not flagged for leakage")
        check(flags[0]["known_object"]["triggered"] and flags[0]["known_object"]["value"] < 0.01,
              "asteroid matches the known object: %s" % flags[0]["known_object"])
        tracklet_of_the_demo(cli, tmp, cpath, real, wcs, mjd, sky)


def tracklet_of_the_demo(cli, tmp, cpath, real, wcs, mjd, sky):
    """The asteroid labelled real is submitted as a tracklet: one ADES line per segment position of its fit,
    one trkSub, at each segment's mean time, at astropy's sky position of that pixel at that time (the WCS is
    the first frame's: the stars have moved by the sky rate since); --positions fit gives the one position;
    a bad --positions value is a usage error."""
    positions = real["fit"].get("segment_positions", [])
    check(len(positions) >= 2 and real["fit"].get("position_segments", 0) >= 2,
          "the demo's fit has a tracklet: %d positions" % len(positions))
    settings = ["--station", "X05", "--observer", "A. Observer", "--telescope-aperture", "0.5",
                "--ast-cat", "Gaia3"]
    ades = os.path.join(tmp, "tracklet.psv")
    session = os.path.join(tmp, "t.json")
    r = run(cli, ["report", cpath, "--session", session, "--label", "1=real", "--ades", ades] + settings)
    check(r.returncode == 0, "report --ades with a tracklet: " + r.stderr)
    body = [l for l in open(ades).read().splitlines() if not l.startswith(("#", "!"))]
    names = [f.strip() for f in body[0].split("|")]
    rows = [dict(zip(names, (v.strip() for v in l.split("|")))) for l in body[1:]]
    check(len(rows) == len(positions), "one ADES line per segment position: %d of %d" % (len(rows), len(positions)))
    t_first = (mjd[0] - float(np.mean(mjd))) * 86400.0
    for row, q in zip(rows, positions):
        check(row["trkSub"] == "st00001", "one trkSub: %s" % row["trkSub"])
        t = Time(row["obsTime"][:-1], format="isot", scale="utc").mjd
        check(abs(t - (float(np.mean(mjd)) + q["t_offset_s"] / 86400.0)) * 86400 <= 0.0005 + 1e-6,
              "segment %d obsTime %s at its mean time" % (q["segment"], row["obsTime"]))
        dt = q["t_offset_s"] - t_first
        ra, dec = wcs.all_pix2world([[q["x"] - sky["vx"] * dt, q["y"] - sky["vy"] * dt]], 0)[0]
        check(abs(float(row["ra"]) - ra) <= 2e-7 and abs(float(row["dec"]) - dec) <= 2e-7,
              "segment %d ra/dec %s %s against astropy's %.7f %.7f" % (q["segment"], row["ra"], row["dec"], ra, dec))
    r = run(cli, ["report", cpath, "--session", session, "--positions", "fit", "--ades", ades] + settings)
    body = [l for l in open(ades).read().splitlines() if not l.startswith(("#", "!"))]
    check(r.returncode == 0 and len(body) == 2, "--positions fit: one line (%d)" % (len(body) - 1))
    r = run(cli, ["report", cpath, "--session", session, "--positions", "three", "--ades", ades] + settings)
    check(r.returncode == 2 and "--positions" in r.stderr, "--positions three: usage error (%d) %s" % (r.returncode, r.stderr))
    # The safe SNR and the contact e-mail are kept in the session, as the help says; the AC2 line carries it.
    mpc = os.path.join(tmp, "tracklet_mpc.txt")
    r = run(cli, ["report", cpath, "--session", session, "--safe-snr", "9", "--contact-email", "me@example.org",
                  "--mpc", mpc] + settings)
    kept = json.load(open(session))["settings"]
    check(r.returncode == 0 and kept.get("safe_snr") == 9 and kept.get("contact_email") == "me@example.org",
          "--safe-snr and --contact-email kept: %s" % kept)
    check("AC2 me@example.org" in open(mpc).read().splitlines(), "AC2 line")
    r = run(cli, ["report", cpath, "--session", session, "--safe-snr", "-1"])
    check(r.returncode == 2 and "--safe-snr" in r.stderr, "--safe-snr -1: usage error (%d)" % r.returncode)
    r = run(cli, ["report", cpath, "--session", session, "--label", "5=real"])
    check(r.returncode != 0 and "candidate 5 does not exist" in r.stderr, "candidate named as given: " + r.stderr)


if __name__ == "__main__":
    sys.exit(main())
