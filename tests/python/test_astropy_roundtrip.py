#!/usr/bin/env python3
"""astropy cross-check of synthtrack's FITS I/O (issue 2, section 4).

astropy writes a few 2-D frames (DATE-OBS, EXPTIME, a TAN WCS) into a temporary folder;
`synthtrack-cli convert` turns them into one cube and `synthtrack-cli info --json` describes them; astropy then
reads the cube and checks: pixels equal (exactly: float32 in, float32 out), WCS keywords equal (CTYPE strings,
CRVAL/CRPIX/CD numbers to 1e-12 relative), frame mid-times equal to DATE-OBS + EXPTIME/2 (1e-8 day), and that
info reports the same frames, size, times and plate scale.

usage: test_astropy_roundtrip.py PATH-TO-synthtrack-cli     (prints "N passed, N failed"; exit 1 on failure)
"""
import json
import os
import sys
import tempfile

import _support

_support.require_astropy()
import numpy as np  # noqa: E402
from astropy.io import fits  # noqa: E402
from astropy.time import Time  # noqa: E402

from _support import check, finish, run_cli  # noqa: E402
from _support import run_ok as run  # noqa: E402


def write_frames(folder):
    rng = np.random.default_rng(7)
    starts = ["2024-03-01T05:06:07.125", "2024-03-01T05:06:07.725", "2024-03-01T05:06:06.525", "2024-03-01T05:06:08.325"]
    frames = []
    for i, start in enumerate(starts):
        data = rng.normal(1000.0, 30.0, size=(24, 32)).astype(np.float32)
        data[3, 5] = 60000.0 + i  # a bright pixel to tell the frames apart
        h = fits.Header()
        h["DATE-OBS"] = start
        h["EXPTIME"] = (0.5, "s")
        h["OBJECT"] = "test field"
        h["CTYPE1"], h["CTYPE2"] = "RA---TAN", "DEC--TAN"
        h["CRVAL1"], h["CRVAL2"] = 150.123456789012, -2.3456789012345
        h["CRPIX1"], h["CRPIX2"] = 16.5, 12.25
        h["CD1_1"], h["CD1_2"] = -8.47222222222e-05, 1.23e-07
        h["CD2_1"], h["CD2_2"] = 1.1e-07, 8.47222222222e-05
        h["CUNIT1"], h["CUNIT2"] = "deg", "deg"
        h["RADESYS"] = "ICRS"
        path = os.path.join(folder, f"frame{i}.fits")
        fits.PrimaryHDU(data, h).writeto(path)
        mid = Time(start, scale="utc").mjd + 0.25 / 86400.0
        frames.append((mid, data, path))
    return sorted(frames, key=lambda f: f[0])


def main():
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    cli = sys.argv[1]
    with tempfile.TemporaryDirectory() as tmp:
        inp = os.path.join(tmp, "in")
        os.mkdir(inp)
        frames = write_frames(inp)
        cube_path = os.path.join(tmp, "cube.fits")
        run(cli, "convert", inp, "-o", cube_path)
        info = json.loads(run(cli, "info", "--json", inp))
        info_cube = json.loads(run(cli, "info", "--json", cube_path))

        with fits.open(cube_path) as hdul:
            cube = hdul[0].data
            h = hdul[0].header
            check(cube.dtype == np.dtype(">f4"), f"cube dtype {cube.dtype}")
            check(cube.shape == (4, 24, 32), f"cube shape {cube.shape}")
            for n, (mid, data, _) in enumerate(frames):
                check(np.array_equal(cube[n], data), f"pixels of frame {n} (sorted by time)")
            for key in ("CTYPE1", "CTYPE2"):
                check(h.get(key) == "RA---TAN" if key == "CTYPE1" else h.get(key) == "DEC--TAN", f"{key} = {h.get(key)}")
            ref = fits.getheader(frames[0][2])
            for key in ("CRVAL1", "CRVAL2", "CRPIX1", "CRPIX2", "CD1_1", "CD1_2", "CD2_1", "CD2_2"):
                got = h.get(key)
                check(isinstance(got, float) and abs(got - ref[key]) <= 1e-12 * max(1.0, abs(ref[key])),
                      f"{key}: cube {got!r} vs frame {ref[key]!r}")
            check(h.get("OBJECT") == "test field", f"OBJECT = {h.get('OBJECT')!r}")
            check(str(h.get("SOFTWARE", "")).startswith("synthtrack "), f"SOFTWARE = {h.get('SOFTWARE')!r}")
            table = hdul["FRAMES"].data
            check(len(table) == 4, f"FRAMES rows {len(table)}")
            for n, (mid, _, path) in enumerate(frames):
                check(abs(table["MJD_MID"][n] - mid) < 1e-8, f"FRAMES MJD_MID[{n}] {table['MJD_MID'][n]!r} vs {mid!r}")
                check(abs(table["EXPTIME"][n] - 0.5) < 1e-12, f"FRAMES EXPTIME[{n}]")
                check(table["FILE"][n].strip() == path, f"FRAMES FILE[{n}] {table['FILE'][n]!r}")

        for label, i in (("folder", info), ("cube", info_cube)):
            check(i["frames"] == 4 and i["width"] == 32 and i["height"] == 24, f"info {label}: size/frames {i}")
            check(all(abs(a - f[0]) < 1e-8 for a, f in zip(i["mjd_mid"], frames)), f"info {label}: times {i['mjd_mid']}")
            check(abs(i["plate_scale_arcsec_px"] - 0.305) < 1e-3, f"info {label}: plate scale {i['plate_scale_arcsec_px']}")
            check(abs(i["median_cadence_s"] - 0.6) < 1e-6, f"info {label}: cadence {i['median_cadence_s']}")
        check(info["bitpix"] == -32, f"info bitpix {info['bitpix']}")
        check(any("sorted" in w for w in info["warnings"]), f"info warns about the time order: {info['warnings']}")

        # Usage and input errors: exit codes 2 and 1, one line on stderr.
        r = run_cli(cli, ["convert", inp])
        check(r.returncode == 2 and r.stderr.count("\n") == 1, f"convert without -o: rc {r.returncode}, {r.stderr!r}")
        # A start time without an exposure time is said to be a start, not a mid-exposure time.
        bare = os.path.join(tmp, "noexp.fits")
        hdu = fits.PrimaryHDU(np.zeros((8, 8), dtype=np.float32))
        hdu.header["DATE-OBS"] = "2026-01-02T03:04:05.0"
        hdu.writeto(bare)
        r = run_cli(cli, ["info", bare])
        check(r.returncode == 0 and "start of the exposure" in r.stdout and "mid-exposure" not in r.stdout,
              f"info without EXPTIME: rc {r.returncode}, {r.stdout!r}")
        r = run_cli(cli, ["info", os.path.join(tmp, "missing.fits")])
        check(r.returncode == 1 and "missing.fits" in r.stderr and r.stderr.count("\n") == 1,
              f"info on a missing file: rc {r.returncode}, {r.stderr!r}")

    return finish()


if __name__ == "__main__":
    sys.exit(main())
