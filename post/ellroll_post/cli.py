"""ellroll-plot: figures from ellroll HDF5 files."""
import argparse
import pathlib
import sys

from .reader import NotAnEllrollFile, open as open_run
from .plots import plot_trace, plot_nutation

FIGURES = {
    "trace": ("fig2_trace", plot_trace, (6.5, 5.0)),
    "nutation": ("fig3_nutation", plot_nutation, (7.5, 4.0)),
}


def main(argv=None):
    parser = argparse.ArgumentParser(prog="ellroll-plot", description=__doc__)
    parser.add_argument("figure", choices=sorted(FIGURES), help="which figure to draw")
    parser.add_argument("file", help="ellroll HDF5 file")
    parser.add_argument("--case", type=int, default=0, help="case index (default 0)")
    parser.add_argument("--out", default=".", help="output folder (default: current)")
    parser.add_argument("--format", default="png", choices=["png", "pdf", "svg"])
    args = parser.parse_args(argv)

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    stem, draw, size = FIGURES[args.figure]
    try:
        with open_run(args.file) as run:
            fig, ax = plt.subplots(figsize=size, layout="constrained")
            draw(ax, run, args.case)
    except (NotAnEllrollFile, IndexError) as exc:
        print(f"ellroll-plot: error: {exc}", file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{stem}.{args.format}"
    fig.savefig(path, dpi=150)
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
