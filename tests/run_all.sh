#!/usr/bin/env bash
# Sets up, builds (Release and Debug) and runs every test: ctest on both builds, then pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/setup test
export PATH="$PWD/.venv/bin:$PATH"
echo "== ctest (Release)"
ctest --test-dir build --output-on-failure -j 2
echo "== ctest (Debug: -fcheck=all, FP traps)"
ctest --test-dir build-debug --output-on-failure -j 2
echo "== pytest"
ELLROLL_EXE="$PWD/build/ellroll" ELLROLL_DEBUG_EXE="$PWD/build-debug/ellroll" \
  ELLROLL_MPI_EXE="$PWD/build-mpi/ellroll" .venv/bin/python -m pytest -q tests/python
