#!/usr/bin/env python3
"""Convert the digitized NBS Report 9264 wall-temperature traces to cryofit's long format.

Usage (from the repository root):

    python3 examples/nbs/convert.py SOURCE_DIR [OUT_DIR]

SOURCE_DIR holds the digitized files of the liquid-nitrogen runs (nbs9264_fig10_ln2_2p5atm.csv,
nbs9264_fig11_ln2_3p4atm.csv, nbs9264_fig13_ln2_4p2atm.csv), of the liquid-hydrogen runs
(nbs9264_fig02_lh2_5p1atm.csv, nbs9264_fig03_lh2_2p5atm.csv, nbs9264_fig04_lh2_4p2atm.csv) and
LICENSE-OpenFLUME.txt; OUT_DIR defaults to the directory of this script (examples/nbs/). Writes
saturated-2.5atm-data.csv, saturated-3.4atm-data.csv, subcooled-4.2atm-data.csv (nitrogen),
hydrogen-saturated-5.1atm-data.csv, hydrogen-subcooled-2.5atm-data.csv,
hydrogen-subcooled-4.2atm-data.csv (hydrogen) and a verbatim copy of LICENSE-OpenFLUME.txt.

Each source file is `#` comment lines, then the header `time_s,station_m,T_wall_K` and one row per
reading. The output keeps the `#` lines as they are, adds two lines (where the file came from, and
its licence), then writes `time_s,station,x_m,quantity,value` (DESIGN.md section 3.2) with one row
per source row, in the source order: the time and temperature text unchanged, the station named
TS1-TS4 from its position, x_m the station position and quantity `wall_temperature_k`. Nothing is
thinned, resampled or rounded. Python 3 standard library only.
"""

import os
import shutil
import sys

# (source file, output file): the liquid-nitrogen runs (Figs. 10, 11, 13), then the liquid-hydrogen
# runs (Figs. 2, 3, 4) of the same line.
FILES = [
    ("nbs9264_fig10_ln2_2p5atm.csv", "saturated-2.5atm-data.csv"),
    ("nbs9264_fig11_ln2_3p4atm.csv", "saturated-3.4atm-data.csv"),
    ("nbs9264_fig13_ln2_4p2atm.csv", "subcooled-4.2atm-data.csv"),
    ("nbs9264_fig02_lh2_5p1atm.csv", "hydrogen-saturated-5.1atm-data.csv"),
    ("nbs9264_fig03_lh2_2p5atm.csv", "hydrogen-subcooled-2.5atm-data.csv"),
    ("nbs9264_fig04_lh2_4p2atm.csv", "hydrogen-subcooled-4.2atm-data.csv"),
]

# Wall thermocouple stations: name, position from the supply dewar in m (as written in x_m).
STATIONS = [("TS1", "6.1"), ("TS2", "24.4"), ("TS3", "43.0"), ("TS4", "60.4")]

LICENCE = "LICENSE-OpenFLUME.txt"
SOURCE_HEADER = "time_s,station_m,T_wall_K"
OUTPUT_HEADER = "time_s,station,x_m,quantity,value"


def station_for(position_text, where):
    x = float(position_text)
    for name, x_text in STATIONS:
        if abs(float(x_text) - x) < 1e-9:
            return name, x_text
    raise SystemExit(f"{where}: station_m = {position_text} is not one of the stations 6.1/24.4/43.0/60.4 m")


def convert(source_path, out_path):
    source_name = os.path.basename(source_path)
    with open(source_path, encoding="ascii", newline="") as f:
        lines = f.read().splitlines()
    comments = []
    k = 0
    while k < len(lines) and lines[k].startswith("#"):
        comments.append(lines[k])
        k += 1
    if k >= len(lines) or lines[k].strip() != SOURCE_HEADER:
        raise SystemExit(f"{source_path}: expected the header {SOURCE_HEADER!r} after the # lines")
    out = list(comments)
    out.append(
        f"# CONVERTED: by examples/nbs/convert.py (cryofit) from {source_name}: columns time_s,station_m,T_wall_K"
        " -> time_s,station,x_m,quantity,value with stations TS1/TS2/TS3/TS4 = 6.1/24.4/43.0/60.4 m and quantity"
        " wall_temperature_k; every row kept, times and temperatures unchanged"
    )
    out.append(
        f"# LICENSE: MIT (Copyright (c) 2026 OpenFLUME contributors), the digitized data of {source_name};"
        f" see {LICENCE} in this directory"
    )
    out.append(OUTPUT_HEADER)
    rows = 0
    for n, line in enumerate(lines[k + 1 :], start=k + 2):
        if not line.strip():
            continue
        fields = line.split(",")
        where = f"{source_path}:{n}"
        if len(fields) != 3:
            raise SystemExit(f"{where}: expected 3 fields, found {len(fields)}")
        time_text, position_text, temperature_text = (field.strip() for field in fields)
        float(time_text), float(temperature_text)  # both must be numbers
        name, x_text = station_for(position_text, where)
        out.append(f"{time_text},{name},{x_text},wall_temperature_k,{temperature_text}")
        rows += 1
    with open(out_path, "w", encoding="ascii", newline="\n") as f:
        f.write("\n".join(out) + "\n")
    print(f"{source_path} -> {out_path}: {rows} rows")


def main(argv):
    if len(argv) not in (2, 3) or argv[1] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    source_dir = argv[1]
    out_dir = argv[2] if len(argv) == 3 else os.path.dirname(os.path.abspath(__file__))
    os.makedirs(out_dir, exist_ok=True)
    for source, target in FILES:
        convert(os.path.join(source_dir, source), os.path.join(out_dir, target))
    shutil.copyfile(os.path.join(source_dir, LICENCE), os.path.join(out_dir, LICENCE))
    print(f"{os.path.join(source_dir, LICENCE)} -> {os.path.join(out_dir, LICENCE)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
