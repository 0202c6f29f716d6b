#!/usr/bin/env bash
# Prints the path of a working CPython X.Y interpreter (pyenv's, else
# python3.X on PATH), or nothing and exit 1. Usage: tests/find_python.sh 3.12
set -uo pipefail
version=$1
root=${PYENV_ROOT:-$HOME/.pyenv}
shopt -s nullglob
candidates=("$root"/versions/"$version".*/bin/python"$version")
found=$(command -v "python$version" 2>/dev/null) && candidates+=("$found")
for candidate in "${candidates[@]}"; do
  # A pyenv shim of a version that is not selected exists but fails.
  if "$candidate" -c 'import sys, venv' >/dev/null 2>&1; then
    echo "$candidate"
    exit 0
  fi
done
exit 1
