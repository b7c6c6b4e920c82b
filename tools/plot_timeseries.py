#!/usr/bin/env python3
"""Plot every time series of a results folder to PNG.

Run with:   python3 tools/plot_timeseries.py results/hertz_bounce [--out DIR] [--series NAME ...]

Reads each *.h5 in the folder (or the one file given), finds the groups under /timeseries (the layout
written by common::H5Writer: one 1-D dataset per column, the first named "time") and writes one PNG per
series, <file stem>_<series>.png, with one panel per column against time. Needs Debian's python3-h5py
and python3-matplotlib.
"""
import argparse
import pathlib
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_series(h5file):
    """{series name: {column: array}} for every group under /timeseries."""
    out = {}
    with h5py.File(h5file, "r") as f:
        group = f.get("timeseries")
        if group is None:
            return out
        for name, series in group.items():
            if not isinstance(series, h5py.Group) or "time" not in series:
                continue
            out[name] = {col: series[col][()] for col in series.keys()}
    return out


def plot_series(name, columns, path, title):
    time = columns["time"]
    others = [c for c in columns if c != "time"]
    fig, axes = plt.subplots(len(others), 1, sharex=True, figsize=(7, 2.2 * len(others) + 0.8), squeeze=False)
    for ax, col in zip(axes[:, 0], others):
        ax.plot(time, columns[col], lw=1.2)
        ax.set_ylabel(col)
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(f"{title}: {name}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=pathlib.Path, help="results folder or one .h5 file")
    ap.add_argument("--out", type=pathlib.Path, help="folder for the PNGs (default: <results>/plots)")
    ap.add_argument("--series", nargs="*", help="only these series")
    args = ap.parse_args(argv)

    if args.results.is_file():
        files, base = [args.results], args.results.parent
    elif args.results.is_dir():
        files, base = sorted(args.results.glob("*.h5")), args.results
    else:
        print(f"plot_timeseries: {args.results} does not exist", file=sys.stderr)
        return 2
    if not files:
        print(f"plot_timeseries: no .h5 files in {args.results}", file=sys.stderr)
        return 2
    out = args.out or base / "plots"
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for h5 in files:
        for name, columns in read_series(h5).items():
            if args.series and name not in args.series:
                continue
            if len(columns) < 2 or len(columns["time"]) == 0:
                continue
            png = out / f"{h5.stem}_{name}.png"
            plot_series(name, columns, png, h5.stem)
            written.append(png)
    if not written:
        print(f"plot_timeseries: no time series found in {', '.join(map(str, files))}", file=sys.stderr)
        return 2
    for png in written:
        print(png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
