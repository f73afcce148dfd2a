#!/usr/bin/env bash
# Runs the paper's case (Legeza 1990) and draws its Fig. 2 and Fig. 3, and a
# report folder with every figure and the summary table, into results/ in the
# current folder:
#   results/legeza1990.h5, results/legeza1990_fig2_trace.png,
#   results/legeza1990_fig3_nutation.png, results/report/index.html
# In a source checkout it first sets up (.ci/setup: the Debian packages, the
# .venv, the Release build) and runs build/ellroll and .venv/bin/ellroll-plot.
# Installed (cmake --install build --prefix P) it runs P/bin/ellroll on
# P/share/ellroll/input/legeza1990.nml, and the ellroll-plot on PATH
# (pip install ./post). ELLROLL and ELLROLL_PLOT name other executables; with
# ELLROLL set nothing is set up.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
top=$(dirname "$here")                        # the checkout, or P/share/ellroll
input=$top/input/legeza1990.nml
if [ -n "${ELLROLL:-}" ]; then
  ellroll=$ELLROLL
  plot=${ELLROLL_PLOT:-ellroll-plot}
elif [ -f "$top/.ci/setup" ]; then
  bash "$top/.ci/setup"
  ellroll=$top/build/ellroll
  plot=${ELLROLL_PLOT:-$top/.venv/bin/ellroll-plot}
else
  ellroll=$top/../../bin/ellroll
  plot=${ELLROLL_PLOT:-ellroll-plot}
fi
if ! command -v "$plot" > /dev/null; then
  echo "$0: no $plot: install it with 'pip install ./post' from the source, or set ELLROLL_PLOT" >&2
  exit 2
fi
mkdir -p results
"$ellroll" run "$input" -o results/legeza1990.h5 --overwrite
"$plot" trace results/legeza1990.h5 --out results --overwrite
"$plot" nutation results/legeza1990.h5 --out results --overwrite
"$plot" report results/legeza1990.h5 --out results/report --overwrite
echo "open results/report/index.html"
