#!/usr/bin/env bash
# Install (if needed) and run the whole test suite. .ci/run calls exactly this.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
# two test processes (pytest-xdist, one test file each at a time: a file's fixtures are made once); each keeps its
# linear algebra to one thread, so the two do not fight over the cores. JS2_TEST_WORKERS=0 runs in one process.
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}
exec .venv/bin/python -m pytest -q -n "${JS2_TEST_WORKERS:-2}" --dist loadfile --durations=25 "$@"
