#!/usr/bin/env bash
# Sets up, builds (Release, Debug, MPI, sanitizers) and runs every test: ctest
# on the Release and Debug builds, then pytest (which
# also uses Debug and MPI), then the tests of inputs and model limits again on
# the sanitizer build (memory errors and undefined behaviour stop it).
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/setup test
export PATH="$PWD/.venv/bin:$PATH"
echo "== ctest (Release)"
ctest --test-dir build --output-on-failure -j 2
echo "== ctest (Debug: -fcheck=all, FP traps)"
ctest --test-dir build-debug --output-on-failure -j 2
if [ "${ELLROLL_TEST_FULL:-0}" != 0 ]; then        # (the larger budgets: README)
  echo "== ctest (portable: -DELLROLL_NATIVE=OFF)"
  ctest --test-dir build-portable --output-on-failure -j 2
fi
echo "== pytest"
# two workers (pytest-xdist): the tests are independent processes, most of one
# thread; a group of tests that share a costly fixture runs on one worker
ELLROLL_EXE="$PWD/build/ellroll" ELLROLL_DEBUG_EXE="$PWD/build-debug/ellroll" \
  ELLROLL_MPI_EXE="$PWD/build-mpi/ellroll" .venv/bin/python -m pytest -q -n 2 --dist loadgroup tests/python
echo "== pytest on the sanitizer build (-fcheck=all, -fsanitize=address,undefined): fuzz, extreme inputs, the input space, literals, hard cases, limits, dt sweeps"
ELLROLL_BUILD=sanitize ELLROLL_EXE="$PWD/build-sanitize/ellroll" ELLROLL_DEBUG_EXE="$PWD/build-sanitize/ellroll" \
  .venv/bin/python -m pytest -q -n 2 tests/python/test_fuzz.py tests/python/test_extreme_inputs.py \
  tests/python/test_input_space.py tests/python/test_input_literals.py tests/python/test_hard_cases.py \
  tests/python/test_limits_fixed_step.py
