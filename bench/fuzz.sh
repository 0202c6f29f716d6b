#!/usr/bin/env bash
# Runs every libFuzzer target (fuzz/*_fuzz.cpp, and fuzz/*_fuzz.py under
# atheris with PYTHON) for SECONDS each, starting from its seed corpus in
# fuzz/corpus/<name>/ (never modified: new inputs go to
# BUILD_DIR/corpus/<name>/). Crashes are written to BUILD_DIR/artifacts/.
# Usage: bench/fuzz.sh BUILD_DIR SECONDS [PYTHON]
set -euo pipefail
usage="usage: fuzz.sh BUILD_DIR SECONDS [PYTHON]"
build=${1:?$usage}
seconds=${2:?$usage}
python=${3:-}
root="$(cd "$(dirname "$0")/.." && pwd)"
shopt -s nullglob
sources=("$root"/fuzz/*_fuzz.cpp "$root"/fuzz/*_fuzz.py)
if [ ${#sources[@]} -eq 0 ]; then
  echo "fuzz: no fuzz/*_fuzz.cpp targets yet; nothing to run"
  exit 0
fi
mkdir -p "$build/artifacts"
failed=()
for source in "${sources[@]}"; do
  if [[ "$source" == *.py ]]; then
    name=$(basename "$source" .py)
    if [ -z "$python" ]; then
      echo "fuzz: $name needs the PYTHON argument (the venv with wiretape and atheris); failing" >&2
      failed+=("$name")
      continue
    fi
    program=("$python" "$source")
  else
    name=$(basename "$source" .cpp)
    program=($(find "$build" -type f -perm -u+x -name "$name" | head -n 1))
    if [ ${#program[@]} -eq 0 ]; then
      echo "fuzz: $name was not built (see $build); failing" >&2
      failed+=("$name")
      continue
    fi
  fi
  help=$("${program[@]}" -help=1 2>&1 || true)
  # A Python target without atheris mutates at random (it says so).
  if [[ "$source" != *.py && "$help" != *libFuzzer* ]]; then
    echo "fuzz: ${program[*]} is not a libFuzzer program (built without clang, or no atheris?); failing" >&2
    failed+=("$name")
    continue
  fi
  mkdir -p "$build/corpus/$name"
  seeds=()
  [ -d "$root/fuzz/corpus/$name" ] && seeds+=("$root/fuzz/corpus/$name")
  echo "fuzz: $name for ${seconds}s"
  if ! "${program[@]}" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
      -print_final_stats=1 -artifact_prefix="$build/artifacts/$name-" \
      "$build/corpus/$name" "${seeds[@]}" >"$build/$name.log" 2>&1; then
    echo "fuzz: $name FAILED; the last lines of $build/$name.log:" >&2
    tail -n 40 "$build/$name.log" >&2
    failed+=("$name")
  else
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb|ran cleanly" "$build/$name.log" \
      | sed "s/^/  /" || true
  fi
done
[ -z "$python" ] || { echo "fuzz: test_combinations, $((seconds * 2)) examples"; WIRETAPE_COMBINATION_EXAMPLES=$((seconds * 2)) "$python" -m pytest -q -p no:cacheprovider "$root/tests/python/bindings/test_combinations.py" >"$build/test_combinations.log" 2>&1; } || { tail -n 40 "$build/test_combinations.log" >&2; failed+=(test_combinations); }
[ -z "$python" ] || { echo "fuzz: test_combination_events, $((seconds * 2)) examples"; WIRETAPE_COMBINATION_EXAMPLES=$((seconds * 2)) "$python" -m pytest -q -p no:cacheprovider "$root/tests/python/bindings/test_combination_events.py" >"$build/test_combination_events.log" 2>&1; } || { tail -n 40 "$build/test_combination_events.log" >&2; failed+=(test_combination_events); }
# The sweep runs a converter (tshark for captures) at every damaged
# position, most of make fuzz's time: on two workers (-rP prints each
# file's tally, which -s cannot under xdist).
[ -z "$python" ] || { echo "fuzz: import damage sweep, every position (WIRETAPE_DAMAGE_SWEEP=full)"; WIRETAPE_DAMAGE_SWEEP=full "$python" -m pytest -q -n 2 -rP -p no:cacheprovider "$root/tests/python/tools/test_import_damage_sweep.py" >"$build/import_damage_sweep.log" 2>&1 && grep "damage sweep" "$build/import_damage_sweep.log" | sed "s/^/  /"; } || { tail -n 40 "$build/import_damage_sweep.log" >&2; failed+=(import_damage_sweep); }
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: failed: ${failed[*]}" >&2
  exit 1
fi
echo "fuzz: all targets ran clean"
