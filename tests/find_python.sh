#!/usr/bin/env bash
# Prints the path of a working CPython X.Y interpreter (pyenv's, else
# python3.X on PATH), or nothing and exit 1. Usage: tests/find_python.sh 3.12
# "3.12+" takes the oldest of 3.12 and later that is there (the abi3 wheel
# builds with any of them).
set -uo pipefail
version=$1
root=${PYENV_ROOT:-$HOME/.pyenv}
shopt -s nullglob
if [[ $version == *+ ]]; then
  major=${version%%.*}
  minor=${version#*.}
  minor=${minor%+}
  for next in $(seq "$minor" $((minor + 10))); do
    "$0" "$major.$next" && exit 0
  done
  exit 1
fi
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
