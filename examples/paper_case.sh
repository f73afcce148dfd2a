#!/usr/bin/env bash
# Sets up, runs the paper's case (Legeza 1990) and draws its Fig. 2 and Fig. 3,
# and a report folder with every figure and the summary table.
# Output: results/legeza1990.h5, results/legeza1990_fig2_trace.png, results/legeza1990_fig3_nutation.png,
#         results/report/index.html
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/setup
mkdir -p results
build/ellroll run input/legeza1990.nml -o results/legeza1990.h5 --overwrite
.venv/bin/ellroll-plot trace results/legeza1990.h5 --out results --overwrite
.venv/bin/ellroll-plot nutation results/legeza1990.h5 --out results --overwrite
.venv/bin/ellroll-plot report results/legeza1990.h5 --out results/report --overwrite
echo "open results/report/index.html"
