#!/usr/bin/env python3
"""Plot model against data: wall temperature at the four NBS stations, as an SVG.

Standard library only. Usage (from the repository root, after running the cases):

    cargo run --release -p cryofit -- simulate examples/nbs/subcooled-4.2atm.toml --out out/nbs/subcooled-4.2atm
    python3 tools/plot_validation.py out/nbs/subcooled-4.2atm/probes.csv \
        examples/nbs/subcooled-4.2atm-data.csv docs/validation/subcooled-4.2atm.svg \
        --title "Subcooled LN2, 4.2 atm" --t-max 400

Both inputs are in the long format time_s,station,x_m,quantity,value; only the rows with
quantity wall_temperature_k are drawn. Data solid, model dashed, one colour per station.
"""

import argparse
import csv
import sys

COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"]


def read(path):
    series = {}
    with open(path) as f:
        rows = (line for line in f if not line.startswith("#"))
        for row in csv.DictReader(rows):
            if row["quantity"] != "wall_temperature_k":
                continue
            series.setdefault(row["station"], []).append((float(row["time_s"]), float(row["value"])))
    return series


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("model")
    ap.add_argument("data")
    ap.add_argument("out")
    ap.add_argument("--title", default="")
    ap.add_argument("--t-max", type=float, default=400.0)
    ap.add_argument("--temp-min", type=float, default=60.0)
    ap.add_argument("--temp-max", type=float, default=320.0)
    a = ap.parse_args()
    model, data = read(a.model), read(a.data)
    if not model or not data:
        sys.exit("no wall_temperature_k rows in one of the inputs")
    width, height = 760, 480
    left, right, top, bottom = 70, 150, 40, 60
    pw, ph = width - left - right, height - top - bottom

    def sx(t):
        return left + pw * min(max(t, 0.0), a.t_max) / a.t_max

    def sy(v):
        v = min(max(v, a.temp_min), a.temp_max)
        return top + ph * (1.0 - (v - a.temp_min) / (a.temp_max - a.temp_min))

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{width}" height="{height}" fill="white"/>',
           f'<text x="{left + pw / 2}" y="22" text-anchor="middle" font-size="15">{a.title}</text>']
    # grid and ticks
    for k in range(0, 9):
        t = a.t_max * k / 8
        out.append(f'<line x1="{sx(t):.1f}" y1="{top}" x2="{sx(t):.1f}" y2="{top + ph}" stroke="#ddd"/>')
        out.append(f'<text x="{sx(t):.1f}" y="{top + ph + 18}" text-anchor="middle">{t:g}</text>')
    step = 20 if a.temp_max - a.temp_min <= 300 else 50
    v = a.temp_min - a.temp_min % step + (step if a.temp_min % step else 0)
    while v <= a.temp_max:
        out.append(f'<line x1="{left}" y1="{sy(v):.1f}" x2="{left + pw}" y2="{sy(v):.1f}" stroke="#ddd"/>')
        out.append(f'<text x="{left - 8}" y="{sy(v) + 4:.1f}" text-anchor="end">{v:g}</text>')
        v += step
    out.append(f'<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="none" stroke="black"/>')
    out.append(f'<text x="{left + pw / 2}" y="{height - 18}" text-anchor="middle">time (s)</text>')
    out.append(f'<text transform="translate(20 {top + ph / 2}) rotate(-90)" text-anchor="middle">'
               f'wall temperature (K)</text>')
    stations = sorted(set(model) | set(data))
    for k, name in enumerate(stations):
        colour = COLOURS[k % len(COLOURS)]
        for series, dash in ((data, ""), (model, ' stroke-dasharray="6 4"')):
            pts = [p for p in series.get(name, []) if p[0] <= a.t_max]
            if pts:
                path = " ".join(f"{sx(t):.1f},{sy(v):.1f}" for t, v in pts)
                out.append(f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="1.8"{dash}/>')
        y = top + 20 + 22 * k
        out.append(f'<line x1="{left + pw + 15}" y1="{y}" x2="{left + pw + 45}" y2="{y}" stroke="{colour}" '
                   f'stroke-width="2"/>')
        out.append(f'<text x="{left + pw + 52}" y="{y + 4}">{name}</text>')
    y = top + 20 + 22 * len(stations) + 10
    out.append(f'<line x1="{left + pw + 15}" y1="{y}" x2="{left + pw + 45}" y2="{y}" stroke="black"/>')
    out.append(f'<text x="{left + pw + 52}" y="{y + 4}">data</text>')
    out.append(f'<line x1="{left + pw + 15}" y1="{y + 20}" x2="{left + pw + 45}" y2="{y + 20}" stroke="black" '
               f'stroke-dasharray="6 4"/>')
    out.append(f'<text x="{left + pw + 52}" y="{y + 24}">model</text>')
    out.append("</svg>")
    with open(a.out, "w") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
