#!/usr/bin/env bash
# Create ./.venv (if needed) and install js2 with its pinned dependencies and test tools into it.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[js2] creating .venv with $($PY --version)"
  "$PY" -m venv .venv
fi
stamp=.venv/.js2-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "[js2] installing js2 and its dependencies into .venv (first time: ~1 minute)"
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -e '.[test]'
  touch "$stamp"
fi
